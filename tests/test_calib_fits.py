"""The calib fits on synthetic data with known truth (no simulator)."""
from __future__ import annotations

import numpy as np
import pytest

from rcci.calib.exceptions import FitError, LogError
from rcci.calib.friction import fit_friction
from rcci.calib.gravity import fit_gravity
from rcci.calib.lsq import bounded_lsq
from rcci.calib.poses import TABLE_4_7, main_sweep, repeat_sweep
from rcci.calib.sensitivity import GRAVITY, fit_sensitivity
from rcci.calib.static import fit_static
from rcci.calib.work import find_passes, window_work
from tests.test_calib_synth import DEG, SIGMA, drive, friction_torque, regressor, sweep, to_trace

FC_P = np.array([0.76, 1.62, 0.85, 0.175, 0.178, 0.140])
FC_M = np.array([0.64, 1.62, 0.75, 0.194, 0.187, 0.159])
FV_P = np.array([12.03, 8.43, 4.78, 0.50, 0.70, 0.31]) / 1000
FV_M = np.array([12.18, 7.61, 4.59, 0.50, 0.69, 0.29]) / 1000
C = np.array([5.509, -1.762, -1.192])  # c12, c13, c15


def rates(t, q):
    return np.gradient(q, t, axis=0)


def test_window_work_of_constant_torque_is_exact():
    th = np.linspace(-0.3, 1.3, 17)
    tau = np.full_like(th, 2.0)
    (p,) = find_passes(th, 0.1, 0.9)
    assert p.direction == 1
    assert window_work(th, tau, p, 0.1, 0.9) == pytest.approx(1.6)
    (q,) = find_passes(th[::-1], 0.1, 0.9)
    assert q.direction == -1
    assert window_work(th[::-1], -tau, q, 0.1, 0.9) == pytest.approx(1.6)


def test_window_work_of_linear_torque_is_exact_off_sample():
    th = np.linspace(0.0, 1.0, 11)
    (p,) = find_passes(th, 0.123, 0.777)
    assert window_work(th, 3 * th, p, 0.123, 0.777) == pytest.approx(1.5 * (0.777**2 - 0.123**2))


def test_turn_inside_window_is_not_a_pass():
    th = np.r_[np.linspace(-0.5, 0.5, 20), np.linspace(0.5, -0.5, 20)]
    assert find_passes(th, -0.2, 0.8) == []


def test_bounded_lsq_holds_negative_estimate_at_zero():
    A = np.c_[np.ones(4), [1.0, 2.0, 3.0, 4.0]]
    fit = bounded_lsq(A, np.array([1.0, 0.9, 0.8, 0.7]), lower=np.zeros(2))
    assert fit.x[1] == pytest.approx(0.0, abs=1e-9) and fit.x.min() >= 0.0
    assert fit.x[0] == pytest.approx(0.85, abs=1e-6)
    with pytest.raises(FitError, match="do not separate"):
        bounded_lsq(np.c_[np.ones(3), np.ones(3)], np.ones(3))


def test_sensitivity_recovers_table_4_1_through_the_coupled_wrist():
    rng = np.random.default_rng(1)
    d = drive()
    traces = []
    for j in range(6):
        lo, hi = 0.0, 60 * DEG
        t, q = sweep(np.zeros(6), j, lo, hi, [0.3] * 4)
        qd = rates(t, q)
        fric = friction_torque(qd, FC_P, FC_M, FV_P, FV_M)
        for mass in (0.0, 2.0):
            tau = fric.copy()
            tau[:, j] += mass * GRAVITY * 0.05 * (1 + 0.03 * (mass > 0))  # load raises friction 3 %
            tau[:, j] += 0.03 * mass * np.sign(qd[:, j])
            meta = {"experiment": "sensitivity", "joint": j + 1, "window": [lo, hi],
                    "load": {"mass_kg": mass, "radius_m": 0.05 * (1 + 0.03 * (mass > 0)), "sign": 1}}
            traces.append(to_trace(t, q, tau, meta, d, rng))
    # the fit knows nothing of the true sigma: hand it a wrong one
    res = fit_sensitivity(traces, drive(np.full(6, 0.05)))
    got = np.array([r.mean for r in res])
    np.testing.assert_allclose(got, SIGMA, rtol=0.01)
    assert all(r.trials == 4 for r in res)


