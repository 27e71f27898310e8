"""Values of a robot data file as loaded: a number, vector or matrix in SI with its source."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

@dataclass(frozen=True)
class Source:
    """Where a value comes from: ``tag`` is ``"thesis ..."`` or ``"estimate"``."""

    tag: str
    why: str = ""

    @property
    def is_estimate(self) -> bool:
        return self.tag == "estimate"

    def __str__(self) -> str:
        return f"{self.tag}: {self.why}" if self.why else self.tag


@dataclass(frozen=True)
class Value:
    """A scalar in SI units with its source (``uncertainty`` in the same unit)."""

    value: float
    unit: str
    source: Source
    uncertainty: float | None = None


@dataclass(frozen=True)
class Vector:
    """A per-joint (or named) vector in SI units; ``units`` has one SI unit per entry."""

    values: np.ndarray
    units: tuple[str, ...]
    source: Source
    uncertainty: np.ndarray | None = None
    names: tuple[str, ...] | None = None


@dataclass(frozen=True)
class Matrix:
    """An (n, n) matrix in SI units; ``units`` has one SI unit per column."""

    values: np.ndarray
    units: tuple[str, ...]
    source: Source
