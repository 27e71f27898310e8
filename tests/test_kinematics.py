"""Defined behaviour of the generated kinematics at singularities, out of reach and on bad input."""
from __future__ import annotations

import numpy as np
import pytest

from rccl.kinematics import exceptions as errors
from rccl.kinematics import microbo as M
from rccl.kinematics import puma260 as P


def _close(a, b, tol=1e-12):
    return np.abs(np.asarray(a) - np.asarray(b)).max() < tol


def test_errors_are_value_errors():
    for cls in (errors.Unreachable, errors.Singular, errors.InvalidInput):
        assert issubclass(cls, errors.KinematicsError)
    assert issubclass(errors.KinematicsError, ValueError)


def test_contract_surface():
    for mod in (P, M):
        for name in ("fk", "ik", "ik_all", "config_of", "jacobian4", "jacobian6", "cartesian_from_joint",
                     "torque_from_force", "joint_from_cartesian", "force_from_torque", "gravity",
                     "gravity_regressor", "tool_load", "CONFIGS", "ROBOT", "Config"):
            assert hasattr(mod, name), (mod.ROBOT, name)
    assert len(P.CONFIGS) == 8 and len(M.CONFIGS) == 2
    assert P.A2 == pytest.approx(0.2032) and P.D3 == pytest.approx(0.12624) and P.D4 == pytest.approx(0.2032)
    assert "make derive" in open(P.__file__).readline()


# -- PUMA -------------------------------------------------------------------------------

Q_PUMA = np.array([0.3, 1.1, -2.0, 0.7, 0.9, -0.4])


def test_puma_wrist_singularity_theta5_zero():
    q = Q_PUMA.copy()
    q[4] = 0.0
    t = P.fk(q)
    with pytest.raises(errors.Singular, match="theta5"):
        P.ik(t, P.config_of(q))
    with pytest.raises(errors.Singular):
        P.ik_all(t)
    # with a reference, theta4 is kept and theta6 absorbs the rest
    q2 = P.ik(t, P.config_of(q), q_ref=q)
    assert q2[3] == q[3]
    assert _close(P.fk(q2), t, 1e-13)
    assert _close(q2, q, 1e-9)
    for frame in (4, 6):
        with pytest.raises(errors.Singular, match="theta5"):
            P.joint_from_cartesian(q, np.ones(6), frame)
        with pytest.raises(errors.Singular):
            P.force_from_torque(q, np.ones(6), frame)


def test_puma_shoulder_singularity_branches_meet():
    # h = a2 C2 - d4 S23 = 0: the wrist centre on the d3-cylinder about the joint-1 axis
    q = np.array([0.4, np.arctan2(P.A2, P.D4), 0.0, 0.5, 1.0, 0.2])
    t = P.fk(q)
    sols = P.ik_all(t)
    assert len(sols) == 4  # left and right arm coincide
    for _, s in sols:
        assert _close(P.fk(s), t, 1e-13)
    for frame in (4, 6):
        with pytest.raises(errors.Singular, match="shoulder"):
            P.joint_from_cartesian(q, np.ones(6), frame)
        with pytest.raises(errors.Singular, match="shoulder"):
            P.force_from_torque(q, np.ones(6), frame)


def test_puma_wrist_centre_on_joint1_axis_is_unreachable():
    # with the d3 shoulder offset no configuration puts the wrist centre on the axis
    t = np.eye(4)
    t[:3, 3] = [0.0, 0.0, 0.15]
    for cfg in P.CONFIGS:
        with pytest.raises(errors.Unreachable, match="cylinder"):
            P.ik(t, cfg)
    assert P.ik_all(t) == []


def test_puma_stretched_elbow():
    q = np.array([0.2, 0.8, -np.pi / 2, 0.3, 0.7, 0.1])
    t = P.fk(q)
    sols = P.ik_all(t)
    assert len(sols) == 4  # elbow up and down coincide
    assert any(np.abs(s - q).max() < 1e-6 for _, s in sols)
    with pytest.raises(errors.Singular, match="elbow"):
        P.joint_from_cartesian(q, np.ones(6))
    # one percent farther out: out of reach in every configuration
    far = t.copy()
    far[:3, 3] *= 1.01
    for cfg in P.CONFIGS:
        with pytest.raises(errors.Unreachable, match="stretched"):
            P.ik(far, cfg)
    assert P.ik_all(far) == []


def test_puma_folded_elbow_wrist_at_shoulder():
    assert P.A2 == P.D4  # Table 3.1: the folded forearm brings the wrist centre to the shoulder
    q = np.array([0.2, 0.8, np.pi / 2, 0.3, 0.7, 0.1])
    t = P.fk(q)
    with pytest.raises(errors.Singular, match="folded"):
        P.ik(t, P.config_of(q))


def test_puma_branch_nearest_reference():
    t = P.fk(Q_PUMA)
    ref = Q_PUMA + np.array([0, 0, 0, 2 * np.pi, 0, -2 * np.pi])
    q = P.ik(t, P.config_of(Q_PUMA), q_ref=ref)
    assert _close(q, ref, 1e-10)


def test_puma_eight_configurations_and_config_of():
    t = P.fk(Q_PUMA)
    sols = P.ik_all(t)
    assert len(sols) == 8
    for cfg, q in sols:
        assert P.config_of(q) == cfg
        assert _close(P.fk(q), t, 1e-13)


