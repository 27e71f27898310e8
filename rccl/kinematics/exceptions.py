"""Exceptions of the generated kinematics modules: the contract's (``rcci.models.kinematics``), named here."""
from __future__ import annotations

from rcci.models.kinematics import InvalidInput, KinematicsError, NoSolver, Singular, Unreachable

__all__ = ["KinematicsError", "Unreachable", "Singular", "InvalidInput", "NoSolver"]
