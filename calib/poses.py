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


def table_4_7_identifies(regressor: Callable[[np.ndarray], np.ndarray], lower: np.ndarray,
                         upper: np.ndarray, kinds: tuple[str, ...] | None = None) -> bool:
    """Whether Table 4.8's sweeps serve this arm: every joint revolute, both ends of each
    sweep inside the joint ranges, and their rows identifying every column of the arm's
    regressor (true of the thesis's PUMA 260 and its c12, c13, c15)."""
    if kinds is not None and any(k != "revolute" for k in kinds):
        return False
    rows = []
    for name, joint in TABLE_4_8_SWEEPS:
        sw = main_sweep(name, joint)
        q = sw.q_start.copy()
        for x in (sw.phi_low, sw.phi_low + np.pi):
            q[joint - 1] = x
            if not _within(q, lower, upper):
                return False
        rows.append(_row(regressor, q, joint - 1))
    A = np.array(rows)
    return bool(np.linalg.matrix_rank(A, tol=1e-9 * max(1.0, np.abs(A).max())) == A.shape[1])


def unidentified(A: np.ndarray, names: tuple[str, ...], rtol: float = 1e-9) -> list[str]:
    """The coefficients (``names`` of A's columns) that rows ``A`` leave open: those with a
    part in A's null space (a coefficient whose column is zero, or a combination of
    coefficients every row sees only together)."""
    A = np.atleast_2d(A) / np.maximum(np.sqrt((np.atleast_2d(A) ** 2).mean(axis=0)), 1e-300)
    _, s, vt = np.linalg.svd(A, full_matrices=True)
    rank = int((s > rtol * max(s.max(initial=0.0), 1e-300)).sum())
    null = vt[rank:]
    return [n for n, v in zip(names, np.abs(null).max(axis=0, initial=0.0)) if v > 1e-6]


def _idle_joints(regressor: Callable[[np.ndarray], np.ndarray], lo: np.ndarray, hi: np.ndarray,
                 rng: np.random.Generator, samples: int = 8) -> np.ndarray:
    """Mask of the joints the regressor does not depend on, by trying them at random poses."""
    n = len(lo)
    idle = np.ones(n, dtype=bool)
    for _ in range(samples):
        q = rng.uniform(lo, hi)
        Y = np.asarray(regressor(q))
        for m in range(n):
            if idle[m]:
                q2 = q.copy()
                q2[m] = rng.uniform(lo[m], hi[m])
                idle[m] = np.abs(np.asarray(regressor(q2)) - Y).max() < 1e-12
    return idle


def _short_tour(A: np.ndarray, poses: list[np.ndarray], picked: list[int], keep: float) -> list[int]:
    """``picked`` (rows of A) in the order of a nearest-neighbour tour (joint space, largest
    joint change: what a move between sweeps takes), each stop after the first swapped for
    the candidate nearest the one before it that keeps det(A_S^T A_S) above ``keep`` times
    that of ``picked`` (the identified region's volume, at least sqrt(keep) of it)."""
    P = np.array(poses)
    M = A[picked].T @ A[picked]
    floor = np.linalg.slogdet(M)[1] + np.log(keep)
    rest = list(picked)
    tour = [rest.pop(0)]
    while rest:
        here = P[tour[-1]]
        cur = min(rest, key=lambda c: float(np.abs(P[c] - here).max()))
        rest.remove(cur)
        a = A[cur]
        trial = M - np.outer(a, a) + A[:, :, None] * A[:, None, :]       # every candidate in its place
        sign, logdet = np.linalg.slogdet(trial)
        ok = (sign > 0) & (logdet >= floor)
        ok[tour + rest] = False
        ok[cur] = True
        dist = np.where(ok, np.abs(P - here).max(axis=1), np.inf)
        best = int(np.argmin(dist))
        M = M - np.outer(a, a) + np.outer(A[best], A[best])
        tour.append(best)
    return tour


