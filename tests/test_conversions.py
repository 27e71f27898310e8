"""Property tests for rci.conversions: every round trip of thesis 4.28-4.38, both robots."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from hypothesis.extra.numpy import arrays

from rci.conversions import Conversions, friction_torque
from rcci.models import load_robot

ROBOTS = ("puma260", "microbo")
CONV = {r: Conversions.for_robot(r) for r in ROBOTS}
MODEL = {r: load_robot(r) for r in ROBOTS}

robots = st.sampled_from(ROBOTS)
batch = st.integers(min_value=1, max_value=5)


def vecs(n_rows: int, lo: float, hi: float):
    return arrays(np.float64, (n_rows, 6), elements=st.floats(lo, hi, allow_nan=False, allow_infinity=False))


@settings(max_examples=60, deadline=None)
@given(robots, batch.flatmap(lambda b: vecs(b, -1.0, 1.0)))
def test_angles_counts_round_trip(robot, u):
    c, m = CONV[robot], MODEL[robot]
    q = m.lower + (u + 1.0) / 2.0 * (m.upper - m.lower)        # inside the joint ranges
    np.testing.assert_allclose(c.counts_to_angles(c.angles_to_counts(q)), q, atol=1e-9)
    # rounding to whole counts loses at most half a count per encoder
    qi = c.counts_to_angles(c.angles_to_counts_int(q))
    e_err = c.angles_to_counts(qi) - c.angles_to_counts(q)
    assert np.all(np.abs(e_err) <= 0.5 + 1e-6)


@settings(max_examples=60, deadline=None)
@given(robots, batch.flatmap(lambda b: vecs(b, -2000.0, 2000.0)))
def test_counts_angles_round_trip(robot, e):
    c = CONV[robot]
    np.testing.assert_allclose(c.angles_to_counts(c.counts_to_angles(e)), e, atol=1e-6)


@settings(max_examples=60, deadline=None)
@given(robots, batch.flatmap(lambda b: vecs(b, -10.0, 10.0)))
def test_motor_joint_round_trips(robot, x):
    c = CONV[robot]
    np.testing.assert_allclose(c.motor_to_joint_angles(c.joint_to_motor_angles(x)), x, atol=1e-9)
    np.testing.assert_allclose(c.joint_to_motor_torques(c.motor_to_joint_torques(x)), x, atol=1e-9)
    np.testing.assert_allclose(c.motor_to_joint_torques(c.joint_to_motor_torques(x)), x, atol=1e-9)


@settings(max_examples=60, deadline=None)
@given(robots, batch.flatmap(lambda b: vecs(b, -2048.0, 2047.0)))
def test_adc_dac_round_trips(robot, v):
    c = CONV[robot]
    np.testing.assert_allclose(c.motor_torques_to_adc(c.adc_to_motor_torques(v)), v, atol=1e-7)
    np.testing.assert_allclose(c.currents_to_adc(c.adc_to_currents(v)), v, atol=1e-7)
    np.testing.assert_allclose(c.joint_torques_to_adc(c.adc_to_joint_torques(v)), v, atol=1e-6)
    np.testing.assert_allclose(c.motor_torques_to_dac(c.dac_to_motor_torques(v)), v, atol=1e-7)
    np.testing.assert_allclose(c.joint_torques_to_dac(c.dac_to_joint_torques(v)), v, atol=1e-6)


@settings(max_examples=60, deadline=None)
@given(robots, batch.flatmap(lambda b: vecs(b, -3.0, 3.0)))
def test_work_is_invariant(robot, x):
    """Power is the same at motor and joint level: t_s . dTheta_s = t_j . dTheta (4.28 with 4.29)."""
    c = CONV[robot]
    t_s, dq = x, x[::-1] if len(x) > 1 else x * 0.5
    lhs = np.sum(t_s * c.joint_to_motor_angles(dq), axis=-1)
    rhs = np.sum(c.motor_to_joint_torques(t_s) * dq, axis=-1)
    np.testing.assert_allclose(lhs, rhs, rtol=1e-9, atol=1e-9)


@settings(max_examples=60, deadline=None)
@given(robots, batch.flatmap(lambda b: vecs(b, -1.0, 1.0)), vecs(1, -1.0, 1.0), vecs(1, -2.0, 2.0))
def test_net_torque_equations_invert(robot, t_a, t_g, qd):
    """4.38 then 4.37 gives back the net torque, with friction handled at the ADC/DAC level."""
    c, m = CONV[robot], MODEL[robot]
    fr = m.friction
    f = friction_torque(qd[0], fr.coulomb_pos.values, fr.coulomb_neg.values,
                        fr.viscous_pos.values, fr.viscous_neg.values)
    v_dac = c.dac_for_net_torques(t_a, t_g[0], c.friction_to_dac(f))
    # the motor then draws the current the DAC commands; the ADC sees that current
    v_adc = c.currents_to_adc(c.dac_to_currents(v_dac))
    np.testing.assert_allclose(c.net_torques(v_adc, c.friction_to_adc(f), t_g[0]), t_a, atol=1e-9)


def test_puma_kadc_and_kappa_reading():
    """k_adc of 4.32 by hand for joint 1, and kappa as DAC/ADC ratio for the same current."""
    c = CONV["puma260"]
    assert c.k_adc[0] == pytest.approx(0.00111 / 0.301 * 0.0732)
    i = np.array([[1.0, -0.5, 0.25, 0.1, 0.2, -0.3]])
    np.testing.assert_allclose(c.motor_torques_to_dac(i * c.sigma) / c.currents_to_adc(i), 1.333, rtol=1e-12)


def test_puma_coupled_wrist_counts():
    """Moving joint 4 alone turns encoders 4, 5 and 6 (R lower triangular, Appendix D)."""
    c = CONV["puma260"]
    de = c.angles_to_counts(np.array([0, 0, 0, 0.1, 0, 0])) - c.angles_to_counts(np.zeros(6))
    np.testing.assert_allclose(de, [0, 0, 0, 554.0, -125.365, 12.732], atol=1e-9)
    # and the motor torque of motor 6 loads joints 4, 5 and 6 (G^T upper triangular)
    tj = c.motor_to_joint_torques(np.array([0, 0, 0, 0, 0, 1.0]))
    np.testing.assert_allclose(tj, [0, 0, 0, 1.0, -6.9424, 31.7692])


def test_tortodac_refuses_nan_and_clips():
    c = CONV["puma260"]
    with pytest.raises(ValueError, match="non-finite"):
        c.tortodac(np.array([0, np.nan, 0, 0, 0, 0]))
    out = c.tortodac(np.array([1e6, -1e6, 0, 0, 0, 0]))
    assert out[0] in (2047, -2048) and out[1] in (2047, -2048) and out.dtype == np.int64


def test_wrong_shape_is_named():
    c = CONV["puma260"]
    with pytest.raises(ValueError, match="encoder counts.*length 6"):
        c.counts_to_angles(np.zeros(5))


def test_friction_torque_eq_4_27():
    fr = MODEL["puma260"].friction
    f = friction_torque(np.array([1.0, -1.0, 0, 0, 0, 0]), fr.coulomb_pos.values, fr.coulomb_neg.values,
                        fr.viscous_pos.values, fr.viscous_neg.values)
    assert f[0] == pytest.approx(0.760 + 0.01203)
    assert f[1] == pytest.approx(-1.620 - 0.00761)
    assert np.all(f[2:] == 0)


def test_printed_and_consistent_encoder_matrices():
    """By default R is the data file's consistent R (r65 = 127.32 g65); the printed one is available."""
    printed = Conversions.from_model(MODEL["puma260"], consistent_encoders=False)
    c = CONV["puma260"]
    diff = np.argwhere(printed.R != c.R)
    assert diff.tolist() == [[5, 4]] and printed.R[5, 4] == -713.01 and c.R[5, 4] == pytest.approx(127.32 * -6.9424, abs=0.01)
    q = np.array([0.1, -0.2, 0.3, 0.4, -0.5, 0.6])
    np.testing.assert_allclose(printed.counts_to_angles(printed.angles_to_counts(q)), q, atol=1e-12)
    # every row of the consistent R is (counts per motor radian) x the row of G
    ratio = c.R / np.where(c.G != 0, c.G, np.nan)
    per_row = np.nanmax(np.abs(ratio), axis=1)
    np.testing.assert_allclose(per_row, [1000 / (2 * np.pi)] * 3 + [800 / (2 * np.pi)] * 3, rtol=2e-4)
