"""The rest of the thesis audited (derive/audit.py, last section of reports/thesis-equations.md): the
derivation's own checks hold, the report leaves no numbered equation unaudited, and the project code
named there implements the equation it is named for."""
from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import sympy as sp
import pytest

from derive import audit
from rccl.position import EQ, TL, makeposition
from rccl.trajectory import drive
from rccl.transform import T6, Trsf, axis_angle, delta_matrix, diff_map, force_map, inverse, noap, rot, trsl
from rci.conversions import Conversions, friction_torque

REPORT = Path(__file__).resolve().parent.parent / "reports" / "thesis-equations.md"
RNG = np.random.default_rng(5)


def _rigid() -> np.ndarray:
    q, _ = np.linalg.qr(RNG.normal(size=(3, 3)))
    if np.linalg.det(q) < 0:
        q[:, 0] *= -1
    x = np.eye(4)
    x[:3, :3], x[:3, 3] = q, RNG.normal(size=3)
    return x


def _covered(report: str) -> set[str]:
    """Every equation number the report's rows name (ranges like 4.39-4.43 and lists like 4.28, 4.30 expanded)."""
    out = set()
    for line in report.splitlines():
        if not line.startswith("| ") or line.startswith("| eq."):
            continue
        cell = line.split("|")[1].strip()
        for part in cell.split(","):
            m = re.fullmatch(r"\s*([1-5E])\.(\d+)(?:-(?:[1-5E]\.)?(\d+))?\s*", part)
            if m:
                lo, hi = int(m[2]), int(m[3] or m[2])
                out |= {f"{m[1]}.{i}" for i in range(lo, hi + 1)}
    return out


def test_every_numbered_equation_of_the_audited_ranges_has_a_row_and_none_differs():
    text = REPORT.read_text()
    want = ({f"1.{i}" for i in range(1, 24)} | {f"3.{i}" for i in (83, 84)} | {f"4.{i}" for i in range(1, 58)}
            | {f"5.{i}" for i in range(1, 7)} | {f"E.{i}" for i in range(1, 9)})
    missing = sorted(want - _covered(text), key=lambda s: (s[0], int(s.split(".")[1])))
    assert missing == []
    assert len(want) == 96
    assert "| differs |" not in text


def test_the_derivations_of_the_audit_hold():
    e_print, e_derived = audit.check_delta()
    assert e_print > 1.0 and e_derived < 1e-6          # 1.8: the print's +dw is off, the derived skew form is right
    assert audit.check_homogeneous() < 1e-12 and audit.check_similarity() < 1e-12
    assert audit.check_virtual_work()
    ratio, _ = audit.check_error_expansion()
    assert 50 < ratio < 200                            # second-order remainder (3.84)
    assert audit.check_q_matrices() and audit.check_sensitivity_algebra() and audit.check_friction_repeat()
    gw = audit.gravity_work()
    # W_g the work done against gravity (issue 29, item 12): 4.45, 4.46 and Table 4.8's header stand as
    # printed, and 4.47 is tau0 = -(Wg1 - Wg2)/2, tau1 = -(Wg1 + Wg2)/2
    m, g, r, p0 = sp.symbols("m g r phi0", real=True)
    assert sp.simplify(gw["Wg"] - (-2 * m * g * r * sp.sin(p0))) == 0
    assert sp.simplify(gw["Wg1-Wg2"] - 2 * m * g * r * sp.cos(p0)) == 0
    assert sp.simplify((gw["Wg2"] - gw["Wg1"]) / 2 - (-m * g * r * sp.cos(p0))) == 0      # Table 4.8: = tau0
    assert str(gw["tau0/(Wg1-Wg2)"]) == "-1/2" and str(gw["tau1/(Wg1+Wg2)"]) == "-1/2"
    fl = audit.force_limit_example()                   # 4.53-4.55 read as a limit on f_x: t_l as printed
    F = sp.Symbol("F_l", positive=True)
    assert list(fl["t_l, limit on fx"]) == [F, 0] and list(fl["t_l, limit on fy"]) == [F, F]
    assert audit.two_link_pose() and audit.check_condition_bound()


def test_noap_and_homogeneous_product_1_3():
    x = _rigid()
    t = noap(x[:3, 0], x[:3, 1], x[:3, 2], x[:3, 3])
    r = RNG.normal(size=3)
    np.testing.assert_allclose((t @ np.append(r, 1))[:3], x[:3, :3] @ r + x[:3, 3], atol=1e-12)


def test_delta_matrix_is_the_derived_1_8():
    dc = RNG.normal(size=6)
    np.testing.assert_allclose(delta_matrix(dc), audit.delta_from_motion(dc), atol=1e-5)


