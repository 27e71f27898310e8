"""A numeric 7-joint stand-in for RCCL's redundancy tests: the Franka Panda's published
modified-DH (Craig) table, its forward kinematics, 6x7 Jacobians and an inverse kinematics
with q7 given (Newton's method on the other six joints from q_ref).

Tests only: it lets rccl.redundancy and the generators be tested on pure math before (and
besides) the generated rccl.kinematics.panda; it follows that module's contract for a
redundant arm: ``ik(T, config, q_ref, q7=...)``, ``jacobian6(q)`` (6, 7), ``config_of(q)``.
Table (Franka's documentation): a = 0, 0, 0, 0.0825, -0.0825, 0, 0.088 m; d = 0.333, 0,
0.316, 0, 0.384, 0, 0 m; alpha = 0, -90, 90, 90, -90, 90, 90 deg; T6 is the flange
frame, 0.107 m along link 7's z axis (as models/panda.toml's frame 7).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from rccl.limits import Limits

A = np.array([0.0, 0.0, 0.0, 0.0825, -0.0825, 0.0, 0.088])
D = np.array([0.333, 0.0, 0.316, 0.0, 0.384, 0.0, 0.0])
ALPHA = np.radians([0.0, -90.0, 90.0, 90.0, -90.0, 90.0, 90.0])
ROBOT = "panda-standin"
JOINT_KINDS = ("revolute",) * 7
LOWER = np.array([-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973])
UPPER = np.array([2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973])
VELOCITY = np.array([2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61])
FLANGE = 0.107
READY = np.array([0.0, -math.pi / 4, 0.0, -3 * math.pi / 4, 0.0, math.pi / 2, math.pi / 4])


class Unreachable(ValueError):
    pass


class Singular(ValueError):
    pass


class Config(NamedTuple):
    wrist: int   # +1: sin(q6) >= 0 (the Panda's usual wrist), -1 otherwise


def limits() -> Limits:
    """The Panda's joint ranges and speeds (Franka's published values), a_max = v_max / 0.25 s."""
    return Limits(LOWER.copy(), UPPER.copy(), VELOCITY.copy(), VELOCITY / 0.25, source="panda stand-in")


def _link(theta: float, i: int) -> np.ndarray:
    """Craig's A-matrix: RotX(alpha_{i-1}) TransX(a_{i-1}) RotZ(theta_i) TransZ(d_i)."""
    ct, st = math.cos(theta), math.sin(theta)
    ca, sa = math.cos(ALPHA[i]), math.sin(ALPHA[i])
    return np.array([[ct, -st, 0.0, A[i]],
                     [st * ca, ct * ca, -sa, -sa * D[i]],
                     [st * sa, ct * sa, ca, ca * D[i]],
                     [0.0, 0.0, 0.0, 1.0]])


def frames(q) -> list[np.ndarray]:
    """Base-to-link-i transforms, i = 1..7."""
    t, out = np.eye(4), []
    for i in range(7):
        t = t @ _link(float(q[i]), i)
        out.append(t)
    return out


def fk(q) -> np.ndarray:
    q = np.asarray(q, dtype=float)
    if q.ndim == 2:
        return np.array([fk(x) for x in q])
    t = frames(q)[-1].copy()
    t[:3, 3] += FLANGE * t[:3, 2]
    return t


def jacobian0(q) -> np.ndarray:
    """Geometric Jacobian (6, 7) of the flange's origin, base frame: rows v (m/rad), w (rad/rad)."""
    fs = frames(q)
    p = fk(q)[:3, 3]
    j = np.empty((6, 7))
    for i, f in enumerate(fs):
        z, o = f[:3, 2], f[:3, 3]
        j[:3, i] = np.cross(z, p - o)
        j[3:, i] = z
    return j


def jacobian6(q) -> np.ndarray:
    """The same Jacobian in the flange frame (6, 7)."""
    r = fk(q)[:3, :3]
    j = jacobian0(q)
    return np.vstack([r.T @ j[:3], r.T @ j[3:]])


def config_of(q) -> Config:
    return Config(1 if math.sin(float(q[5])) >= 0.0 else -1)


def _error(t: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Pose error (6,) from x to t in the base frame: position (m), rotation vector (rad, small)."""
    r = t[:3, :3] @ x[:3, :3].T
    w = 0.5 * np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    return np.concatenate([t[:3, 3] - x[:3, 3], w])


def _newton(t: np.ndarray, q: np.ndarray) -> np.ndarray:
    for _ in range(30):
        e = _error(t, fk(q))
        if np.max(np.abs(e)) < 1e-13:
            return q
        j = jacobian0(q)[:, :6]
        if np.linalg.svd(j, compute_uv=False)[-1] < 1e-6:
            raise Singular(f"stand-in: singular at q = {q}")
        q[:6] += np.linalg.solve(j, e)
    raise Unreachable(f"stand-in: no solution with q7 = {q[6]:.4f}")


def ik(t, config, q_ref=None, q7=None) -> np.ndarray:
    """Joints with q7 given (rad) reproducing T to 1e-13, Newton's method from ``q_ref``
    (q7 carried there in steps of at most 0.05 rad, so the branch is q_ref's)."""
    if q_ref is None or q7 is None:
        raise ValueError("the stand-in needs q_ref and q7")
    t = np.asarray(t, dtype=float)
    q = np.array(q_ref, dtype=float)
    steps = max(1, int(math.ceil(abs(q7 - q[6]) / 0.05)))
    t_ref = fk(q)
    for v in np.linspace(q[6], q7, steps + 1)[1:-1]:
        q[6] = v
        q = _newton(t_ref, q)
    q[6] = q7
    return _newton(t, q)
