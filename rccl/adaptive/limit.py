"""Motion termination on a force or displacement limit (thesis 5.4.1, E.2): ``limit(spec, values)``.

A ``Limit`` holds tool-frame bounds on forces/torques (estimated from joint currents,
4.37 + 4.56) and on the path deviation (E.2). ``check`` returns the first component whose
magnitude exceeds its bound, as a ``MotionEnd``, or None; it is a ``MotionCheck``
(``rccl.adaptive.check``). A limit belongs to one motion
request: the next one queued after ``limit()`` is called (5.4.1: "valid for the next
motion only").

A force limit is only as good as the estimate it watches (thesis 6.2). When its motion
starts, ``vet`` compares each force/torque bound with the estimate's free-air error bar
there (``ForceEstimator.error_bar``, from the arm's data file): a bound not above the bar
would end the motion in free air and is refused (``ForceLimitRefused``); a bound under
``TRIP_BARS`` bars is allowed with a ``ForceEstimateWarning`` that gives the figures (and
the thesis's own, ``THESIS_FORCE_ERROR``, when the bar here is larger). A bound beyond
``TRIP_BARS`` bars passes silently.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from . import spec as specmod
from ..ending import MotionEnd
from .check import Estimate, Sample
from .exceptions import ForceEstimateError

# thesis 6.2: "a typical static friction error of .5 Newton-meters (Table 4.6) will result in an
# error of about 4.5 Newtons in the observed translational force" (PUMA 260, best configuration)
THESIS_FORCE_ERROR = 4.5
# the error bar is one standard deviation per joint, summed in magnitude over the joints; a
# bound within three of them may still be crossed in free air (a joint's draw beyond 3 sigma is
# 0.3 %, but several joints add up)
TRIP_BARS = 3.0


class ForceLimitRefused(ForceEstimateError):
    """A force/torque limit at or below the error bar of the estimate it watches (thesis 6.2)."""


class ForceEstimateWarning(UserWarning):
    """A force/torque limit that the estimate supports only loosely (figures in the message)."""


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

    def vet(self, bar: np.ndarray, where: str = "limit") -> list[str]:
        """Check the force/torque bounds against the estimate's free-air error bar ``bar`` (6,)
        (N, N*m; ``ForceEstimator.error_bar`` where the motion starts). ForceLimitRefused if a
        bound is not above its bar; returns (and issues as ForceEstimateWarning) the notes on
        bounds within ``TRIP_BARS`` bars."""
        notes = []
        bar = np.asarray(bar, dtype=float).tolist()
        for i, b, name in self._force_items:
            unit = "N" if i < 3 else "N*m"
            e = bar[i]
            figure = (f"{where}: |{name}| <= {b:g} {unit}: the force estimate's free-air error here is "
                      f"+-{e:.3g} {unit}")
            if not b > e:
                raise ForceLimitRefused(f"{figure}, not below the limit: it would end the motion without any contact "
                                        f"(thesis 6.2). Use a limit above {TRIP_BARS * e:.3g} {unit}, or a force sensor")
            if b < TRIP_BARS * e:
                worse = (f" (the thesis's was {THESIS_FORCE_ERROR:g} N, 6.2)"
                         if i < 3 and e > THESIS_FORCE_ERROR else "")
                notes.append(f"{figure}{worse}; a limit under {TRIP_BARS:g}x that ({TRIP_BARS * e:.3g} {unit}) may "
                             "end the motion in free air")
        for note in notes:
            warnings.warn(note, ForceEstimateWarning, stacklevel=2)
        return notes

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


def vet_limits(checks, bar: np.ndarray, where: str) -> list[str]:
    """``Limit.vet`` for every force-limiting check of a motion (the others pass); the notes."""
    notes = []
    for c in checks:
        if isinstance(c, Limit) and c.needs_force:
            notes += c.vet(bar, where)
    return notes
