"""Typical static friction from random halts (thesis 4.5.5, second method, Table 4.6).

At each halt the joints hold still under the servo; what the motors exert beyond the
gravity loading is static friction (4.37 with t_a = 0, the arm unloaded).  A halt is
found in the log as a run of samples over which no encoder moves; its last part, after
the current filter of Appendix C has settled, is averaged.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from rcci.calib.drive import Drive
from rcci.calib.exceptions import FitError
from rcci.calib.logs import clipped_note, saturated_mask
from rcci.calib.trace import Trace

FILTER_SETTLE_S = 0.1  # skip this long into a halt: ~6 time constants of the 15 ms filter


@dataclass(frozen=True)
class StaticResult:
    """Table 4.6 for one joint (N m)."""

    joint: int
    samples: int
    maximum: float
    minimum: float
    mean: float
    std: float


def find_halts(counts: np.ndarray, t: np.ndarray, min_duration: float,
               tol_counts: float = 1.0) -> list[tuple[int, int]]:
    """(first, last) sample indices of every stretch of at least ``min_duration``
    seconds during which no encoder changes by more than ``tol_counts``."""
    still = np.all(np.abs(np.diff(counts, axis=0)) <= tol_counts, axis=1)
    halts, k, n = [], 0, len(still)
    while k < n:
        if not still[k]:
            k += 1
            continue
        start = k
        while k < n and still[k]:
            k += 1
        first, last = start, k  # samples first..last are all within tol of neighbours
        if t[last] - t[first] >= min_duration:
            halts.append((first, last))
    return halts


def halt_samples(trace: Trace, drive: Drive, gravity: Callable[[np.ndarray], np.ndarray],
                 min_duration: float = 0.4, notes: list[str] | None = None) -> np.ndarray:
    """Static friction (N m), (H,n): per halt, joint torque minus gravity loading; halts
    with a reading at an ADC rail are left out (noted in ``notes``)."""
    theta = drive.joint_angles(trace.counts)
    tau = drive.joint_torques(trace.adc)
    rows = []
    n = len(drive.G)
    clipped = saturated_mask(trace, range(n), drive.G)
    halts = find_halts(trace.counts, trace.t, min_duration)
    keep = [(a, b) for a, b in halts if not clipped[a:b + 1].any()]
    if notes is not None and len(keep) < len(halts):
        notes.append(clipped_note(trace, "halts", len(halts) - len(keep), len(halts), range(n), drive.G))
    for first, last in keep:
        settled = trace.t >= trace.t[first] + FILTER_SETTLE_S
        idx = np.arange(first, last + 1)
        idx = idx[settled[idx]]
        if len(idx) == 0:
            continue
        q = theta[idx].mean(axis=0)
        rows.append(tau[idx].mean(axis=0) - np.asarray(gravity(q)))
    return np.array(rows).reshape(-1, n)


def fit_static(traces: list[Trace], drive: Drive, gravity: Callable[[np.ndarray], np.ndarray],
               notes: list[str] | None = None) -> tuple[list[StaticResult], np.ndarray]:
    """Table 4.6 over every halt of every log; also returns the samples (H,n)."""
    samples = np.vstack([halt_samples(tr, drive, gravity, notes=notes) for tr in traces])
    if len(samples) < 2:
        raise FitError(f"{len(samples)} halt(s) found in the static-friction logs; "
                       "Table 4.6 needs many (the thesis used 275)")
    out = []
    for j in range(samples.shape[1]):
        s = samples[:, j]
        out.append(StaticResult(j + 1, len(s), float(s.max()), float(s.min()),
                                float(s.mean()), float(s.std(ddof=1))))
    return out, samples
