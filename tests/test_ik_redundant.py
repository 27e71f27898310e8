"""The Panda's closed-form inverse kinematics with q7 free (derive/inverse_redundant.py, generated
rccl/kinematics/panda_ik.py + _c/panda_ik.c, runtime rccl/kinematics/redundant.py): every
solution reproduces the pose, the drawn joints are among the solutions, unreachable and singular
inputs raise the named errors, batched equals single, C equals Python, fk equals Pinocchio's."""
from __future__ import annotations

import importlib

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from rcci.models import load_robot
from rccl.kinematics import backend, exceptions

MOD = importlib.import_module("rccl.kinematics.panda_ik")
LO, HI = MOD.LOWER, MOD.UPPER
TOL = 1e-9
#: draws closer than this to a singular or boundary configuration are left to the singular tests
#: (there q's recovery error grows like eps / distance; the pose is still reproduced)
MARGIN = 1e-3


def _wrapped(d):
    return (np.asarray(d) + np.pi) % (2 * np.pi) - np.pi


def _pose_error(t, q):
    return float(np.abs(MOD.fk(q)[:3] - t[:3]).max())


def _conditioned(q) -> bool:
    """q away from the singular sets: every config indicator (sin q2, the elbow's and the
    wrist's root) clear of 0."""
    (vals,), _, _ = MOD._ROBOT.raw("config_indicators", q)
    return bool(np.all(np.abs(vals) > MARGIN))


joint = [st.floats(float(lo), float(hi), allow_nan=False) for lo, hi in zip(LO, HI)]


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.tuples(*joint))
def test_ik_all_contains_q_and_every_solution_reproduces_T(qt):
    q = np.array(qt)
    assume(_conditioned(q))
    t = MOD.fk(q)
    sols = MOD.ik_all(t, q[6])
    assert sols, f"no solution for fk(q), q = {q}"
    best = min(float(np.abs(_wrapped(s - q)).max()) for _, s in sols)
    assert best < TOL, f"q = {q} not among the {len(sols)} solutions (closest {best:.3g})"
    for cfg, s in sols:
        assert _pose_error(t, s) < TOL
        assert np.all(s >= LO - 1e-12) and np.all(s <= HI + 1e-12)
        assert s[6] == pytest.approx(q[6], abs=1e-15)
        assert MOD.config_of(s) == cfg
    match = [c for c, s in sols if np.abs(_wrapped(s - q)).max() < TOL][0]
    assert MOD.config_of(q) == match
    np.testing.assert_allclose(MOD.ik(t, match, q7=q[6]), q, atol=TOL)


def test_fk_equals_pinocchio_on_the_urdf():
    model = pin.buildModelFromUrdf(str(load_robot("panda").urdf_path))
    data = model.createData()
    fid = model.getFrameId("link7")
    rng = np.random.default_rng(7)
    for q in rng.uniform(LO, HI, size=(50, 7)):
        pin.framesForwardKinematics(model, data, q)
        np.testing.assert_allclose(MOD.fk(q), data.oMf[fid].homogeneous, atol=1e-12)


def test_unreachable_poses_raise_and_ik_all_is_empty():
    t = MOD.fk(np.array([0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.7]))
    far = t.copy()
    far[:3, 3] = [1.5, 0.0, 0.5]  # beyond the stretched elbow (reach ~1.2 m from the shoulder)
    with pytest.raises(exceptions.Unreachable, match="elbow's range"):
        MOD.ik(far, MOD.Config(1, 1, 1), q7=0.7)
    assert MOD.ik_all(far, 0.7) == []
    with pytest.raises(exceptions.Unreachable, match="joint 7's range"):
        MOD.ik_all(t, 3.0)
    with pytest.raises(exceptions.InvalidInput, match="free value"):
        MOD.ik(t, MOD.Config(1, 1, 1))


