"""Exceptions raised by the calibration package (one module for the whole package)."""
from __future__ import annotations


class CalibError(Exception):
    """Base class of every error the calibration package raises."""


class LogError(CalibError):
    """A recorded log cannot be used: malformed, truncated, or missing metadata.

    The message names the file, the record (``None`` when the problem is with the file
    as a whole or its metadata) and what is wrong.
    """

    def __init__(self, path: str, record: int | None, problem: str) -> None:
        self.path = str(path)
        self.record = record
        self.problem = problem
        where = self.path if record is None else f"{self.path}: record {record}"
        super().__init__(f"{where}: {problem}")


class MixedLogsError(CalibError):
    """Logs that cannot be fitted together (different robots, different experiments)."""


class FitError(CalibError):
    """The data are not enough to determine the requested parameters."""
