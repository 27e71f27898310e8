"""The one exception of the robot description (its own root: nothing below it to inherit from).

``rci`` re-exports it (``rci.ModelError``, ``rci.exceptions.ModelError``) for programs written
against the earlier layout.
"""
from __future__ import annotations


class ModelError(Exception):
    """A robot model file (data file, URDF or calibration parameter file) is malformed or inconsistent.

    The message names the file, the field and the problem.
    """

    def __init__(self, path: str, field: str, problem: str) -> None:
        self.path = str(path)
        self.field = field
        self.problem = problem
        super().__init__(f"{self.path}: {field}: {problem}")
