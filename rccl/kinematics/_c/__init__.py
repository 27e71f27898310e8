"""Compiled kinematics kernels: one extension module per robot, built from the generated `<robot>.c` at install time."""
