"""Compatibility name: the robot description now lives in the ``models`` package.

Programs written as ``from rci.robot_model import load_robot`` keep working; new code
imports ``from rcci.models import load_robot`` (the project's own code does).
"""
from __future__ import annotations

from rcci.models import (  # noqa: F401
    JOINT_KINDS, UNITS, Conversion, Friction, Joint, LinkInertial, Matrix, ModelError, Motors,
    RobotModel, Source, Value, Vector, available_robots, load_robot, models_dir,
)

__all__ = [
    "Source", "Value", "Vector", "Matrix", "Joint", "LinkInertial", "Friction", "Motors",
    "Conversion", "RobotModel", "load_robot", "models_dir", "available_robots", "UNITS",
]
