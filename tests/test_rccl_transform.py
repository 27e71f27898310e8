"""RCCL transforms (TRSF): constructors, inverse, angle sets, differential and force maps (thesis 1.4)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from rccl.exceptions import ConstTransformError, TransformError
from rccl.transform import (T6, Trsf, axis_angle, delta_matrix, delta_vector, diff_map, euler, force_map,
                            inverse, noap, rot, rpy, to_euler, to_rpy, trsl)

ang = st.floats(-math.pi, math.pi, allow_nan=False)
small = st.floats(-1.0, 1.0, allow_nan=False)


def random_transform(rng) -> np.ndarray:
    t = rot(rng.normal(size=3), rng.uniform(-math.pi, math.pi))
    t[:3, 3] = rng.uniform(-1, 1, 3)
    return t


@settings(max_examples=60, deadline=None)
@given(ang, st.floats(-1.5, 1.5), ang)
def test_rpy_round_trip(yaw, pitch, roll):
    t = rpy(yaw, pitch, roll)
    assert np.allclose(rpy(*to_rpy(t)), t, atol=1e-9)


@settings(max_examples=60, deadline=None)
@given(ang, st.floats(0.01, math.pi - 0.01), ang)
def test_euler_round_trip(phi, theta, psi):
    t = euler(phi, theta, psi)
    assert np.allclose(euler(*to_euler(t)), t, atol=1e-9)


def test_rpy_is_fixed_axis_x_then_y_then_z():
    # yaw about x first, then pitch about the fixed y: premultiplication
    assert np.allclose(rpy(0.3, 0.0, 0.0), rot("x", 0.3))
    assert np.allclose(rpy(0.3, 0.4, 0.5), rot("z", 0.5) @ rot("y", 0.4) @ rot("x", 0.3))


def test_gimbal_lock_angles_still_reproduce_rotation():
    for pitch in (math.pi / 2, -math.pi / 2):
        t = rpy(0.7, pitch, -0.2)
        assert np.allclose(rpy(*to_rpy(t)), t, atol=1e-9)
    t = euler(0.4, 0.0, 0.3)
    assert np.allclose(euler(*to_euler(t)), t, atol=1e-9)


@settings(max_examples=60, deadline=None)
@given(st.tuples(small, small, small).filter(lambda v: np.linalg.norm(v) > 1e-3), st.floats(0.0, math.pi))
def test_axis_angle_round_trip(axis, angle):
    r = rot(axis, angle)
    k, a = axis_angle(r)
    assert np.allclose(rot(k, a), r, atol=1e-7)
    assert 0.0 <= a <= math.pi + 1e-12


def test_inverse_and_product():
    rng = np.random.default_rng(0)
    for _ in range(20):
        t = random_transform(rng)
        assert np.allclose(inverse(t) @ t, np.eye(4), atol=1e-12)
        a = Trsf("A", t)
        assert np.allclose((a @ a.inv()).matrix, np.eye(4), atol=1e-12)


def test_diff_map_matches_similarity_transform_1_12():
    """D (1.13) applied to dc equals the vector of X^-1 Delta X (1.12), for random X and dc."""
    rng = np.random.default_rng(1)
    for _ in range(20):
        x = random_transform(rng)
        dc = rng.normal(size=6)
        expect = delta_vector(inverse(x) @ delta_matrix(dc) @ x)
        assert np.allclose(diff_map(x) @ dc, expect, atol=1e-12)


def test_force_map_is_inverse_transpose_and_conserves_work():
    rng = np.random.default_rng(2)
    for _ in range(20):
        x = random_transform(rng)
        d, f = diff_map(x), force_map(x)
        assert np.allclose(f, np.linalg.inv(d).T, atol=1e-12)
        dc, q = rng.normal(size=6), rng.normal(size=6)
        assert math.isclose(q @ dc, (f @ q) @ (d @ dc), rel_tol=1e-9, abs_tol=1e-12)  # (1.15)


def test_constructors():
    t = Trsf.trsl("T", 0.25, 0.25, 0.3289)
    assert np.allclose(t.p, [0.25, 0.25, 0.3289]) and t.kind == "const"
    r = Trsf.rot("B", "y", math.pi)
    assert np.allclose(r.a, [0, 0, -1], atol=1e-12)
    n = Trsf.noap("N", [1, 0, 0], [0, 0, 1], [0, -1, 0], [0.1, 0.2, 0.3])
    assert np.allclose(n.matrix, noap([1, 0, 0], [0, 0, 1], [0, -1, 0], [0.1, 0.2, 0.3]))
    e = Trsf.euler("E", 0.1, 0, 0, 0.2, 0.3, 0.4)
    assert np.allclose(e.matrix[:3, :3], euler(0.2, 0.3, 0.4)[:3, :3]) and e.p[0] == 0.1
    y = Trsf.rpy("Y", 0, 0, 0.1, 0.2, 0.3, 0.4)
    assert np.allclose(y.matrix[:3, :3], rpy(0.2, 0.3, 0.4)[:3, :3])
    assert np.allclose(trsl(1, 2, 3) @ rot("z", 0.1), Trsf.rot("R", "z", 0.1, at=(1, 2, 3)).matrix)


def test_kinds_and_errors():
    c = Trsf.trsl("C", 0, 0, 0)
    with pytest.raises(ConstTransformError, match="'C' is const"):
        c.p = [1, 0, 0]
    v = Trsf.trsl("V", 0, 0, 0, kind="variable")
    v.p = [1, 2, 3]
    assert np.allclose(v.p, [1, 2, 3])
    with pytest.raises(TransformError, match="finite 3-vector"):
        v.p = [np.nan, 0, 0]
    with pytest.raises(TransformError, match="not a rigid transform"):
        v.set(np.diag([2.0, 1, 1, 1]))
    with pytest.raises(TransformError, match="kind"):
        Trsf("X", kind="sometimes")
    with pytest.raises(TransformError, match="needs fn"):
        Trsf("F", kind="functional")
    with pytest.raises(TransformError, match="zero length"):
        rot([0, 0, 0], 1.0)
    with pytest.raises(TransformError, match="T6"):
        T6.set(np.eye(4))
    f = Trsf("F", kind="variable")
    f.bind(lambda t: None)
    assert f.kind == "functional"
    f.bind(None)
    assert f.kind == "const"
    with pytest.raises(TransformError, match="read-only|not writeable|assignment"):
        try:
            c.matrix[0, 3] = 5.0
        except ValueError as exc:
            raise TransformError(str(exc)) from exc