def test_force_map_is_d_inverse_transpose_1_21():
    x = _rigid()
    np.testing.assert_allclose(force_map(x), np.linalg.inv(diff_map(x)).T, atol=1e-12)
    # 1.15: the same work seen in both frames
    dc, q = RNG.normal(size=6), RNG.normal(size=6)
    assert float(q @ dc) == pytest.approx(float((force_map(x) @ q) @ (diff_map(x) @ dc)), abs=1e-12)


def test_friction_model_4_27():
    f = friction_torque(np.array([0.5, -0.5, 0.0]), np.full(3, 0.2), np.full(3, 0.3), np.full(3, 0.1), np.full(3, 0.05))
    np.testing.assert_allclose(f, [0.2 + 0.1 * 0.5, -0.3 - 0.05 * 0.5, 0.0])


def test_drive_train_conversions_4_28_to_4_38():
    c = Conversions.for_robot("puma260")
    q, tj = RNG.uniform(-1, 1, 6), RNG.normal(size=6)
    np.testing.assert_allclose(c.joint_to_motor_angles(q), c.G @ q)                       # 4.28
    np.testing.assert_allclose(c.angles_to_counts(q) - c.encoder_offset, c.R @ q)         # 4.30
    ts = c.joint_to_motor_torques(tj)
    np.testing.assert_allclose(c.motor_to_joint_torques(ts), c.G.T @ ts)                  # 4.29
    dq = RNG.normal(size=6)
    assert float(tj @ dq) == pytest.approx(float(ts @ (c.G @ dq)))                        # same work (1.19)
    k_adc = c.v_g / c.sense_resistance * c.sigma                                          # 4.32
    v_adc = RNG.normal(size=6) * 100
    np.testing.assert_allclose(c.adc_to_motor_torques(v_adc), k_adc * v_adc)              # 4.31
    np.testing.assert_allclose(c.adc_to_joint_torques(v_adc), c.G.T @ (k_adc * v_adc))    # 4.36
    k_dac = c.kappa / k_adc                                                               # 4.34 (units, see the report)
    np.testing.assert_allclose(c.joint_torques_to_dac(tj), k_dac * (np.linalg.inv(c.G).T @ tj))   # 4.33, 4.35
    tg, f = RNG.normal(size=6), RNG.normal(size=6)
    ta = c.net_torques(v_adc, c.friction_to_adc(f), tg)                                   # 4.37
    np.testing.assert_allclose(ta, c.G.T @ (k_adc * v_adc) - c.G.T @ (k_adc * c.friction_to_adc(f)) - tg)
    np.testing.assert_allclose(c.dac_for_net_torques(ta, tg, c.friction_to_dac(f)),       # 4.38 inverts 4.37
                               k_dac * (np.linalg.inv(c.G).T @ (ta + tg)) + c.friction_to_dac(f))


def test_second_robot_5_6():
    z = Trsf("Z", trsl(0.1, 0.0, 0.2) @ rot("z", 0.3))
    b = Trsf("B", trsl(0.3, 0.1, 0.0) @ rot("y", math.pi))
    r12 = Trsf("R12", trsl(1.0, -0.4, 0.0) @ rot("z", 2.0))
    p1 = makeposition("p1", z, T6, EQ, b, TL, T6)
    p2 = makeposition("p2", r12, z, T6, EQ, b, TL, T6)
    np.testing.assert_allclose(r12.matrix @ z.matrix @ p2.solve(), b.matrix, atol=1e-12)
    np.testing.assert_allclose(p1.solve(), inverse(z.matrix) @ b.matrix, atol=1e-12)


def test_drive_transform_e1_to_e5():
    d_a, d_b = _rigid(), _rigid()
    rel = inverse(d_a) @ d_b
    k, theta = axis_angle(rel)
    d = rel[:3, 3]
    np.testing.assert_allclose(drive(d, k, theta, 0.0), np.eye(4), atol=1e-12)          # E.3
    np.testing.assert_allclose(d_a @ drive(d, k, theta, 1.0), d_b, atol=1e-9)            # E.4, E.5 at t_b
    mid = [drive(d, k, theta, lam)[:3, 3] for lam in (0.0, 0.25, 0.5, 1.0)]
    np.testing.assert_allclose(mid[1], 0.25 * d, atol=1e-12)                              # straight line


def test_every_test_the_audit_names_exists():
    root = REPORT.parent.parent
    text = REPORT.read_text()
    named = set(re.findall(r"(tests/[\w/]+\.py)::(\w+)", text))
    named |= {(f, t.strip()) for f, ts in re.findall(r"(tests/[\w/]+\.py)::\w+, ((?:::\w+(?:, )?)+)", text)
              for t in ts.replace("::", "").split(",")}
    assert len(named) >= 15
    for path, name in sorted(named):
        assert f"def {name}(" in (root / path).read_text(), f"{path}::{name} named in the report does not exist"
