"""One recorded run as the fits see it: raw samples plus the run's metadata."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rcci.calib.exceptions import LogError


@dataclass
class Trace:
    """Samples of one log: time (s), encoder counts and ADC readings, both (N, n), n the
    robot's joints (6, or 7 for the Panda).

    ``meta`` is the run's metadata as the measurement program wrote it (see
    docs/calib.md: experiment, joint, window, load, start position, ...).
    """

    path: str
    robot: str
    rate_hz: float
    meta: dict[str, Any]
    t: np.ndarray
    counts: np.ndarray
    adc: np.ndarray
    first_record: int = 0
    extra: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def experiment(self) -> str:
        return str(self.meta.get("experiment", ""))

    def need(self, key: str, kind: type | tuple[type, ...] = object) -> Any:
        """A metadata value, or a LogError naming the file and the missing key."""
        if key not in self.meta:
            raise LogError(self.path, None, f"missing metadata '{key}' "
                           f"(needed for a {self.experiment or 'calibration'} fit)")
        value = self.meta[key]
        if kind is not object and not isinstance(value, kind):
            raise LogError(self.path, None, f"metadata '{key}' = {value!r} "
                           f"is not of type {getattr(kind, '__name__', kind)}")
        return value

    def joint_index(self) -> int:
        """The measured joint as a 0-based index (metadata 'joint' is thesis 1..6, 1..n on an arm
        of n joints)."""
        joint = self.need("joint", int)
        n = self.counts.shape[1] if np.ndim(self.counts) == 2 else 6
        if not 1 <= joint <= n:
            raise LogError(self.path, None, f"metadata 'joint' = {joint} is not 1..{n}")
        return joint - 1


def check_samples(trace: Trace) -> None:
    """Raise LogError naming the first bad record: NaN, time going back, wrong shape."""
    n = len(trace.t)
    nj = trace.counts.shape[1] if np.ndim(trace.counts) == 2 and trace.counts.shape[1] >= 6 else 6
    for name, arr in (("encoder counts", trace.counts), ("ADC readings", trace.adc)):
        if arr.shape != (n, nj):
            raise LogError(trace.path, None, f"{name} have shape {arr.shape}, expected ({n}, {nj})")
        bad = ~np.isfinite(arr).all(axis=1)
        if bad.any():
            k = int(np.argmax(bad))
            raise LogError(trace.path, trace.first_record + k, f"{name} not finite: {arr[k]}")
    if n < 2:
        raise LogError(trace.path, None, f"only {n} samples: nothing to integrate")
    dt = np.diff(trace.t)
    if not np.isfinite(trace.t).all() or (dt <= 0).any():
        k = int(np.argmax(~np.isfinite(trace.t[1:]) | (dt <= 0))) + 1
        raise LogError(trace.path, trace.first_record + k,
                       f"time {trace.t[k]!r} does not follow {trace.t[k - 1]!r}")
