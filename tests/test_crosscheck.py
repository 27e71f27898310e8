"""Generated kinematics vs Pinocchio on the URDFs (hypothesis + the derive.crosscheck sweep)."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from derive import crosscheck as cc
from rccl.kinematics import exceptions as errors

ROBOTS = list(cc.MODULES)  # every arm under models/: the thesis arms, the PUMA 560 and the Stanford arm
ARMS = {name: cc.PinArm.load(name) for name in ROBOTS}
TOL = 1e-13  # entries are O(1) (m, rad, N m): a few hundred ulps


def joints(name: str):
    mod = cc.MODULES[name]
    edges = cc.edge_values(mod)
    per_joint = [
        st.one_of(st.floats(float(lo), float(hi), allow_nan=False), st.sampled_from(e))
        for lo, hi, e in zip(mod.LOWER, mod.UPPER, edges)
    ]
    return st.tuples(*per_joint).map(np.array)


@pytest.mark.parametrize("name", ROBOTS)
def test_fk_and_jacobians_match_pinocchio(name):
    mod, arm = cc.MODULES[name], ARMS[name]

    @settings(max_examples=150, deadline=None)
    @given(joints(name))
    def check(q):
        assert np.abs(mod.fk(q) - arm.pose(q)).max() < TOL
        j4, j6 = arm.jacobians(q)
        assert np.abs(mod.jacobian6(q) - j6).max() < TOL
        assert np.abs(mod.jacobian4(q) - j4).max() < TOL

    check()


@pytest.mark.parametrize("name", ROBOTS)
def test_gravity_matches_pinocchio(name):
    mod, arm = cc.MODULES[name], ARMS[name]
    from rcci.models import load_robot

    model = load_robot(name)
    masses = np.array([link.mass for link in model.links])
    coms = np.array([link.com for link in model.links])
    coeffs = mod.coefficients_from_links(masses, coms)

    @settings(max_examples=150, deadline=None)
    @given(joints(name))
    def check(q):
        g = arm.gravity(q)
        assert np.abs(mod.gravity(q, coeffs) - g).max() < 1e-12
        assert np.abs(mod.gravity_links(q, masses, coms) - g).max() < 1e-12
        # the model file's coefficients (Table 4.9 for the PUMA) within their 11-digit rounding;
        # a new arm's file may have none yet (docs/kinematics.md, adding an arm)
        if model.gravity_coeffs:
            assert np.abs(mod.gravity(q, model) - g).max() < 1e-9

    check()


@pytest.mark.parametrize("name", ROBOTS)
def test_ik_round_trip(name):
    mod = cc.MODULES[name]
    if not cc.has_ik(mod):  # a redundant arm before derive/inverse_redundant.py: named refusal, no fake solver
        from rccl.kinematics.exceptions import NoSolver

        t = mod.fk(np.asarray(mod.LOWER) / 2 + np.asarray(mod.UPPER) / 2)
        for call in (lambda: mod.ik(t, mod.config_of(mod.LOWER)), lambda: mod.ik_all(t)):
            with pytest.raises(NoSolver, match="inverse_redundant"):
                call()
        return
    if len(mod.JOINT_KINDS) == 7:  # a redundant arm: ik_all(T, q7) with q7 free (more in test_ik_redundant.py)
        rng = np.random.default_rng(28)
        for q in rng.uniform(mod.LOWER, mod.UPPER, size=(100, 7)):
            t = mod.fk(q)
            sols = mod.ik_all(t, q[6])
            assert all(np.abs(mod.fk(s)[:3] - t[:3]).max() < 1e-9 for _, s in sols)
            near = [np.abs((s - q + np.pi) % (2 * np.pi) - np.pi).max() for _, s in sols]
            assert min(near) < 1e-8, (q, near)  # the drawn q is among the solutions
        return

    @settings(max_examples=150, deadline=None)
    @given(joints(name))
    def check(q):
        t = mod.fk(q)
        well = cc.conditioning(mod, q)[0] > cc.WELL_CONDITIONED
        ref = None if well else q
        try:
            sols = mod.ik_all(t, q_ref=ref)
        except errors.Singular:
            sols = mod.ik_all(t, q_ref=q)
        assert sols, "fk(q) must be reachable"
        for cfg, qs in sols:
            # near a singularity the closed form is ill-conditioned: on a boundary the
            # branches meet through sqrt(rounding) (~1e-11 in fk), and within the wrist
            # tolerance (|S5| < 1e-9) theta4 is taken from q_ref, which costs up to |S5|.
            # Each solution by its own distances: another branch of a well-conditioned q can
            # be singular (q = (0, pi/2, 4e-12, 0, pi/2, 0) on the PUMA 260: a branch with
            # theta5 = pi, fk within 3.2e-12)
            sol_well = well and cc.conditioning(mod, qs)[0] > cc.WELL_CONDITIONED
            assert np.abs(mod.fk(qs) - t).max() < (1e-13 if sol_well else 2e-9)
        if well:
            # (near a singularity q itself is not recoverable: the branches meet to within
            # sqrt(eps) and theta4/theta6 trade off; there only fk(ik(T)) = T is asked)
            assert any(cc.joint_error(mod, qs, q) < 1e-10 for _, qs in sols)
            assert cc.joint_error(mod, mod.ik(t, mod.config_of(q)), q) < 1e-10

    check()


@pytest.mark.parametrize("name", ROBOTS)
def test_crosscheck_sweep(name):
    """The report's sweep on a small sample: every quantity near machine precision."""
    mod, arm = cc.MODULES[name], cc.PinArm.load(name)
    qs = cc.samples(mod, 60, seed=3)
    res = cc.CrossCheckResult(name)
    cc.check_forward(mod, arm, qs, res)
    cc.check_jacobians(mod, arm, qs, res)
    cc.check_jacobian_computations(mod, arm, qs, res)
    cc.check_gravity(mod, arm, qs, res)
    if cc.has_ik(mod):
        (cc.check_inverse_redundant if cc.redundant(mod) else cc.check_inverse)(mod, qs, res)
    # q7 free: the runtime's guarantee, every returned solution within 1e-9 (redundant_ik.REPRODUCE_TOL)
    limits = {"model-file coefficients": 1e-9, "relative": 1e-11, "ik(fk(q)": 1e-10, "q7 free": 1e-9}
    for key, err in res.errors.items():
        tol = next((v for k, v in limits.items() if k in key), 1e-12)
        assert err < tol, f"{name}: {key}: {err:.3g} >= {tol:g}"
        assert res.counts[key] > 0, key


