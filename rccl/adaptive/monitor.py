"""Motion termination by a programmer-defined monitor function (thesis 5.4.2): ``evalfn(monitor)``.

A ``MotionCheck`` (``rccl.adaptive.check``): the function is called once per sample, at the
control level, during the motion it was attached to, with a ``Sample`` record. It returns a false value (None, False, 0) to let
the motion go on, or any other value, its *termination code*, to end the motion now; the
code is recorded in the motion's ``MotionEnd``. Like every control-level function (2.2.3)
it must be quick and must not block. An exception it raises, or a NaN code, is a
``MonitorError`` that stops the arm (never silently ignored).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from ..ending import MotionEnd
from .check import Estimate, Sample, estimate_named
from .exceptions import MonitorError

__all__ = ["Monitor", "Sample"]


@dataclass
class Monitor:
    """A monitor function bound to one motion; ``needs`` asks for force/deviation estimates."""

    fn: Callable[[Sample], Any]
    needs: tuple[str, ...] = ()

    @property
    def name(self) -> str:
        return getattr(self.fn, "__name__", repr(self.fn))

    def __post_init__(self) -> None:
        if not callable(self.fn):
            raise MonitorError(f"evalfn: {self.fn!r} is not callable")
        bad = set(self.needs) - {"force", "deviation"}
        if bad:
            raise MonitorError(f"evalfn: needs {sorted(bad)} not among 'force', 'deviation'")

    @property
    def estimates(self) -> Estimate:
        """A monitor always sees the net joint torques; force and deviation if it asked (MotionCheck)."""
        out = Estimate.TORQUE
        for name in self.needs:
            out |= estimate_named(name, "evalfn(needs=...)")
        return out

    def ends(self, s: Sample) -> MotionEnd | None:
        """MotionCheck: the monitor's verdict on this sample."""
        return self(s)

    def __call__(self, s: Sample) -> MotionEnd | None:
        """Run the function on ``s``; a MotionEnd if it returned a termination code."""
        try:
            code = self.fn(s)
        except Exception as exc:  # a user's error must stop the arm and say where it came from
            raise MonitorError(f"monitor {self.name} raised {type(exc).__name__}: {exc} at t = {s.t:.3f} s") from exc
        if code is None or code is False:
            return None
        if isinstance(code, float) and math.isnan(code):
            raise MonitorError(f"monitor {self.name} returned NaN at t = {s.t:.3f} s (not a termination code)")
        if isinstance(code, (int, float, np.number)) and code == 0:
            return None
        return MotionEnd("monitor", self.name, code=code, t=s.t, sample=s.sample)
