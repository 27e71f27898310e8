"""The Panda's closed-form inverse kinematics with q7 free (derive/inverse_redundant.py, generated
into the arm's module rccl/kinematics/panda.py + _c/panda.c by `python -m derive --robot panda`,
runtime rccl/kinematics/redundant_ik.py, C fast entry _c/kin_redundant.h): every solution
reproduces the pose, the drawn joints are among the solutions, unreachable and singular inputs
raise the named errors, batched equals single, C equals Python (kernels and public entries,
also with RCCL_KINEMATICS=python), fk equals Pinocchio's."""
from __future__ import annotations

import importlib
import json
import os
import subprocess
import sys

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from rcci.models import load_robot
from derive.robots import load_spec
from rccl.kinematics import backend, exceptions, load

MOD = load("panda")
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


def _python_every_config(ts, q7s):
    """q (N, 8, 7) and guards (N, 8, 5) of every configuration by the generated Python ik kernel."""
    qs, gs = [], []
    for c in MOD.Config.all():
        out = MOD._ik_many(ts, q7s, np.broadcast_to(np.array(c.signs, float), (len(ts), 3)))
        qs.append(np.asarray(out[0]))
        gs.append(np.stack([np.asarray(g) for g in out[1:]], axis=-1))
    return np.stack(qs, axis=1), np.stack(gs, axis=1)


def _compiled():
    cm = backend.c_module("panda")
    if cm is None:
        pytest.fail("the compiled panda kernels are missing or stale: `pip install -e .` after "
                    "`python -m derive --robot panda`")
    return cm


def test_c_and_python_kernels_agree():
    cm = _compiled()
    rng = np.random.default_rng(5)
    qs = rng.uniform(LO, HI, size=(64, 7))
    ts = MOD._fk_many(qs)[0]
    q_c, g_c = cm.ik_all(ts, qs[:, 6])[:2]
    with np.errstate(all="ignore"):
        q_p, g_p = _python_every_config(ts, qs[:, 6])
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
    from derive.inverse import REDUNDANT
    from derive.inverse import class_reasons as all_reasons

    r = load_spec("panda").dh
    assert class_reasons(r) == []
    assert all_reasons(r)[REDUNDANT] == []  # derive.inverse takes the class's reasons from here
    links = list(r.links)
    links[4] = DHLink(links[4].d, Q7[4], links[4].alpha, 0.05)  # axes 5 and 6 no longer meet
    bad = DHRobot("bent", tuple(links), r.params)
    assert any("axes 5 and 6" in why for why in class_reasons(bad))
    assert all_reasons(bad)[REDUNDANT] == class_reasons(bad)
    with pytest.raises(OutsideClass, match="axes 5 and 6"):
        redundant_ik(bad)
    assert class_reasons(DHRobot("six", tuple(links[:6]), r.params)) == ["7 joints (the table has 6)"]


def _frames(q):
    """Frames 1..7 of the standard-DH table in the base frame, numerically (4, 4) each."""
    t, out = np.eye(4), []
    for j, qi in zip(load_robot("panda").joints, q):
        ct, st, ca, sa = np.cos(qi), np.sin(qi), np.cos(j.alpha), np.sin(j.alpha)
        t = t @ np.array([[ct, -st * ca, st * sa, j.a * ct], [st, ct * ca, -ct * sa, j.a * st],
                          [0.0, sa, ca, j.d], [0.0, 0.0, 0.0, 1.0]])
        out.append(t)
    return out


@pytest.mark.parametrize("axis, words", [(4, "joint-5 axis")])
def test_shoulder_point_on_a_wrist_axis_is_singular(axis, words):
    """S = (0, 0, d1) on the axis of joint 5 (z4 through W): found by a least-squares search
    over q, then ik of its pose and q7 raises Singular naming the axis. (On the joint-6 axis
    S cannot be on the Panda: test_shoulder_point_never_on_the_joint6_axis.)"""
    from scipy.optimize import least_squares

    s = np.array([0.0, 0.0, load_robot("panda").joints[0].d])

    def off_axis(q):
        f = _frames(q)
        w, z = f[4][:3, 3], f[axis - 1][:3, 2]
        return np.cross(s - w, z)

    fit = least_squares(off_axis, np.array([0.2, 0.3, 0.1, -1.8, 0.4, 1.5, 0.3]), xtol=1e-15, ftol=1e-15, gtol=1e-15)
    q = fit.x
    assert np.abs(off_axis(q)).max() < 1e-12
    t = MOD.fk(q)
    with pytest.raises(exceptions.Singular, match=words):
        for cfg in MOD.Config.all():  # the branch of q is singular (others may be unreachable)
            try:
                MOD.ik(t, cfg, q7=float(q[6]))
            except exceptions.Unreachable:
                continue


