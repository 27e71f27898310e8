"""The planned-path collision check: a move's path sampled densely enough for its clearance margin.

``check_plan(world, margin, kin, limits, req, plan)`` runs at the planning level on the
``Plan`` that ``move()`` has just checked for reach and singularities (rccl.segments), before
the request is queued. It samples the path from the corner it was planned from to its
destination and raises ``PathCollision`` at the first sample where a checked pair (two links,
or a link and an environment object) is closer than ``margin``.

How dense: the world's ``lever`` bounds how far any capsule point moves per unit of each
joint, so a joint step dq moves every point by at most D(dq) = sum_i lever_i |dq_i|, and a
pair's distance changes by at most 2 D (both bodies move). The samples are spaced so that
2 D between two neighbours is at most ``margin``: every configuration between two samples is
within D <= margin / 2 of the nearer one, so a path accepted keeps every checked pair at
least margin / 2 apart. That holds exactly in joint mode (the path is the straight joint-space
line the quartic generator follows between its corners); in Cartesian mode the joints come
from inverse kinematics at the samples and the bound assumes they move linearly between two
of them (true to first order at this spacing).

A pair already closer than ``margin`` where the motion starts (the arm was brought there)
is refused only if the motion brings it closer still (by more than ``START_TOL``), so that an
arm can always move away from a near contact.
"""
from __future__ import annotations

import math

import numpy as np

from ..drive import drive_coefficients
from ..exceptions import BadRequest, PathCollision
from ..limits import Limits
from ..motion import Request
from ..segments import Kinematics, Plan
from .world import CollisionWorld

START_TOL = 1e-4          # m: how much closer a pair already inside the margin may come (numerical noise)
MAX_SAMPLES = 20000       # samples of one path at most (1 m of point travel at a 0.1 mm margin)
MIN_SAMPLES = 2           # the corner and the destination
COARSE = 16               # Cartesian mode: IK samples that first measure the joint path's length


def samples_needed(length_bound: float, margin: float, where: str) -> int:
    """How many intervals make 2 D per interval <= margin for a path whose D over its whole length is
    ``length_bound`` (m); a BadRequest naming ``where`` if that is more than MAX_SAMPLES."""
    n = max(MIN_SAMPLES, math.ceil(2.0 * length_bound / margin))
    if n > MAX_SAMPLES:
        raise BadRequest(f"{where}: checking this path for a {margin * 1e3:.2f} mm clearance margin would take {n} "
                         f"samples (at most {MAX_SAMPLES}); use a larger margin or a shorter move")
    return int(n)


def path_joints(world: CollisionWorld, margin: float, kin: Kinematics, limits: Limits, req: Request,
                plan: Plan) -> tuple[np.ndarray, np.ndarray]:
    """(fractions 0..1 along the motion, joints there (N, n)) of the planned path, spaced for ``margin``."""
    where = f"move({req.position.name})"
    if plan.mode == "joint" or plan.stationary:
        n = samples_needed(world.displacement(plan.dq), margin, where)
        s = np.linspace(0.0, 1.0, n + 1)
        return s, plan.q_b[None, :] - s[:, None] * plan.dq[None, :]
    coarse = _cartesian(kin, limits, plan, COARSE, where)
    length = sum(world.displacement(b - a) for a, b in zip(coarse[:-1], coarse[1:]))
    n = samples_needed(length, margin, where)
    return np.linspace(0.0, 1.0, n + 1), (coarse if n == COARSE else _cartesian(kin, limits, plan, n, where))


def _cartesian(kin: Kinematics, limits: Limits, plan: Plan, n: int, where: str) -> np.ndarray:
    """Joints at n + 1 evenly spaced points of a Cartesian plan's straight line (inverse kinematics)."""
    lams = 1.0 - np.arange(1, n + 1) / n
    poses = (drive_coefficients(plan.theta, lams) @ plan.basis).reshape(n, 4, 4)
    return kin.ik_path(poses, plan.config, plan.q_b, where, lams, limits)


def travel_time(req: Request, plan: Plan) -> float:
    """The motion's travel time as planned (s): the path's own limit or settime's travel time."""
    travel = req.params.travel_time
    return plan.t_lim if travel is None or travel < plan.t_lim else float(travel)


def collision_error(world: CollisionWorld, where: str, k: int, d: float, margin: float,
                    fraction: float | None, t: float | None, q: np.ndarray, when: str) -> PathCollision:
    """The PathCollision of pair ``k`` at distance ``d`` (m), with a sentence naming both and where."""
    a, b = world.pairs[k]
    gap = f"overlap by {-d * 1e3:.1f} mm" if d < 0 else f"come {d * 1e3:.1f} mm apart"
    msg = (f"{where}: {world.describe(a)} and {world.describe(b)} would {gap}, inside the "
           f"{margin * 1e3:.1f} mm clearance margin, {when} (joints {np.array2string(q, precision=3)})")
    return PathCollision(msg, (a, b), d, margin, fraction, t, q.copy())


def check_plan(world: CollisionWorld, margin: float, kin: Kinematics, limits: Limits, req: Request,
               plan: Plan) -> int:
    """Raise PathCollision at the first sample of ``plan`` too close for ``margin``; return the samples checked."""
    fractions, qs = path_joints(world, margin, kin, limits, req, plan)
    check_samples(world, margin, req, plan, fractions, qs)
    return len(fractions)


def check_samples(world: CollisionWorld, margin: float, req: Request, plan: Plan, fractions: np.ndarray,
                  qs: np.ndarray) -> None:
    """Raise PathCollision at the first of the path's samples (``fractions``, joints ``qs``) too close for ``margin``."""
    start = None
    for s, q in zip(fractions, qs):
        d, k = world.nearest(q)
        if d >= margin:
            continue
        if start is None:
            start = world.distances(qs[0])
        d_all = world.distances(q)
        bad = (d_all < margin) & (d_all < start - START_TOL)
        if bad.any():
            k = int(np.argmin(np.where(bad, d_all, np.inf)))
            t = float(s) * travel_time(req, plan)
            where = f"move({req.position.name})"
            raise collision_error(world, where, k, float(d_all[k]), margin, float(s), t, q,
                                  f"at {100 * s:.0f}% of the path, about {t:.2f} s after the motion starts")
