"""Functionally defined transforms (thesis 5.4.4, E.7-E.8): called once per sample, change per sample limited.

``FunctionalUpdater.update(positions, jac6)`` calls every functional transform found in
``positions`` exactly once (a transform in several equations, or in both segments of a
transition, is still called once), then limits the change of the first position's T6
over the sample: the change dC (frame 6) maps to joint motion through E.8,
dtheta = J^-1 dC (on a 7-joint arm through ``joint_map``: the free joint q7 held, as the
free-parameter rule holds or sets it apart from the pose), and every joint's share of that is kept under ``share`` x its velocity
limit x dt, and (given acceleration limits) may change from one sample to the next by at
most ``share`` x its acceleration limit x dt^2. If some joint would move more, every transform changed this sample is moved
only part of the way from its old value to its new one (translation and rotation angle
scaled alike); the function catches up over the next samples. Near a singularity
(cond(J) above ``max_condition``) a change is refused altogether, so a wild function
cannot produce wild joint motion.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..redundancy import FREE_JOINT
from ..transform import axis_angle, inverse, rot_matrix
from .exceptions import FunctionalError

# estimate: half of each joint's speed for the functional part leaves the other half to the planned motion
DEFAULT_SHARE = 0.5
# estimate: above this condition number E.8's linear relation gives no useful bound (see force.MAX_CONDITION)
DEFAULT_MAX_CONDITION = 1.0e3


def differential(t_from: np.ndarray, t_to: np.ndarray) -> np.ndarray:
    """dC seen in the frame of ``t_from``: (dx, dy, dz, rx, ry, rz) with t_to ~ t_from (I + Delta) (1.7)."""
    # on Python floats: a dozen 3-vector products cost less than numpy's per-call overhead at this size
    (a00, a01, a02, ax), (a10, a11, a12, ay), (a20, a21, a22, az), _ = t_from.tolist()
    (b00, b01, b02, bx), (b10, b11, b12, by), (b20, b21, b22, bz), _ = t_to.tolist()
    px, py, pz = bx - ax, by - ay, bz - az
    # r = R_from^T R_to; only its off-diagonal terms are needed
    r21 = a02 * b01 + a12 * b11 + a22 * b21
    r12 = a01 * b02 + a11 * b12 + a21 * b22
    r02 = a00 * b02 + a10 * b12 + a20 * b22
    r20 = a02 * b00 + a12 * b10 + a22 * b20
    r10 = a01 * b00 + a11 * b10 + a21 * b20
    r01 = a00 * b01 + a10 * b11 + a20 * b21
    return np.array([a00 * px + a10 * py + a20 * pz, a01 * px + a11 * py + a21 * pz, a02 * px + a12 * py + a22 * pz,
                     0.5 * (r21 - r12), 0.5 * (r02 - r20), 0.5 * (r10 - r01)])


def interpolate(m0: np.ndarray, m1: np.ndarray, s: float) -> np.ndarray:
    """The transform a fraction ``s`` of the way from m0 to m1 (relative motion m0^-1 m1 scaled)."""
    rel = inverse(m0) @ m1
    k, theta = axis_angle(rel)
    part = np.eye(4)
    part[:3, :3] = rot_matrix(k, s * theta) if theta > 1e-15 else np.eye(3)
    part[:3, 3] = s * rel[:3, 3]
    return m0 @ part


def joint_map(jac6: np.ndarray) -> np.ndarray:
    """E.8's J^-1 (n x 6, rad per m or rad) for a 6 x n frame-6 Jacobian: the inverse of a 6x6 one;
    for a 7-joint arm the inverse of its six columns other than the free joint (``FREE_JOINT``,
    q7), with a zero row for q7. That is the joint change the inverse kinematics makes for a
    pose change dC at a given q7, which is what every free-parameter rule does (rccl.redundancy:
    q7 held, a function of time, or a small step of its own), so the limiter bounds the joints
    the target's change really moves. Raises numpy's LinAlgError where those columns are singular."""
    n = jac6.shape[1]
    if n == 6:
        return np.linalg.inv(jac6)
    if n != 7:
        raise np.linalg.LinAlgError(f"E.8 joint map: a 6x{n} Jacobian (only 6 joints, or 7 with a free q7)")
    keep = [j for j in range(n) if j != FREE_JOINT]
    out = np.zeros((n, 6))
    out[keep] = np.linalg.inv(jac6[:, keep])
    return out


def step_scale(jac6: np.ndarray, dc6: np.ndarray, max_step: np.ndarray) -> tuple[float, np.ndarray]:
    """Largest s in [0, 1] with |s (J^-1 dc6)_i| <= max_step_i (E.8); also returns dtheta = J^-1 dc6
    (``joint_map``: on a 7-joint arm q7 held)."""
    dtheta = joint_map(jac6) @ dc6
    worst = float(np.max(np.abs(dtheta) / max_step))
    return (1.0 if worst <= 1.0 else 1.0 / worst), dtheta


@dataclass
class UpdateInfo:
    """What one sample's update did: transforms called, the scale applied (1 = unlimited), the condition."""

    called: int = 0
    scale: float = 1.0
    condition: float = 0.0


