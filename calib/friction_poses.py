"""Friction poses for any arm: long windows over which gravity does no work, or little that the fit takes off.

The thesis's poses (rcci.calib.experiments.FRICTION_POSES) were chosen for the PUMA 260 and are
kept wherever they serve an arm. Elsewhere (the PUMA 560's narrower joint 1 and 4 ranges, the
Stanford arm's other link layout and its prismatic joint 3) :func:`friction_pose` searches:
the other joints at right angles (-180, -90, 0, 90, 180 deg, inside their ranges; a prismatic
joint at mid-range), the swept joint centred on one of those angles (a prismatic one at
mid-range), the window as long as the range leaves room for the turns (at most the thesis's
150 deg, at least MIN_HALF); a candidate is kept when every column of the joint's regressor
row averages to zero over the window (:func:`check_friction_pose`: no net work
whatever the coefficients). The longest window wins, then the pose nearest the arm's ready pose.

Where no window is free of gravity's work (the PUMA 560's joints 2 and 3: their links' centres
of mass lie off the links' lines, so gravity's torque is a cos + b sin of the angle and no window
shorter than a turn averages both to zero), :func:`loaded_friction_pose` takes the same candidates
and keeps a window over which the large terms cancel (the link's weight along it, odd about the
upright link) and only small ones are left: gravity's mean torque over it, g_w (N m), is then
taken off with the fitted gravity coefficients and their errors carried into F_c
(rcci.calib.window_gravity), as the thesis took its own fitted values into later measurements.
"""
from __future__ import annotations

import itertools

import numpy as np

DEG = np.pi / 180
MAX_HALF = 150 * DEG         # rad, the thesis's longest half window (joints 4 and 6)
MIN_HALF = 20 * DEG          # rad: shorter windows average too few readings per pass
TURN_ROOM = 8 * DEG          # rad beyond the window: the turn margin, sweep_path's 2 deg, a short ramp
LOADED_SHARE = 0.10         # of the joint's Coulomb friction: the most gravity's mean torque over a loaded window
                            # may be, coefficients at their data-file sizes (what g_w's error scales with)
PRISMATIC_ROOM = 0.15        # m beyond a prismatic joint's window: its turns at the sweeps' 12 m/s^2 and margins


def _levels(lo: float, hi: float, kind: str) -> list[float]:
    if kind == "prismatic":
        return [(lo + hi) / 2]
    vals = [a * DEG for a in (-180, -90, 0, 90, 180) if lo + 10 * DEG <= a * DEG <= hi - 10 * DEG]
    return vals or [(lo + hi) / 2]


def _half(c: float, lo: float, hi: float, kind: str) -> float:
    room = PRISMATIC_ROOM if kind == "prismatic" else TURN_ROOM
    cap = 0.45 * (hi - lo) if kind == "prismatic" else MAX_HALF
    return float(min(cap, c - lo - room, hi - c - room))


def friction_pose(info, j: int) -> tuple[np.ndarray, float] | None:
    """(pose (n,) rad/m, half window) for joint ``j`` (1-based) of the arm of ``info``
    (rcci.calib.robot.RobotInfo), or None when no candidate leaves gravity without work."""
    from rcci.calib.exceptions import CalibError

    lower, upper, kinds = np.asarray(info.lower), np.asarray(info.upper), info.kinds
    n = len(lower)
    ready = _ready(info.name)
    axes = [_levels(lower[k], upper[k], kinds[k]) for k in range(n)]
    cands = []
    for combo in itertools.product(*axes):
        q = np.array(combo, dtype=float)
        half = _half(q[j - 1], lower[j - 1], upper[j - 1], kinds[j - 1])
        min_half = 0.05 if kinds[j - 1] == "prismatic" else MIN_HALF
        if half >= min_half:
            cands.append((-half, float(np.abs(q - ready).sum()), q, half))
    cands.sort(key=lambda c: (c[0], c[1]))
    for _, _, q, half in cands:
        try:
            check_friction_pose(info, j, q[j - 1] - half, q[j - 1] + half, q, points=21)
        except CalibError:
            continue
        return q, half
    return None


