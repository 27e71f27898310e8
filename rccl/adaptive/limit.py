"""Motion termination on a force or displacement limit (thesis 5.4.1, E.2): ``limit(spec, values)``.

A ``Limit`` holds tool-frame bounds on forces/torques (estimated from joint currents,
4.37 + 4.56) and on the path deviation (E.2). ``check`` returns the first component whose
magnitude exceeds its bound, as a ``MotionEnd``, or None; it is a ``MotionCheck``
(``rccl.adaptive.check``). A limit belongs to one motion
request: the next one queued after ``limit()`` is called (5.4.1: "valid for the next
motion only").
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import spec as specmod
from ..ending import MotionEnd
from .check import Estimate, Sample


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

    def __post_init__(self) -> None:
        # the limited components as plain (index, bound, name) triples: checked every sample
        for attr, arr, names in (("_force_items", self.force, specmod.FORCE_NAMES),
                                 ("_dev_items", self.dev, specmod.DEV_NAMES)):
            items = tuple((i, float(b), names[i]) for i, b in enumerate(np.asarray(arr, float).tolist()) if b == b)
            object.__setattr__(self, attr, items)

    @property
    def needs_force(self) -> bool:
        return bool(self._force_items)

    @property
    def needs_deviation(self) -> bool:
        return bool(self._dev_items)

    @property
    def estimates(self) -> Estimate:
        """MotionCheck: the tool-frame force if a force component is limited, the deviation if one is."""
        return ((Estimate.FORCE if self._force_items else Estimate.NONE)
                | (Estimate.DEVIATION if self._dev_items else Estimate.NONE))

    def ends(self, s: Sample) -> MotionEnd | None:
        """MotionCheck: the first exceeded component of this sample, or None."""
        return self.check(s.force, s.deviation, s.t, s.sample)

    def check(self, force: np.ndarray | None, dev: np.ndarray | None, t: float = 0.0,
              sample: int = 0) -> MotionEnd | None:
        """The first exceeded component (forces first), or None. NaN observations count as exceeded."""
        for obs, items in ((force, self._force_items), (dev, self._dev_items)):
            if obs is None or not items:
                continue
            values = obs.tolist()
            for i, b, name in items:
                if not abs(values[i]) <= b:       # "not <=" catches NaN
                    return MotionEnd("limit", name, float(values[i]), b, t=t, sample=sample)
        return None
