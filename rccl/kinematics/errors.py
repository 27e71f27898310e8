"""Exceptions of the generated kinematics modules (one module for the package)."""
from __future__ import annotations


class KinematicsError(ValueError):
    """Base class: the input lies outside the domain of a kinematic function."""


class Unreachable(KinematicsError):
    """No joint configuration reaches the pose (out of reach or outside a joint range)."""


class Singular(KinematicsError):
    """The configuration is singular: the solution is not unique or does not exist."""


class InvalidInput(KinematicsError):
    """An argument has the wrong shape, is not finite, or is not a rigid transform."""