def identifying_sweeps(regressor: Callable[[np.ndarray], np.ndarray], names: tuple[str, ...],
                       lower: np.ndarray, upper: np.ndarray, kinds: tuple[str, ...],
                       noise: np.ndarray, margin: float, extra: int = 0, candidates: int = 400,
                       seed: int = 1985, keep: float = 0.25) -> list[Sweep]:
    """Gravity sweeps for an arm Table 4.7 does not serve, chosen by its regressor.

    A 180-degree sweep of a revolute joint measures one row of the regressor, the joint's
    at the sweep's start (each direction once, the second with the opposite sign), so an
    arm with k coefficients needs k sweeps whose rows are independent. Candidates are
    random poses inside the ranges (``margin`` rad to spare at both ends of each swept
    joint for the turns), the swept joint's row divided by its expected noise
    (``noise``: its friction, which is what remains of W1 - W2), columns scaled alike;
    k are picked greedily (the largest part of a row outside the span of those already
    picked) and improved by exchanges that raise |det| (the volume of the identified
    region), then ``extra`` more by their leverage. The order is a nearest-neighbour tour
    from the first, each stop traded for a nearer pose where the volume stays above
    ``keep`` of the best (the moves between sweeps took as long as the sweeps). No
    repeat: the fit takes the friction pattern out with each sweep's own up/down profile
    (rcci.calib.gravity). CalibError, naming them, when coefficients cannot be identified by any
    such sweep (a prismatic joint's mass term, say)."""
    from rcci.calib.exceptions import CalibError

    k = len(names)
    rng = np.random.default_rng(seed)
    joints = [i for i, kind in enumerate(kinds)
              if kind == "revolute" and upper[i] - lower[i] >= np.pi + 2 * margin]
    # held joints keep ``margin`` (rad) inside their ranges, a prismatic one 5 % of its stroke
    pad = np.where(np.array(kinds) == "revolute", margin, 0.05 * (upper - lower))
    lo_all, hi_all = lower + pad, upper - pad
    # joints gravity does not see (a vertical joint 1) stay mid-range: shorter moves between sweeps
    idle = _idle_joints(regressor, lo_all, hi_all, rng)
    pool: list[tuple[int, np.ndarray]] = []
    rows = []
    for i in joints:
        for _ in range(candidates):
            q = rng.uniform(lo_all, hi_all)
            q[idle] = (lo_all[idle] + hi_all[idle]) / 2
            q[i] = rng.uniform(lower[i] + margin, upper[i] - margin - np.pi)
            row = _row(regressor, q, i) / noise[i]
            if np.abs(row).max() > 0:
                pool.append((i, q))
                rows.append(row)
    if not rows:
        raise CalibError(f"no joint can be swept through 180 degrees inside its range: gravity "
                         f"coefficients {', '.join(names)} cannot be measured by sweeps")
    A = np.array(rows)
    A = A / np.maximum(np.sqrt((A ** 2).mean(axis=0)), 1e-300)
    open_ = unidentified(A, names)
    if open_:
        raise CalibError("gravity coefficients " + ", ".join(open_) + " cannot be identified by 180-degree "
                         "sweeps of the revolute joints (" + ", ".join(str(i + 1) for i in joints)
                         + ") of this arm: no sweep's regressor row separates them")
    picked: list[int] = []
    R = A.copy()
    for _ in range(k):
        best = int(np.argmax((R ** 2).sum(axis=1)))
        picked.append(best)
        u = R[best] / np.linalg.norm(R[best])
        R = R - np.outer(R @ u, u)
    for _ in range(10):                       # exchanges: det(S with row p -> x) = det(S) (x . S^-1[:, p])
        S_inv = np.linalg.inv(A[picked])
        ratio = np.abs(A @ S_inv)             # (candidates, k)
        ratio[picked] = 0.0
        c, p = np.unravel_index(int(np.argmax(ratio)), ratio.shape)
        if ratio[c, p] <= 1.0 + 1e-9:
            break
        picked[p] = int(c)
    for _ in range(extra):
        M = np.linalg.inv(A[picked].T @ A[picked])
        lev = np.einsum("ij,jk,ik->i", A, M, A)
        lev[picked] = -1.0
        picked.append(int(np.argmax(lev)))
    tour = _short_tour(A, [q for _, q in pool], picked, keep)
    out = []
    for n, c in enumerate(tour, start=1):
        i, q = pool[c]
        phi_low = float(q[i])
        q = q.copy()
        q[i] = phi_low + np.pi / 2
        out.append(Sweep(f"g{n:02d}", "main", i + 1, q, phi_low, "no repeat"))
    return out