def loaded_friction_pose(info, j: int) -> tuple[np.ndarray, float, float] | None:
    """(pose (n,) rad, half window rad, nominal g_w N m) for revolute joint ``j`` (1-based) of the arm
    of ``info`` (rcci.calib.robot.RobotInfo) when gravity works over every window: the candidates of
    :func:`friction_pose` whose window leaves gravity's mean torque, each coefficient counted at its
    data-file size (sum |mean row_k c_k|), under LOADED_SHARE of the joint's smaller data-file Coulomb
    friction, and whose gravity torque the motor carries (rcci.calib.headroom, at 0.9 of the
    velocity limit both ways); the longest window, then the pose nearest ready. None when no
    candidate does."""
    if info.kinds[j - 1] != "revolute":
        return None
    lower, upper = np.asarray(info.lower), np.asarray(info.upper)
    n = len(lower)
    ready = _ready(info.name)
    nom = info.nominal
    coeffs = np.array([float(nom["gravity_coeffs"][k]["value"]) for k in info.gravity_names])
    fc = min(float(nom["friction"][k]["values"][j - 1]) for k in ("coulomb_pos", "coulomb_neg"))
    cands = []
    for combo in itertools.product(*[_levels(lower[k], upper[k], info.kinds[k]) for k in range(n)]):
        q = np.array(combo, dtype=float)
        half = _half(q[j - 1], lower[j - 1], upper[j - 1], "revolute")
        if half >= MIN_HALF:
            cands.append((-half, float(np.abs(q - ready).sum()), q, half))
    cands.sort(key=lambda c: (c[0], c[1]))
    for _, _, q, half in cands:
        m = mean_gravity_row(info, j, q[j - 1] - half, q[j - 1] + half, q)
        if np.sum(np.abs(m * coeffs)) > LOADED_SHARE * fc or not _carried(info, j, q, half):
            continue
        return q, half, float(m @ coeffs)
    return None


def mean_gravity_row(info, joint: int, lo: float, hi: float, q: np.ndarray, points: int = 61,
                     taper: float = 0.0) -> np.ndarray:
    """The joint's (1-based) gravity regressor row averaged over [lo, hi] rad at the pose ``q``,
    weighted by Hann edges of ``taper`` rad as the friction passes' means are (N m per coefficient)."""
    from rcci.calib.work import hann_edge_weights

    th = np.linspace(lo, hi, points)
    w = hann_edge_weights(th, lo, hi, taper)
    rows = []
    for x in th:
        qq = np.array(q, dtype=float)
        qq[joint - 1] = x
        rows.append(np.asarray(info.regressor(qq))[joint - 1])
    return np.asarray(w @ np.array(rows) / np.sum(w))


def _carried(info, j: int, q: np.ndarray, half: float) -> bool:
    """Whether the motors carry joint ``j``'s sweeps over the window (gravity, friction at 0.9 of
    the velocity limit both ways; rcci.calib.headroom's margins)."""
    from rcci.calib.headroom import HEADROOM, max_current, peak_currents
    from rcci.models import load_robot

    v = 0.9 * float(load_robot(info.name).max_velocity[j - 1])
    th = np.linspace(q[j - 1] - half, q[j - 1] + half, 41)
    path = np.tile(q, (len(th), 1))
    path[:, j - 1] = th
    rate = v / float(th[1] - th[0])                        # samples one step apart at speed v
    cur = np.vstack([peak_currents(info, p, rate) for p in (path, path[::-1])])   # A, both directions
    return bool(np.all(cur <= HEADROOM * max_current(info.name)))


def check_friction_pose(info, joint: int, lo: float, hi: float, q: np.ndarray, points: int = 61) -> None:
    """Refuse (CalibError) a friction window of ``joint`` (1-based) over which gravity does work
    on the arm of ``info`` (rcci.calib.robot.RobotInfo), judged by its regressor: the mean of every
    column of the joint's row over [lo, hi] must vanish (4.5.4), whatever the coefficients.
    FRICTION_POSES were chosen on the PUMA 260; another arm needs poses of its own."""
    from rcci.calib.exceptions import CalibError

    th = np.linspace(lo, hi, points)
    rows = []
    for x in th:
        qq = q.copy()
        qq[joint - 1] = x
        rows.append(np.asarray(info.regressor(qq))[joint - 1])
    mean = np.abs(np.trapezoid(np.array(rows), th, axis=0) / (hi - lo))
    if mean.max() > 1e-9:
        names = ", ".join(n for n, m in zip(info.gravity_names, mean) if m > 1e-9)
        raise CalibError(f"robot {info.name}: gravity does work on joint {joint} over its friction window "
                         f"[{np.degrees(lo):.0f}, {np.degrees(hi):.0f}] deg at the pose "
                         f"{np.round(np.degrees(q), 1).tolist()} deg (through {names})")


def _ready(robot: str) -> np.ndarray:
    from rcci.models import load_robot

    return np.asarray(load_robot(robot).poses["ready"], dtype=float)
