"""Units of the robot data files: each unit's dimension and factor to SI, and the
dimensions of per-joint quantities for revolute and prismatic joints."""
from __future__ import annotations

import math
from types import MappingProxyType
from typing import Mapping

# unit -> (dimension, factor to SI)
UNITS: Mapping[str, tuple[str, float]] = MappingProxyType({
    "m": ("length", 1.0), "mm": ("length", 1e-3),
    "rad": ("angle", 1.0), "deg": ("angle", math.pi / 180.0),
    "m/s": ("linear_velocity", 1.0), "mm/s": ("linear_velocity", 1e-3),
    "rad/s": ("angular_velocity", 1.0), "deg/s": ("angular_velocity", math.pi / 180.0),
    "m/s^2": ("acceleration", 1.0),
    "rad/s^2": ("angular_acceleration", 1.0), "deg/s^2": ("angular_acceleration", math.pi / 180.0),
    "rad/s^3": ("angular_jerk", 1.0), "m/s^3": ("linear_jerk", 1.0),
    "N*m": ("torque", 1.0), "N": ("force", 1.0),
    "N*m*s/rad": ("rotary_viscous", 1.0), "N*s/m": ("linear_viscous", 1.0),
    "N*m/A": ("torque_sensitivity", 1.0),
    "A": ("current", 1.0), "ohm": ("resistance", 1.0), "V/count": ("volts_per_count", 1.0),
    "kg": ("mass", 1.0), "kg*m^2": ("inertia", 1.0),
    "counts": ("counts", 1.0), "counts/rad": ("counts_per_angle", 1.0),
    "counts/m": ("counts_per_length", 1.0), "rad/m": ("motor_angle_per_length", 1.0),
    "1": ("dimensionless", 1.0),
})

# Dimensions of per-joint quantities, (revolute, prismatic).
JOINT_DIMS: Mapping[str, tuple[str, str]] = MappingProxyType({
    "position": ("angle", "length"),
    "velocity": ("angular_velocity", "linear_velocity"),
    "acceleration": ("angular_acceleration", "acceleration"),
    "jerk": ("angular_jerk", "linear_jerk"),
    "effort": ("torque", "force"),
    "viscous": ("rotary_viscous", "linear_viscous"),
    "gear": ("dimensionless", "motor_angle_per_length"),
    "encoder": ("counts_per_angle", "counts_per_length"),
})

JOINT_KINDS = ("revolute", "prismatic")

__all__ = ["UNITS", "JOINT_DIMS", "JOINT_KINDS"]