def test_elbow_up_means_elbow_above_shoulder_wrist_line():
    for cfg, q in P.ik_all(P.fk(Q_PUMA)):
        s1, c1 = np.sin(q[0]), np.cos(q[0])
        elbow = np.array([c1 * np.cos(q[1]), s1 * np.cos(q[1]), np.sin(q[1])]) * P.A2
        wrist = P.fk(q)[:3, 3]
        # height of the elbow above the shoulder-wrist line, in the arm plane
        along = wrist - np.array([P.D3 * s1, -P.D3 * c1, 0.0])
        t_par = elbow @ along / (along @ along)
        height = (elbow - t_par * along)[2]
        assert np.sign(height) == cfg.elbow, (cfg, height)


def test_batch_matches_single_and_names_bad_row():
    qs = np.array([Q_PUMA, Q_PUMA + 0.1, Q_PUMA - 0.2])
    ts = P.fk(qs)
    assert ts.shape == (3, 4, 4)
    for i in range(3):
        assert _close(ts[i], P.fk(qs[i]), 1e-15)  # math vs numpy: at most an ulp
    cfg = P.config_of(Q_PUMA)
    assert P.ik(ts, cfg).shape == (3, 6)
    bad = qs.copy()
    bad[1, 4] = 0.0
    with pytest.raises(errors.Singular, match="batch row 1"):
        P.ik(P.fk(bad), cfg)
    assert P.gravity(qs, P.gravity_regressor(qs[0]).shape[1] * [1.0]).shape == (3, 6)


def test_bad_input_is_named():
    with pytest.raises(errors.InvalidInput, match="not finite"):
        P.fk([0, 0, np.nan, 0, 0, 0])
    with pytest.raises(errors.InvalidInput, match="shape"):
        P.fk([0, 0, 0])
    t = P.fk(Q_PUMA)
    sheared = t.copy()
    sheared[0, 1] += 0.01
    with pytest.raises(errors.InvalidInput, match="rigid"):
        P.ik(sheared, P.CONFIGS[0])
    with pytest.raises(errors.InvalidInput):
        P.ik(t, (1, 0, 1))
    with pytest.raises(errors.InvalidInput, match="frame"):
        P.cartesian_from_joint(Q_PUMA, np.ones(6), frame=5)
    with pytest.raises(errors.InvalidInput, match="c13"):
        P.gravity(Q_PUMA, {"c12": 1.0, "c15": 1.0})
    with pytest.raises(errors.InvalidInput, match="z6"):
        P.tool_load({"c12": 1.0, "c13": 1.0, "c15": 1.0}, 1.0, [0.01, 0.0, 0.1])


def test_puma_gravity_thesis_form():
    # 4.25: tau_g2 = tau_g3 + C2 c12 (Table 4.9 coefficients)
    c = {"c12": 5.509, "c13": -1.762, "c15": -1.192}
    tau = P.gravity(Q_PUMA, c)
    assert tau[0] == 0.0 and tau[5] == 0.0
    assert tau[1] == pytest.approx(tau[2] + np.cos(Q_PUMA[1]) * 5.509, abs=1e-14)
    # 4.26
    loaded = P.tool_load(c, 0.5, 0.1)
    g = 9.81
    assert loaded["c15"] == pytest.approx(-1.192 - g * 0.5 * 0.1)
    assert loaded["c13"] == pytest.approx(-1.762 - g * 0.5 * P.D4)
    assert loaded["c12"] == pytest.approx(5.509 + g * 0.5 * P.A2)


# -- Microbo ------------------------------------------------------------------------------

Q_MICROBO = np.array([0.3, 0.2, 0.35, 0.7, 2.0, -0.4])


def test_microbo_wrist_singularity_theta5_pi_and_zero():
    for theta5 in (np.pi, 0.0):  # S5 = 0 at both; pi is the straight wrist, inside the range
        q = Q_MICROBO.copy()
        q[4] = theta5
        t = M.fk(q)
        with pytest.raises(errors.Singular, match="theta5"):
            M.ik(t, M.config_of(q))
        q2 = M.ik(t, M.config_of(q), q_ref=q)
        assert q2[3] == q[3] and _close(M.fk(q2), t, 1e-13)
        with pytest.raises(errors.Singular):
            M.joint_from_cartesian(q, np.ones(6))


def test_microbo_out_of_reach_and_axis():
    t = M.fk(Q_MICROBO)
    far = t.copy()
    far[:2, 3] *= 10  # radial extension beyond joint 3's range
    with pytest.raises(errors.Unreachable, match="prismatic joint 3"):
        M.ik(far, M.CONFIGS[0])
    high = t.copy()
    high[2, 3] = M.UPPER[1] + 0.01
    with pytest.raises(errors.Unreachable, match="prismatic joint 2"):
        M.ik(high, M.CONFIGS[0])
    axis = t.copy()
    axis[:2, 3] = 0.0
    with pytest.raises(errors.Singular, match="joint-1 axis"):
        M.ik(axis, M.CONFIGS[0])
    assert M.ik_all(far) == []


def test_microbo_two_configurations():
    t = M.fk(Q_MICROBO)
    sols = M.ik_all(t)
    assert len(sols) == 2
    for cfg, q in sols:
        assert M.config_of(q) == cfg and _close(M.fk(q), t, 1e-13)
