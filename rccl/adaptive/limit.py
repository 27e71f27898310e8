"""Motion termination on a force or displacement limit (thesis 5.4.1, E.2): ``limit(spec, values)``.

A ``Limit`` holds tool-frame bounds on forces/torques (estimated from joint currents,
4.37 + 4.56) and on the path deviation (E.2). ``check`` returns the first component whose
magnitude exceeds its bound, as a ``MotionEnd``, or None. A limit belongs to one motion
request: the next one queued after ``limit()`` is called (5.4.1: "valid for the next
motion only").
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import spec as specmod
from .ending import MotionEnd


@dataclass(frozen=True)
class Limit:
    """Bounds (SI, magnitudes) per tool-frame component; NaN where a component is not limited."""

    force: np.ndarray        # (6,) N, N*m
    dev: np.ndarray          # (6,) m, rad
    text: str = ""

    @classmethod
    def parse(cls, spec: str, *values: float) -> "Limit":
        """``Limit.parse("fz dx", 10.0, 0.005)``; SpecError for a bad token or value."""
        items = specmod.parse(spec, values, f"limit({spec!r})")
        force, dev = np.full(6, np.nan), np.full(6, np.nan)
        for (kind, i), v in items.items():
            (force if kind == "force" else dev)[i] = v
        return cls(force, dev, spec)

    @property
    def needs_force(self) -> bool:
        return bool(np.any(np.isfinite(self.force)))

    @property
    def needs_deviation(self) -> bool:
        return bool(np.any(np.isfinite(self.dev)))

    def check(self, force: np.ndarray | None, dev: np.ndarray | None, t: float = 0.0,
              sample: int = 0) -> MotionEnd | None:
        """The first exceeded component (forces first), or None. NaN observations count as exceeded."""
        for obs, bound, names in ((force, self.force, specmod.FORCE_NAMES), (dev, self.dev, specmod.DEV_NAMES)):
            if obs is None:
                continue
            for i in range(6):
                b = bound[i]
                if b == b and not abs(obs[i]) <= b:     # b == b: limited; "not <=" catches NaN
                    return MotionEnd("limit", names[i], float(obs[i]), float(b), t=t, sample=sample)
        return None