def test_redundant_inverse_computations_are_minimum_norm_and_least_squares():
    """The Panda's 6 x 7 Jacobian: joint_from_cartesian solves J dq = dc with dq in J's row
    space (the minimum-norm solution), force_from_torque leaves a residual tau - J^T f
    orthogonal to J^T's range (least squares), in frame 4 and in the last frame; at the
    straight-up pose (joints 1, 3, 5, 7 on one vertical line) J loses rank: Singular."""
    mod = cc.MODULES["panda"]
    rng = np.random.default_rng(11)
    for q in rng.uniform(mod.LOWER, mod.UPPER, size=(20, 7)):
        for frame in (4, 6):
            j = mod.jacobian4(q) if frame == 4 else mod.jacobian6(q)
            dc, tau = rng.normal(size=6), rng.normal(size=7)
            dq = mod.joint_from_cartesian(q, dc, frame)
            assert np.abs(j @ dq - dc).max() < 1e-10
            null = np.linalg.svd(j)[2][-1]                  # J's null space (one direction)
            assert abs(null @ dq) < 1e-10 * max(1.0, np.abs(dq).max())
            f = mod.force_from_torque(q, tau, frame)
            assert np.abs(j @ (tau - j.T @ f)).max() < 1e-10 * max(1.0, np.abs(tau).max())
    with pytest.raises(errors.Singular, match="rank < 6"):
        mod.joint_from_cartesian(np.zeros(7), np.ones(6))
