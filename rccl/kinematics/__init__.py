"""The arms' generated kinematics (one module per robot data file, written by ``make derive``)
and :func:`load`, the one way to get the module of a robot by name."""
from .loader import KinematicsNotFound, load

__all__ = ["KinematicsNotFound", "load"]