def test_shoulder_point_never_on_the_joint6_axis():
    """The joint-6 axis lies in the plane z4 = d5 of frame 4 and S's height there, S4z(q4), stays
    within +-sqrt(a3^2 + d3^2) < d5 on the Panda: guard_axis6 is for other tables of the class."""
    import sympy as sp

    from derive.inverse_redundant import Q7, redundant_ik

    spec = load_spec("panda")
    r, params = spec.dh, spec.params
    s4z = sp.lambdify(Q7[3], redundant_ik(r).named["S4"][2].subs(params))
    q4 = np.linspace(-np.pi, np.pi, 4001)
    height = np.array([float(s4z(x)) for x in q4])
    d5 = load_robot("panda").joints[4].d
    assert np.abs(height).max() < d5 - 0.05


def test_q_ref_keeps_the_reference_branch_and_bad_q_ref_is_named():
    q = np.array([0.4, -0.6, 0.3, -1.8, 0.5, 1.6, -0.4])
    t = MOD.fk(q)
    cfg = MOD.config_of(q)
    np.testing.assert_allclose(MOD.ik(t, cfg, q_ref=q + 0.01, q7=q[6]), q, atol=TOL)
    sols = MOD.ik_all(t, q[6], q_ref=q)
    assert any(np.abs(s - q).max() < TOL for _, s in sols)
    with pytest.raises(exceptions.InvalidInput, match="q_ref"):
        MOD.ik(t, cfg, q_ref=q[:6], q7=q[6])


def test_no_q6_for_the_elbow_height_is_unreachable():
    """guard_wrist_height: the pose of q = (0, -0.3, 0, -2, 0, 1.8, 0.7) with q7 = -1.5 instead of
    0.7 keeps the wrist within the elbow's reach (guard_elbow_reach >= 0) but no q6 puts the
    shoulder point at the height along the joint-5 axis that q4 needs."""
    t = MOD.fk(np.array([0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.7]))
    for cfg in MOD.Config.all():
        (_,), guards, _ = MOD._ROBOT.raw("ik", t, -1.5, np.array(cfg.signs, float))
        assert guards[0] >= 0 > guards[1], f"{cfg}: guards {guards}"
        with pytest.raises(exceptions.Unreachable, match="no q6 puts the shoulder point"):
            MOD.ik(t, cfg, q7=-1.5)
    assert MOD.ik_all(t, -1.5) == []
    assert MOD.ik_all(t, 0.7)  # the drawn q7 reaches it


def _same(a, b) -> bool:
    return [c for c, _ in a] == [c for c, _ in b] and all(np.array_equal(x, y) for (_, x), (_, y) in zip(a, b))


def _outcome(fn, *args, **kw):
    try:
        return fn(*args, **kw)
    except exceptions.KinematicsError as e:
        return type(e)