def test_friction_fit_recovers_tables_4_2_and_4_3():
    rng = np.random.default_rng(2)
    d = drive()
    traces = []
    for j in range(6):
        # three round trips per speed: one pass per speed left the viscous fit within
        # 15 % only for lucky seeds (the tapered pass mean of rcci.calib.work weighs 3/4 of a
        # 1 rad window)
        t, q = sweep(np.zeros(6), j, -0.5, 0.5, [0.05, 0.2, 0.5, 0.9, 1.4] * 3)
        tau = friction_torque(rates(t, q), FC_P, FC_M, FV_P, FV_M)
        tau[:, j] *= 1 + 0.1 * np.sin(7 * q[:, j])  # position-dependent variation
        meta = {"experiment": "friction", "joint": j + 1, "window": [-0.5, 0.5]}
        traces.append(to_trace(t, q, tau, meta, d, rng))
    res, points = fit_friction(traces, d)
    for r in res:
        j = r.joint - 1
        assert r.plus.coulomb == pytest.approx(FC_P[j], abs=0.03 * FC_P[j] + 0.005)
        assert r.minus.coulomb == pytest.approx(FC_M[j], abs=0.03 * FC_M[j] + 0.005)
        assert r.plus.viscous == pytest.approx(FV_P[j], abs=max(0.15 * FV_P[j], 3e-4))
        assert 0.05 < r.variation < 0.15
    assert len(points) == 6 * 30


def test_static_friction_statistics_of_halts():
    rng = np.random.default_rng(3)
    d = drive()
    truth = rng.normal(0.0, 0.1, size=(60, 6))
    ts, qs, taus, t0 = [], [], [], 0.0
    for k in range(60):
        q = rng.uniform(-1, 1, 6)
        n = 36
        ts.append(t0 + np.arange(n) / 36.0)
        t0 += n / 36.0 + 1.0
        qs.append(np.tile(q, (n, 1)))
        taus.append(np.tile(regressor(q) @ C + truth[k], (n, 1)))
    tr = to_trace(np.concatenate(ts), np.vstack(qs), np.vstack(taus),
                  {"experiment": "static"}, d, rng, adc_noise=0.0)
    res, samples = fit_static([tr], d, lambda q: regressor(q) @ C)
    assert samples.shape == (60, 6)
    for r in res:
        s = truth[:, r.joint - 1]
        assert r.mean == pytest.approx(s.mean(), abs=0.01)
        assert r.std == pytest.approx(s.std(ddof=1), abs=0.01)


def _gravity_traces(rng, friction_tilt: float):
    """Sweeps at the Table 4.7 positions and their repeats; friction rises along the path
    by friction_tilt per radian so that W_f1 != W_f2 and only the repeat removes it."""
    d = drive()
    traces = []
    for name in TABLE_4_7:
        main = main_sweep(name)
        for sw in (main, repeat_sweep(main, regressor)):
            j, lo = sw.joint - 1, sw.phi_low
            t, q = sweep(sw.q_start, j, lo, lo + np.pi, [0.4, 0.4])
            qd = rates(t, q)
            tau = np.array([regressor(qq) @ C for qq in q])
            fr = friction_torque(qd, FC_P, FC_M, FV_P, FV_M)
            fr[:, j] *= 1 + friction_tilt * (q[:, j] - main.phi_low)
            tau += fr
            meta = {"experiment": "gravity", "joint": sw.joint, "position": name,
                    "role": sw.role, "q_start": list(sw.q_start), "phi_low": lo}
            traces.append(to_trace(t, q, tau, meta, d, rng))
    return traces, d


