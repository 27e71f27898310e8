"""Exceptions raised by the RCI layer (one module for the whole package)."""
from __future__ import annotations


class RCIError(Exception):
    """Base class of every error the RCI layer raises."""


class ModelError(RCIError):
    """A robot model file (data file or URDF) is malformed or inconsistent.

    The message names the file, the field and the problem.
    """

    def __init__(self, path: str, field: str, problem: str) -> None:
        self.path = str(path)
        self.field = field
        self.problem = problem
        super().__init__(f"{self.path}: {field}: {problem}")
