"""A small numeric PUMA 260 kinematics stand-in for RCCL's tests (A-matrix product + closed-form IK).

Written here, independently of the generated ``rccl.kinematics.puma260``, from the DH table
(a2 = 0.2032, d3 = 0.12624, d4 = 0.2032 m, alpha = 90, 0, -90, 90, -90, 0 deg). It follows
the kinematics contract (fk, ik(T, config, q_ref), config_of, Config) so the trajectory
generator can be tested on pure math; the tests below check it against Pinocchio on the URDF.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pytest

A2, D3, D4 = 0.2032, 0.12624, 0.2032
ALPHA = np.radians([90.0, 0.0, -90.0, 90.0, -90.0, 0.0])
A = np.array([0.0, A2, 0.0, 0.0, 0.0, 0.0])
D = np.array([0.0, 0.0, D3, D4, 0.0, 0.0])
ROBOT = "puma260-standin"


class Unreachable(ValueError):
    pass


class Singular(ValueError):
    pass


class Config(NamedTuple):
    arm: int     # +1: wrist centre in front of the shoulder (X >= 0), -1 behind
    elbow: int   # +1: cos(theta3) >= 0, -1 otherwise
    wrist: int   # +1: sin(theta5) >= 0, -1 otherwise


CONFIGS = [Config(a, e, w) for a in (1, -1) for e in (1, -1) for w in (1, -1)]


def _a(theta: float, i: int) -> np.ndarray:
    ct, st = math.cos(theta), math.sin(theta)
    ca, sa = math.cos(ALPHA[i]), math.sin(ALPHA[i])
    return np.array([[ct, -st * ca, st * sa, A[i] * ct], [st, ct * ca, -ct * sa, A[i] * st],
                     [0.0, sa, ca, D[i]], [0.0, 0.0, 0.0, 1.0]])


def fk(q) -> np.ndarray:
    q = np.asarray(q, dtype=float)
    if q.ndim == 2:
        return np.array([fk(x) for x in q])
    t = np.eye(4)
    for i in range(6):
        t = t @ _a(q[i], i)
    return t


def config_of(q) -> Config:
    q = np.asarray(q, dtype=float)
    x = A2 * math.cos(q[1]) - D4 * math.sin(q[1] + q[2])
    return Config(1 if x >= 0 else -1, 1 if math.cos(q[2]) >= 0 else -1, 1 if math.sin(q[4]) >= 0 else -1)


def _near(angle: float, ref: float) -> float:
    return angle + 2 * math.pi * round((ref - angle) / (2 * math.pi))


def ik(t, config: Config, q_ref=None) -> np.ndarray:
    t = np.asarray(t, dtype=float)
    px, py, pz = t[:3, 3]
    r2 = px * px + py * py
    if r2 < D3 * D3:
        raise Unreachable(f"wrist centre ({px:.4f}, {py:.4f}) m is within d3 of the joint 1 axis")
    phi = math.atan2(py, px)
    x = config.arm * math.sqrt(r2 - D3 * D3)
    th1 = phi + math.atan2(D3, x)
    s3 = (A2 * A2 + D4 * D4 - x * x - pz * pz) / (2 * A2 * D4)
    if abs(s3) > 1 + 1e-12:
        raise Unreachable(f"wrist centre ({px:.4f}, {py:.4f}, {pz:.4f}) m is out of reach")
    s3 = max(-1.0, min(1.0, s3))
    c3 = config.elbow * math.sqrt(1 - s3 * s3)
    th3 = math.atan2(s3, c3)
    u, v = A2 - D4 * s3, D4 * c3
    th2 = math.atan2(pz, x) - math.atan2(v, u)
    t03 = _a(th1, 0) @ _a(th2, 1) @ _a(th3, 2)
    m = t03[:3, :3].T @ t[:3, :3]
    # R36 = Rz(th4) Ry(-th5) Rz(th6)
    s5abs = math.hypot(m[0, 2], m[1, 2])
    ref = np.zeros(6) if q_ref is None else np.asarray(q_ref, dtype=float)
    if s5abs < 1e-9:
        th4 = ref[3]
    else:
        th4 = math.atan2(-config.wrist * m[1, 2], -config.wrist * m[0, 2])
    c4, s4 = math.cos(th4), math.sin(th4)
    s5 = -(c4 * m[0, 2] + s4 * m[1, 2])
    th5 = math.atan2(s5, m[2, 2])
    c5 = math.cos(th5)
    # Ry(th5) Rz(-th4) m = Rz(th6)
    r = np.array([[c5, 0, s5], [0, 1, 0], [-s5, 0, c5]]) @ np.array([[c4, s4, 0], [-s4, c4, 0], [0, 0, 1]]) @ m
    th6 = math.atan2(r[1, 0], r[0, 0])
    q = np.array([th1, th2, th3, th4, th5, th6])
    if q_ref is not None:
        q = np.array([_near(a, b) for a, b in zip(q, ref)])
    return q


# --------------------------------------------------------------------------------------
# tests of the stand-in itself
# --------------------------------------------------------------------------------------
def test_standin_ik_inverts_fk():
    rng = np.random.default_rng(1)
    for _ in range(200):
        q = rng.uniform(-2.5, 2.5, 6)
        q[4] = rng.uniform(0.2, 2.5) * rng.choice([-1, 1])
        c = config_of(q)
        q2 = ik(fk(q), c, q_ref=q)
        assert np.allclose(fk(q2), fk(q), atol=1e-10)
        assert np.allclose(q2, q, atol=1e-8)


def test_standin_ik_raises_when_out_of_reach():
    with pytest.raises(Unreachable):
        ik(np.array([[1, 0, 0, 0.5], [0, 1, 0, 0.3], [0, 0, 1, 0.2], [0, 0, 0, 1.0]]), Config(1, 1, 1))


def test_standin_matches_pinocchio_urdf():
    pin = pytest.importorskip("pinocchio")
    urdf = Path(__file__).resolve().parent.parent / "models" / "urdf" / "puma260.urdf"
    if not urdf.exists():
        pytest.skip("URDF not built yet")
    model = pin.buildModelFromUrdf(str(urdf))
    data = model.createData()
    fid = model.getFrameId("link6")
    rng = np.random.default_rng(2)
    for _ in range(20):
        q = rng.uniform(-1.5, 1.5, 6)
        pin.framesForwardKinematics(model, data, q)
        assert np.allclose(data.oMf[fid].homogeneous, fk(q), atol=1e-9)
