"""Start positions of the gravity sweeps (Table 4.7) and their friction-cancelling repeats.

The repeat of 4.49-4.51 must do the same gravity work in both 90-degree segments.  Best
is the thesis's way, the joint axis made vertical by the joints before it (then gravity
does no work at all and the same joint range is swept); next best keeps the range and
only zeroes the gravity torque at the start (for joint 3, by turning joint 2); for
joint 2, whose axis is always horizontal and whose start torque contains c12 whatever
the later joints do, the range itself has to move.  The search is over a grid of the
free joints, judged by the gravity regressor, so it needs no coefficient values.
"""
from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

DEG = np.pi / 180

# Table 4.7 (degrees): position name -> (joint angles, the joint named after it (1-based)).
TABLE_4_7: dict[str, tuple[tuple[float, ...], int]] = {
    "j5": ((90, 0, 0, 90, 0, 45), 5),
    "j4": ((180, 90, -180, 0, 90, 45), 4),
    "j3A": ((270, 90, -90, 90, 0, 45), 3),
    "j3B": ((270, 90, -90, 90, 90, 45), 3),
    "j2": ((270, 90, 0, 90, 90, 135), 2),
}

# Table 4.8's sweeps, (position, joint): j3B is also swept with joint 2 (the row
# "j3B, c12 - c13, 7.288", whose joint column the OCR lost; c12 - c13 is what 4.24
# gives for joint 2 at j3B with theta2 moved back to 0).
TABLE_4_8_SWEEPS: tuple[tuple[str, int], ...] = (
    ("j5", 5), ("j4", 4), ("j3B", 3), ("j2", 2), ("j3B", 2), ("j3A", 3))


@dataclass(frozen=True)
class Sweep:
    """One gravity sweep: the pose (rad) and the low end of its 180-degree range."""

    name: str
    role: str
    joint: int
    q_start: np.ndarray
    phi_low: float
    how: str  # for the repeat: "vertical axis", "zero start torque", "moved range"


def main_sweep(name: str, joint: int | None = None) -> Sweep:
    """The Table 4.7 sweep: ``joint`` (default: the one the position is named after)
    moved back 90 deg from the start position, then through 180 deg."""
    qdeg, named = TABLE_4_7[name]
    joint = named if joint is None else joint
    q = np.array(qdeg, float) * DEG
    return Sweep(name, "main", joint, q, q[joint - 1] - np.pi / 2, "Table 4.7")


def _row(regressor: Callable[[np.ndarray], np.ndarray], q: np.ndarray, i: int) -> np.ndarray:
    return np.asarray(regressor(q))[i]


def _within(q: np.ndarray, lower: np.ndarray | None, upper: np.ndarray | None,
            margin: float = 0.0) -> bool:
    if lower is None or upper is None:
        return True
    return bool(np.all(q >= lower + margin) and np.all(q <= upper - margin))


def repeat_sweep(main: Sweep, regressor: Callable[[np.ndarray], np.ndarray],
                 lower: np.ndarray | None = None, upper: np.ndarray | None = None,
                 step_deg: float = 15.0, tol: float = 1e-9, margin_deg: float = 8.0) -> Sweep | None:
    """The friction-cancelling repeat of ``main`` (see the module docstring), or None
    when none fits in the joint ranges (the PUMA's joint 2: a zero start torque needs
    theta2 = +-90 deg at one end of a 180-degree sweep, beyond its estimated range).
    Every joint stays ``margin_deg`` inside its range."""
    i = main.joint - 1
    grid = np.arange(-180.0, 180.0 + 1e-9, step_deg) * DEG
    us = np.linspace(0.0, np.pi, 7)

    margin = margin_deg * DEG  # room for the sweep's ramps and the servo's rounding

    def fits(q: np.ndarray, lo: float) -> bool:
        ends = q.copy(), q.copy()
        ends[0][i], ends[1][i] = lo, lo + np.pi
        return _within(ends[0], lower, upper, margin) and _within(ends[1], lower, upper, margin)

    def candidates(free: list[int], base: np.ndarray):
        for vals in itertools.product(grid, repeat=len(free)):
            q = base.copy()
            q[free] = vals
            yield q

    before = list(range(1, i))           # joint 1 turns about g: useless
    best_vertical, best_zero = None, None
    for q in candidates(before, main.q_start):
        if not fits(q, main.phi_low):
            continue
        path = [q.copy() for _ in us]
        for qq, u in zip(path, us):
            qq[i] = main.phi_low + u
        worst = max(np.abs(_row(regressor, qq, i)).max() for qq in path)
        if worst < tol:
            dist = np.abs(q - main.q_start).sum()
            if best_vertical is None or dist < best_vertical[0]:
                best_vertical = (dist, q)
        q0 = q.copy()
        q0[i] = main.phi_low
        if np.abs(_row(regressor, q0, i)).max() < tol:
            dist = np.abs(q - main.q_start).sum()
            if best_zero is None or dist < best_zero[0]:
                best_zero = (dist, q)
    if best_vertical is not None:
        return Sweep(main.name, "repeat", main.joint, best_vertical[1], main.phi_low, "vertical axis")
    if best_zero is not None:
        return Sweep(main.name, "repeat", main.joint, best_zero[1], main.phi_low, "zero start torque")
    # Move the range: the swept joint's start and the next joint are free.
    free = [i, i + 1] if i + 1 < 6 else [i]
    best = None
    for q in candidates(free, main.q_start):
        lo = q[i]
        if not fits(q, lo):
            continue
        if np.abs(_row(regressor, q, i)).max() < tol:
            dist = np.abs(q - main.q_start).sum()
            if best is None or dist < best[0]:
                best = (dist, q, lo)
    if best is None:
        return None
    q = best[1].copy()
    q[i] = best[2] + np.pi / 2
    return Sweep(main.name, "repeat", main.joint, q, best[2], "moved range")