def test_gravity_fit_recovers_table_4_9_and_the_repeat_matters():
    rng = np.random.default_rng(4)
    traces, d = _gravity_traces(rng, friction_tilt=0.05)
    res = fit_gravity(traces, d, regressor, ("c12", "c13", "c15"))
    assert np.all(np.abs(res.value - C) < [0.05, 0.02, 0.005]), res.value
    assert (res.friction_error > 0.002).any()
    assert len(res.rows) == 10  # five positions, both directions


def test_a_sweeps_two_directions_are_one_observation():
    """The + and - rows of a sweep (opposite regressor rows, opposite errors: a drift both passes
    share) are averaged into one observation; the fit's degrees of freedom count sweeps, and a
    row without its opposite stays an observation of its own."""
    from rcci.calib.gravity import GravityRow, sweep_observations

    r = np.array([0.8, -0.3, 0.1])
    rows = [GravityRow("a", 2, 1, 2.0 + 0.01, 2.0, r, r, 1), GravityRow("a", 2, -1, -2.0 - 0.01, -2.0, -r, -r, 1),
            GravityRow("b", 3, 1, 0.5, 0.5, 2 * r, 2 * r, 1)]
    A, y, joint = sweep_observations(rows, True, 3)
    assert A.shape == (2, 3) and joint.tolist() == [2, 3]
    assert np.allclose(A[0], r) and y[0] == pytest.approx(2.01)    # the shared error stays, once
    assert np.allclose(A[1], 2 * r) and y[1] == 0.5


def test_missing_metadata_names_the_file_and_key():
    rng = np.random.default_rng(5)
    t, q = sweep(np.zeros(6), 0, -0.5, 0.5, [0.5])
    tr = to_trace(t, q, np.zeros_like(q), {"experiment": "friction", "joint": 1}, drive(), rng,
                  path="runs/f1.log")
    with pytest.raises(LogError, match=r"runs/f1.log: missing metadata 'window'"):
        fit_friction([tr], drive())


def test_current_filter_lag_is_compensated():
    """Torques through the 15 ms current filter of Appendix C: gravity on a swept joint
    2 then lags position by the filter's time constant; pairing readings with the angle
    15 ms earlier keeps it from reading as viscous friction."""
    from tests.test_calib_synth import drive as make_drive

    rng = np.random.default_rng(6)
    q0 = np.radians([90, 90, -90, 90, 90, 0])
    dt_sub = 1e-3
    # turn 0.5 rad beyond the window: the filter settles (5 tau) before the window
    t, q = sweep(q0, 1, np.radians(40), np.radians(140), [0.1, 0.5, 1.0, 2.0, 2.5], rate=1000.0,
                 margin=0.5)
    tau = np.array([regressor(x) @ C for x in q]) + friction_torque(rates(t, q), FC_P, FC_M, FV_P, FV_M)
    filt = np.empty_like(tau)
    filt[0] = tau[0]
    a = 1 - np.exp(-dt_sub / 0.015)
    for k in range(1, len(tau)):
        filt[k] = filt[k - 1] + a * (tau[k] - filt[k - 1])
    keep = slice(None, None, 28)  # sample the filtered current at about 36 Hz
    meta = {"experiment": "friction", "joint": 2, "window": [np.radians(40), np.radians(140)]}
    tr = to_trace(t[keep], q[keep], filt[keep], meta, make_drive(), rng, adc_noise=0.0)
    # the filter here is discrete (1 ms steps), whose delay is tau - h/2 = 14.5 ms
    lagged, _ = fit_friction([tr], make_drive(lag=0.0145))
    naive, _ = fit_friction([tr], make_drive(lag=0.0))
    assert lagged[0].plus.viscous == pytest.approx(FV_P[1], abs=5e-4)
    assert abs(naive[0].plus.viscous - FV_P[1]) > 0.02  # gravity read as viscous friction