def test_public_c_entries_agree_with_the_python_runtime():
    """The loader's ik / ik_all are the C fast entries; over random poses and q7 values (the
    drawn one and another, which leaves branches unreachable or out of range) they return
    exactly what the Python runtime returns, or raise the same error."""
    _compiled()
    robot = MOD._ROBOT
    assert MOD.ik_all != robot.ik_all and MOD.ik != robot.ik, "the public entries are not the C ones"
    assert load("panda").ik_all is MOD.ik_all
    rng = np.random.default_rng(21)
    qs = rng.uniform(LO, HI, size=(150, 7))
    others = rng.uniform(LO[6], HI[6], size=150)
    counts = {"solutions": 0, "errors": 0}
    for q, other in zip(qs, others):
        t = MOD.fk(q)
        for q7 in (float(q[6]), float(other)):
            a, b = _outcome(MOD.ik_all, t, q7), _outcome(robot.ik_all, t, q7)
            assert (a is b) if isinstance(b, type) else _same(a, b), (q, q7)
            ref = q + 0.01
            assert _same(MOD.ik_all(t, q7, q_ref=ref), robot.ik_all(t, q7, q_ref=ref))
            for cfg in MOD.Config.all():
                x, y = _outcome(MOD.ik, t, cfg, q7=q7), _outcome(robot.ik, t, cfg, q7=q7)
                if isinstance(y, type):
                    assert x is y
                    counts["errors"] += 1
                else:
                    np.testing.assert_array_equal(x, y)
                    assert float(np.abs(MOD.fk(x)[:3] - t[:3]).max()) <= TOL
                    counts["solutions"] += 1
    assert counts["solutions"] > 300 and counts["errors"] > 300, counts
    ts = MOD.fk(qs)
    batch_c, batch_p = MOD.ik_all(ts, qs[:, 6]), robot.ik_all(ts, qs[:, 6])
    assert len(batch_c) == len(qs) and all(_same(a, b) for a, b in zip(batch_c, batch_p))
    with pytest.raises(exceptions.Unreachable, match="joint 7's range"):
        MOD.ik_all(ts[0], 3.5)
    with pytest.raises(exceptions.InvalidInput, match="free value"):
        MOD.ik(ts[0], MOD.Config(1, 1, 1))


def test_python_fallback_gives_what_the_c_entries_give():
    """RCCL_KINEMATICS=python (no compiled kernels): the same solutions, to the bit where the
    kernels agree and within 1e-9 else (the C and Python kernels round differently)."""
    rng = np.random.default_rng(8)
    qs = rng.uniform(LO, HI, size=(20, 7))
    code = ("import json, numpy as np; from rccl.kinematics import load, backend; m = load('panda'); "
            "assert backend.c_module('panda') is None; "
            f"qs = np.array({qs.tolist()!r}); "
            "print(json.dumps([[[str(c), s.tolist()] for c, s in m.ik_all(m.fk(q), q[6])] for q in qs]))")
    env = dict(os.environ, RCCL_KINEMATICS="python")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    slow = json.loads(out.stdout)
    for q, rows in zip(qs, slow):
        fast = MOD.ik_all(MOD.fk(q), q[6])
        assert [str(c) for c, _ in fast] == [c for c, _ in rows]
        for (_, a), (_, b) in zip(fast, rows):
            np.testing.assert_allclose(a, b, atol=1e-9, rtol=0)


def test_the_loader_gives_one_object_with_dynamics_and_ik():
    """rccl.kinematics.load("panda"): fk, the 6 x 7 Jacobians, gravity, dynamics and the redundant
    ik / ik_all with q7, all from the one generated module."""
    q = np.array([0.1, -0.4, 0.2, -2.0, 0.3, 1.7, 0.5])
    assert MOD.jacobian6(q).shape == (6, 7)
    assert MOD.inertia_matrix(q).shape == (7, 7)
    t = MOD.fk(q)
    cfg = MOD.config_of(q)
    np.testing.assert_allclose(MOD.ik(t, cfg, q7=q[6]), q, atol=TOL)
    assert any(np.abs(s - q).max() < TOL for _, s in MOD.ik_all(t, q[6]))


def test_ik_all_leaves_out_a_branch_that_misses_the_pose():
    """make demo's cross-check (2000 configurations, seed 0) drew a Panda pose where one branch,
    where two branches meet, reproduced T only to 2.8e-9 (> REPRODUCE_TOL): ik_all raised for the
    whole pose. It now returns the branches that reproduce T and leaves that one out."""
    from derive.crosscheck import samples
    from rccl.kinematics.redundant_ik import REPRODUCE_TOL

    kin = MOD
    qs = samples(kin, 2000, 0)
    checked = 0
    for q in qs:
        T = kin.fk(q)
        try:
            sols = kin.ik_all(T, q[6])
        except exceptions.Singular:       # a draw on sin q2 = 0 (the sampler includes such edges): named
            continue
        checked += 1
        for _, sol in sols:
            assert np.abs(kin.fk(sol) - T)[:3].max() <= REPRODUCE_TOL
    assert checked >= 1900, checked