def test_a_solution_outside_the_joint_ranges_is_refused_by_ik_and_left_out_by_ik_all():
    q = np.array([0.4, -0.6, 0.3, -1.8, 0.5, 1.6, -0.4])
    t = MOD.fk(q)
    inside = {c for c, _ in MOD.ik_all(t, q[6])}
    outside = [c for c in MOD.Config.all() if c not in inside]
    assert outside, "every branch in range: the test needs a pose with one outside"
    refused = 0
    for c in outside:
        try:
            MOD.ik(t, c, q7=q[6])
        except exceptions.Unreachable as e:
            refused += 1
            assert "range" in str(e)
    assert refused == len(outside)


def test_singular_shoulder_raises():
    q = np.array([0.3, 0.0, -0.2, -1.5, 0.4, 1.4, 0.2])  # sin q2 = 0: joints 1 and 3 aligned
    t = MOD.fk(q)
    with pytest.raises(exceptions.Singular, match="sin q2 = 0"):
        MOD.ik(t, MOD.config_of(q + np.array([0, 0.1, 0, 0, 0, 0, 0])), q7=q[6])
    with pytest.raises(exceptions.Singular):
        MOD.ik_all(t, q[6])


def test_batched_equals_single():
    rng = np.random.default_rng(3)
    qs = rng.uniform(LO, HI, size=(40, 7))
    ts = MOD.fk(qs)
    cfgs = MOD.config_of(qs)
    cfg = cfgs[0]
    rows = [i for i, c in enumerate(cfgs) if c == cfg]
    qb = MOD.ik(ts[rows], cfg, q7=qs[rows, 6])
    for k, i in enumerate(rows):
        np.testing.assert_allclose(qb[k], MOD.ik(ts[i], cfg, q7=qs[i, 6]), atol=1e-12, rtol=0)
    allb = MOD.ik_all(ts, qs[:, 6])
    for i in range(len(qs)):
        one = MOD.ik_all(ts[i], qs[i, 6])
        assert [c for c, _ in one] == [c for c, _ in allb[i]]
        for (_, a), (_, b) in zip(one, allb[i]):
            np.testing.assert_array_equal(a, b)


def test_c_and_python_kernels_agree():
    cm = backend.c_module("panda_ik")
    if cm is None:
        pytest.fail("the compiled panda_ik kernels are missing or stale: `pip install -e .` after "
                    "`python -m derive.redundant_kernels --robot panda`")
    rng = np.random.default_rng(5)
    qs = rng.uniform(LO, HI, size=(64, 7))
    ts = MOD._fk_many(qs)[0]
    q_c, g_c = cm.ik_all(ts, qs[:, 6])[:2]
    q_p, g_p = MOD._ik_all_many(ts, qs[:, 6])[:2]
    ok = (g_p >= 0).all(axis=-1)
    np.testing.assert_array_equal((g_c >= 0).all(axis=-1), ok)
    # past a failed reach guard the later guards may be NaN in one back end and a number in
    # the other (a square root of a negative radicand clamped or not); compare where both are finite
    both = np.isfinite(g_c) & np.isfinite(g_p)
    assert both[ok].all()
    np.testing.assert_allclose(g_c[both], g_p[both], atol=1e-9)
    np.testing.assert_allclose(q_c[ok], q_p[ok], atol=1e-9)
    np.testing.assert_allclose(cm.fk(qs)[0], ts, atol=1e-12)
    assert MOD._ROBOT.ik_all_kernel is not None, "the runtime does not use the compiled ik_all"


def test_class_reasons_name_what_a_table_misses():
    from derive.dh import DHLink, DHRobot
    from derive.inverse import OutsideClass
    from derive.inverse_redundant import Q7, class_reasons, redundant_ik
    from derive.redundant_kernels import table

    r, _ = table("panda")
    assert class_reasons(r) == []
    links = list(r.links)
    links[4] = DHLink(links[4].d, Q7[4], links[4].alpha, 0.05)  # axes 5 and 6 no longer meet
    bad = DHRobot("bent", tuple(links), r.params)
    assert any("axes 5 and 6" in why for why in class_reasons(bad))
    with pytest.raises(OutsideClass, match="axes 5 and 6"):
        redundant_ik(bad)
    assert class_reasons(DHRobot("six", tuple(links[:6]), r.params)) == ["7 joints (the table has 6)"]