class FunctionalUpdater:
    """Calls functional transforms once per sample and limits their effect (E.8).

    ``qd_max`` joint velocity limits (rad/s), ``dt`` sample period (s).
    """

    def __init__(self, qd_max: np.ndarray, dt: float, share: float = DEFAULT_SHARE,
                 max_condition: float = DEFAULT_MAX_CONDITION, qdd_max: np.ndarray | None = None) -> None:
        self.max_step = np.asarray(qd_max, dtype=float) * float(dt) * float(share)
        self._dt, self.share = float(dt), float(share)
        # with joint acceleration limits, the functional part of each joint's step may also change by
        # at most share x qdd_max x dt^2 from one sample to the next (no velocity step either)
        self.max_step_change = (None if qdd_max is None
                                else np.asarray(qdd_max, dtype=float) * float(dt) ** 2 * float(share))
        self.prev_dtheta = np.zeros_like(self.max_step)
        self._max_step = self.max_step.tolist()
        self._max_step_change = None if self.max_step_change is None else self.max_step_change.tolist()
        self._cache = None        # (position, snapshot, its transforms' arrays, their T6) after the last update
        self._trs_key: tuple = ()
        self._trs_all: list = []  # every distinct transform of the positions of _trs_key
        self._first_key = None
        self._first_ids: frozenset = frozenset()
        self.max_condition = float(max_condition)
        self.last = UpdateInfo()
        self.limited = 0           # samples in which a change was scaled down

    def set_period(self, qd_max: np.ndarray, dt: float, qdd_max: np.ndarray | None = None) -> None:
        """New step bounds for samples ``dt`` s apart; the last step is rescaled to the same speed."""
        share = self.share
        self.max_step = np.asarray(qd_max, dtype=float) * float(dt) * share
        self.max_step_change = (None if qdd_max is None
                                else np.asarray(qdd_max, dtype=float) * float(dt) ** 2 * share)
        self.prev_dtheta = self.prev_dtheta * (float(dt) / self._dt)
        self._max_step = self.max_step.tolist()
        self._max_step_change = None if self.max_step_change is None else self.max_step_change.tolist()
        self._dt = float(dt)

    @staticmethod
    def functional_transforms(positions) -> list:
        """The distinct transforms of ``positions`` that are functional now (each once)."""
        seen: dict[int, object] = {}
        for p in positions:
            for t in p.transforms():
                if t.kind == "functional" and t.fn is not None:
                    seen.setdefault(id(t), t)
        return list(seen.values())

    def _functional_now(self, positions) -> list:
        """``functional_transforms`` with the equations' distinct transforms kept while the same positions
        are in play (an equation never changes; a transform's kind may, so that is read every sample)."""
        key = tuple(map(id, positions))
        if key != self._trs_key:
            seen: dict[int, object] = {}
            for p in positions:
                for t in p.transforms():
                    seen.setdefault(id(t), t)
            self._trs_key, self._trs_all = key, list(seen.values())
        return [t for t in self._trs_all if t.kind == "functional" and t.fn is not None]

    def _trs_first(self, position) -> frozenset:
        """ids of the transforms of ``position`` (kept per position)."""
        if self._first_key is not position:
            self._first_key, self._first_ids = position, frozenset(map(id, position.transforms()))
        return self._first_ids

    def update(self, positions, jac6, snap=None, jac6_inv: np.ndarray | None = None,
               condition: float | None = None) -> UpdateInfo:
        """Call each functional transform of ``positions`` once; limit the change of positions[0]'s T6.

        ``jac6`` is the frame-6 Jacobian where the arm is, or a function returning it (called
        only if there is a functional transform), or None (no limiting). Raises
        FunctionalError if a function leaves a non-rigid or non-finite transform. ``jac6_inv``
        (optional) is its inverse (``joint_map``'s), if the caller already has it, and ``condition``
        its cond_1.
        """
        trs = self._functional_now(positions)
        info = UpdateInfo(called=len(trs))
        self.last = info
        if not trs:
            return info
        if callable(jac6):
            jac6 = jac6()
        before = [t.value_array for t in trs]
        t6_0 = None
        if jac6 is not None:
            # T6 before this sample's calls: last sample's result if no transform of the equation was
            # replaced since (setters replace a transform's array, never mutate it), else solved anew
            pos = positions[0]
            values = [t.value_array for t in pos.transforms()]
            c = self._cache
            if c is not None and c[0] is pos and c[1] is snap and all(a is b for a, b in zip(c[2], values)) \
                    and len(c[2]) == len(values):
                t6_0 = c[3]
            else:
                t6_0 = pos.solve(snap)
        for t, m0 in zip(trs, before):
            try:
                t.fn(t)
            except FunctionalError:
                raise
            except Exception as exc:  # the user's function: stop, saying which transform
                raise FunctionalError(f"functional transform {t.name!r}: its function raised "
                                      f"{type(exc).__name__}: {exc}") from exc
        # Trsf's setters refuse non-finite values; this catches a function that bypassed them: through
        # the solved T6 for the transforms of positions[0], one by one for the others (or without T6)
        t6_1 = positions[0].solve(snap) if jac6 is not None else None
        in_first = self._trs_first(positions[0])
        if t6_1 is None or not math.isfinite(float(t6_1.sum())):
            in_first = ()
        for t, m0 in zip(trs, before):
            if t.value_array is not m0 and id(t) not in in_first and not math.isfinite(float(t.value_array.sum())):
                raise FunctionalError(f"functional transform {t.name!r}: its function left a non-finite value")
        if jac6 is None:
            return info
        self._cache = (positions[0], snap, [t.value_array for t in positions[0].transforms()], t6_1)
        dc = differential(t6_0, t6_1)
        if not dc.any():
            self.prev_dtheta[:] = 0.0
            return info
        try:
            jinv = joint_map(jac6) if jac6_inv is None else jac6_inv
            # the 1-norm condition number: as good a bound in E.8 as the 2-norm one and far cheaper
            info.condition = (float(np.abs(jac6).sum(axis=0).max() * np.abs(jinv).sum(axis=0).max())
                              if condition is None or jac6_inv is None else float(condition))
        except np.linalg.LinAlgError:
            info.condition = math.inf
        if not info.condition <= self.max_condition:
            s, dtheta = 0.0, np.zeros_like(self.max_step)
        else:
            dtheta = jinv @ dc
            s = 1.0
            steps = self._max_step
            prev = self.prev_dtheta.tolist()
            change = self._max_step_change
            for i, d in enumerate(dtheta.tolist()):
                d = abs(d)
                allowed = steps[i]
                if change is not None:
                    # speed up by at most one acceleration step a, and brake in time: with d still to
                    # go, a step v is allowed if v + (v - a) + (v - 2a) + ... can stop within d, i.e.
                    # v (v + a) / (2a) <= d: v <= (sqrt(a^2 + 8 a d) - a) / 2 (discrete braking)
                    a = change[i]
                    brake = 0.5 * (math.sqrt(a * a + 8.0 * a * d) - a)
                    allowed = min(allowed, min(abs(prev[i]) + a, brake) + 1e-300)
                if d * s > allowed:
                    s = allowed / d
        self.prev_dtheta = s * dtheta
        if s < 1.0:
            self.limited += 1
            info.scale = s
            for t, m0 in zip(trs, before):
                if t.value_array is not m0:
                    t.set(interpolate(m0, t.value_array, s))
            self._cache = None            # the scaled values differ from the solved ones
        return info
