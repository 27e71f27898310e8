"""The PUMA 560: an arm added by its model file alone (models/puma560.toml + its URDF, then
`make derive`): its elbow offset a3 and base height d1 go through the general PUMA-class
inverse, its gravity through the minimal identifiable coefficients. Pinocchio cross-checks
are in tests/test_crosscheck.py (parametrised over every arm under models/)."""
from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from derive.dh import DHLink, DHRobot, Q
from derive.inverse import OutsideClass, class_reasons, solve_ik
from rcci.models import load_robot
from rccl.kinematics import exceptions as errors
from rccl.kinematics import puma560 as P

Q_560 = np.array([0.3, 1.1, -2.0, 0.7, 0.9, -0.4])


def _close(a, b, tol=1e-12):
    return np.abs(np.asarray(a) - np.asarray(b)).max() < tol


def test_constants_are_the_model_files():
    m = load_robot("puma560")
    assert (P.D1, P.A2, P.A3, P.D3, P.D4) == (0.672, 0.4318, 0.0203, 0.15005, 0.4318)
    assert m.source("joints.3.a").tag.startswith("published [CA94]")
    assert len(P.CONFIGS) == 8
    assert np.allclose(P.LOWER, m.lower) and np.allclose(P.UPPER, m.upper)


def test_eight_named_solutions_round_trip():
    t = P.fk(Q_560)
    sols = P.ik_all(t)
    assert len(sols) == 8
    names = {str(cfg) for cfg, _ in sols}
    assert len(names) == 8  # right/left, up/down, noflip/flip all distinct
    for cfg, q in sols:
        assert _close(P.fk(q), t, 1e-13), cfg
        assert P.config_of(q) == cfg  # each solution is in the configuration it is named by
    assert any(_close(q, Q_560, 1e-10) for _, q in sols)
    assert _close(P.ik(t, P.config_of(Q_560)), Q_560, 1e-10)


def test_elbow_offset_and_base_height_enter_fk():
    # q = 0: upper arm along x0 at the shoulder height d1, elbow offset a3 along x,
    # forearm d4 up, the arm's plane offset d3 along -y0 (A1's z1 = -y0)
    t = P.fk(np.zeros(6))
    assert _close(t[:3, 3], [P.A2 + P.A3, -P.D3, P.D1 + P.D4], 1e-15)


def test_unreachable_and_singular():
    t = P.fk(Q_560)
    far = t.copy()
    far[:3, 3] = [2.0, 0.0, 1.0]  # beyond a2 + sqrt(a3^2 + d4^2) from the shoulder
    with pytest.raises(errors.Unreachable, match="stretched elbow"):
        P.ik(far, P.config_of(Q_560))
    inside = t.copy()
    inside[:3, 3] = [0.05, 0.0, 0.9]  # inside the d3-cylinder about the joint-1 axis
    with pytest.raises(errors.Unreachable, match="cylinder"):
        P.ik(inside, P.config_of(Q_560))
    q = Q_560.copy()
    q[4] = 0.0
    with pytest.raises(errors.Singular, match="theta5"):
        P.ik(P.fk(q), P.config_of(q))
    q2 = P.ik(P.fk(q), P.config_of(q), q_ref=q)
    assert _close(P.fk(q2), P.fk(q), 1e-13)
    # the elbow singularity of the 560 is cos(theta3 - phi) = 0, phi = atan2(a3, d4)
    q = Q_560.copy()
    q[2] = np.arctan2(P.A3, P.D4) - np.pi / 2
    with pytest.raises(errors.Singular, match="elbow"):
        P.joint_from_cartesian(q, np.ones(6), 4)


def test_gravity_minimal_set_and_model_coefficients():
    m = load_robot("puma560")
    assert P.GRAVITY_COEFFS == ("cx2", "cy2", "cx3", "cz3", "cx4", "cz4", "cx5", "cz5", "cx6", "cy6")
    assert tuple(m.gravity_coeffs) == P.GRAVITY_COEFFS
    masses = np.array([link.mass for link in m.links])
    coms = np.array([link.com for link in m.links])
    from_links = P.coefficients_from_links(masses, coms)
    for name, value in from_links.items():
        assert m.gravity_coeffs[name].value == pytest.approx(value, abs=1e-9), name
    q = Q_560
    assert _close(P.gravity(q, m), P.gravity_links(q, masses, coms), 1e-9)
    # the regressor's columns are independent: 10 identifiable combinations
    qs = np.random.default_rng(4).uniform(P.LOWER, P.UPPER, (40, 6))
    y = np.vstack([P.gravity_regressor(q) for q in qs])
    assert np.linalg.matrix_rank(y) == 10


def test_outside_every_class_is_refused_naming_why():
    a2, d4 = sp.symbols("a2 d4", positive=True)
    offset = sp.Symbol("a4", positive=True)
    r = DHRobot("offset_wrist", (
        DHLink(0, Q[0], sp.pi / 2, 0), DHLink(0, Q[1], 0, a2), DHLink(0, Q[2], -sp.pi / 2, 0),
        DHLink(d4, Q[3], sp.pi / 2, offset), DHLink(0, Q[4], -sp.pi / 2, 0), DHLink(0, Q[5], 0, 0)), (a2, d4, offset))
    reasons = class_reasons(r)
    assert any("a4 = a5 = a6 = 0" in why for why in reasons["articulated (PUMA class)"])
    assert set(reasons) == {"articulated (PUMA class)", "cylindrical (Microbo class)", "spherical (Stanford class)"}
    with pytest.raises(OutsideClass, match="no closed-form inverse kinematics.*a4 = a5 = a6 = 0"):
        solve_ik(r)


def test_derive_finds_the_arm_and_reports_it():
    from pathlib import Path

    from derive.robots import load_spec, robot_names

    assert set(robot_names()) >= {"puma260", "microbo", "puma560"}
    spec = load_spec("puma560")
    assert not spec.thesis and spec.config_fields == ("arm", "elbow", "wrist")
    assert load_spec("puma260").thesis and load_spec("microbo").config_fields == ("wrist",)
    text = (Path(__file__).resolve().parent.parent / "reports" / "derivation-puma560.md").read_text()
    for section in ("## DH table", "## A matrices", "## T6", "## Inverse kinematics: articulated class",
                    "## Jacobian", "## Gravity", "| cx2 |"):
        assert section in text, section
