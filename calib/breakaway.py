"""Static friction coefficients F_s from breakaway ramps (thesis 4.5.5 first method, Table 4.5).

A breakaway log (rcci.calib.breakaway_program) holds ramps: runs of cycles in which the
measured joint is under current control (its CHG motion command is CUR, recorded in the
log) with a motor torque rising steadily from zero. The joint stays still until its net
torque exceeds the static friction, then moves. Per ramp:

* the onset is where the encoder first leaves the ramp's starting count; the joint broke
  away between that reading and the one before, taken as their midpoint;
* the joint torque (G^T K_adc v_adc, 4.36) of the readings over the last LOCAL_S of the
  ramp before the onset lies on a line in time, delayed by the current filter
  (Appendix C) by ``current_lag``; the torque at the breakaway is that line at the
  breakaway + lag (a line fit averages the ADC noise and the current-mode ripple
  instead of trusting one reading);
* minus the gravity loading at the pose (4.37 with t_a = 0), its magnitude is F_s in the
  ramp's direction.

Table 4.5 is the mean per joint and direction; the spread of the ramps is reported too.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from rcci.calib.drive import Drive
from rcci.calib.exceptions import FitError, LogError
from rcci.calib.logs import clipped_note, saturated_mask
from rcci.calib.trace import Trace

CUR_COMMAND = 2          # rci.chg.CUR
SETTLE_S = 0.1           # s skipped at a ramp's start: the filter's step from the hold current
# s of ramp before the breakaway that the line is fitted to: on the coupled wrist the
# servoed joints' own friction can step during a ramp (their hold torque reaches the
# measured joint through G), so only the ramp's last part is taken as one line
LOCAL_S = 0.4


# How close to simula's F_s (the data file's Table 4.5) the shipped logs' fit is held;
# the thesis states no uncertainty for its hand-tuned values, so these are this
# project's: 5 %, and 10 % on joint 4, where the joint creeps by less than an encoder
# count before the first count changes and the servoed joints 5 and 6, reacting to the
# creep, change the torque that reaches joint 4 through G during the last readings.
TOLERANCE = {1: 0.05, 2: 0.05, 3: 0.05, 4: 0.10, 5: 0.05, 6: 0.05}


@dataclass(frozen=True)
class BreakawayPoint:
    """One ramp: joint (1-based), direction (+1/-1), joint angle (rad), F_s (N m, > 0)."""

    joint: int
    direction: int
    angle: float
    static: float
    path: str


@dataclass(frozen=True)
class BreakawayResult:
    """Table 4.5 for one joint: mean F_s per direction (N m), spread and ramps."""

    joint: int
    plus: float
    minus: float
    plus_std: float
    minus_std: float
    ramps: int


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) of every run of True in ``mask``."""
    edges = np.flatnonzero(np.diff(np.r_[0, mask.astype(int), 0]))
    return [(int(a), int(b) - 1) for a, b in zip(edges[::2], edges[1::2])]


def breakaway_points(trace: Trace, drive: Drive, gravity: Callable[[np.ndarray], np.ndarray],
                     notes: list[str] | None = None) -> list[BreakawayPoint]:
    """Every ramp of a breakaway log as a point (see the module docstring); ramps with a
    reading at an ADC rail are left out (noted in ``notes``)."""
    i = trace.joint_index()
    com = trace.extra.get("motion_com")
    if com is None:
        raise LogError(trace.path, None, "records lack the CHG motion commands "
                       "(chg_motion_com) that mark the ramps")
    # the first count of travel marks the onset (encoders do not creep; the program
    # waits for a few counts before it stops the ramp, the fit need not)
    moved = 1.0
    theta = drive.joint_angles(trace.counts)
    tau = drive.joint_torques(trace.adc)[:, i]
    points = []
    clipped = saturated_mask(trace, [i], drive.G)
    ramps = [(a, b) for a, b in _runs(com[:, i] == CUR_COMMAND) if b - a >= 8]
    keep = [(a, b) for a, b in ramps if not clipped[a:b + 1].any()]
    if notes is not None and len(keep) < len(ramps):
        notes.append(clipped_note(trace, "ramps", len(ramps) - len(keep), len(ramps), [i], drive.G))
    for a, b in keep:
        go = np.flatnonzero(np.abs(trace.counts[a:b + 2, i] - trace.counts[a, i]) >= moved)
        if len(go) == 0 or go[0] < 2:
            raise LogError(trace.path, trace.first_record + a,
                           f"a ramp of joint {i + 1} with no breakaway (or a moving start)")
        onset = a + int(go[0])
        # the direction the joint broke away in (a DAC's sign is the motor's, and G may
        # turn it round; a ramp may also start from a gravity-balancing offset)
        d = int(np.sign(theta[onset, i] - theta[a, i]))
        t_b = 0.5 * (trace.t[onset - 1] + trace.t[onset])
        # the readings of the last LOCAL_S before the breakaway (none after it: on the
        # coupled wrist the servoed joints react to the motion at once, and their motors'
        # torques reach this joint through G)
        rate = trace.rate_hz if trace.rate_hz > 0 else 1.0 / float(np.median(np.diff(trace.t)))
        use = np.arange(max(a, onset - int(LOCAL_S * rate) - 1), onset)
        use = use[trace.t[use] >= trace.t[a] + SETTLE_S]
        if len(use) < 4:
            raise LogError(trace.path, trace.first_record + a,
                           f"a ramp of joint {i + 1} broke away before the filter settled")
        slope, icpt = np.polyfit(trace.t[use], tau[use], 1)
        at_break = slope * (t_b + drive.current_lag) + icpt
        q = theta[a]
        points.append(BreakawayPoint(i + 1, d, float(q[i]),
                                     float(d * (at_break - gravity(q)[i])), trace.path))
    if not points:
        raise LogError(trace.path, None, f"no breakaway ramp of joint {i + 1} in the log")
    return points


def fit_breakaway(traces: list[Trace], drive: Drive, gravity: Callable[[np.ndarray], np.ndarray],
                  notes: list[str] | None = None) -> tuple[list[BreakawayResult], list[BreakawayPoint]]:
    """Table 4.5 for every joint with breakaway logs; also returns the points."""
    pts = [p for tr in traces for p in breakaway_points(tr, drive, gravity, notes)]
    results = []
    for j in sorted({p.joint for p in pts}):
        up = np.array([p.static for p in pts if p.joint == j and p.direction > 0])
        dn = np.array([p.static for p in pts if p.joint == j and p.direction < 0])
        if len(up) == 0 or len(dn) == 0:
            raise FitError(f"joint {j}: breakaway ramps in one direction only")
        results.append(BreakawayResult(j, float(up.mean()), float(dn.mean()),
                                       float(up.std(ddof=1)) if len(up) > 1 else float("nan"),
                                       float(dn.std(ddof=1)) if len(dn) > 1 else float("nan"),
                                       len(up) + len(dn)))
    if not results:
        raise FitError("no breakaway log among the inputs")
    return results, pts
