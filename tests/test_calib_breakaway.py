"""Table 4.5 from breakaway ramps: the fit on synthetic ramps, the program on simula (slow)."""
from __future__ import annotations

import numpy as np
import pytest

from rcci.calib.breakaway import breakaway_points, fit_breakaway
from rcci.calib.exceptions import LogError
from rcci.calib.trace import Trace
from tests.test_calib_synth import drive

RATE = 72.0
TAU = 0.015


def _ramp_trace(fs: dict[int, float], joint: int = 5, noise: float = 0.5,
                seed: int = 0) -> Trace:
    """Ramps of joint ``joint`` (1-based) in both directions: the joint torque rises at
    0.1 N m/s from 0 until it exceeds fs[direction], then the joint moves; the ADC sees
    the torque through a 15 ms filter (exact exponential response), plus noise."""
    d = drive(lag=TAU)
    rng = np.random.default_rng(seed)
    i = joint - 1
    t_all, q_all, tau_all, com_all, val_all = [], [], [], [], []
    t0 = 0.0
    for direction in (1, -1, 1, -1):
        t = t0 + np.arange(int(3.0 * RATE)) / RATE
        s = t - t0
        torque = direction * 0.1 * s
        tb = fs[direction] / 0.1
        q = np.zeros((len(t), 6))
        q[:, i] = np.where(s > tb, direction * 2.0 * (s - tb) ** 2, 0.0)
        # first-order filter of a ramp started at 0: r (s - tau (1 - exp(-s / tau)))
        filt = direction * 0.1 * (s - TAU * (1 - np.exp(-s / TAU)))
        tau = np.zeros((len(t), 6))
        tau[:, i] = filt
        com = np.zeros((len(t), 6), dtype=np.uint8)
        com[:, i] = 2
        val = np.zeros((len(t), 6))
        val[:, i] = direction * np.arange(len(t))
        t_all.append(t), q_all.append(q), tau_all.append(tau)
        com_all.append(com), val_all.append(val)
        # a servo cycle between ramps (POS): separates the runs
        t_all.append([t[-1] + 1 / RATE]), q_all.append(q[-1:]), tau_all.append(tau[-1:] * 0)
        com_all.append(np.ones((1, 6), dtype=np.uint8)), val_all.append(np.zeros((1, 6)))
        t0 = t[-1] + 2 / RATE
    t = np.concatenate(t_all)
    q, tau = np.vstack(q_all), np.vstack(tau_all)
    counts = np.round(q @ d.R.T)
    adc = (tau @ np.linalg.inv(d.G)) / d.sigma / d.amps_per_adc + noise * rng.standard_normal(tau.shape)
    tr = Trace(path="ramps.log", robot="puma260", rate_hz=RATE,
               meta={"experiment": "breakaway", "joint": joint, "moved_counts": 3},
               t=t, counts=counts, adc=np.round(adc))
    tr.extra["motion_com"] = np.vstack(com_all)
    tr.extra["motion_value"] = np.vstack(val_all)
    return tr


def test_breakaway_fit_recovers_the_static_friction_of_each_direction():
    fs = {1: 0.197, -1: 0.185}
    tr = _ramp_trace(fs)
    no_gravity = lambda q: np.zeros(6)  # noqa: E731
    pts = breakaway_points(tr, drive(lag=TAU), no_gravity)
    assert [p.direction for p in pts] == [1, -1, 1, -1]
    (res,), _ = fit_breakaway([tr], drive(lag=TAU), no_gravity)
    # the onset is known to half a reading (7 ms x 0.1 N m/s) plus the 3 counts of travel
    assert res.plus == pytest.approx(fs[1], abs=0.004)
    assert res.minus == pytest.approx(fs[-1], abs=0.004)
    assert res.ramps == 4


def test_a_ramp_without_breakaway_is_named():
    tr = _ramp_trace({1: 0.5, -1: 0.185})  # + ramps end at 0.3 N m, before 0.5
    with pytest.raises(LogError, match="no breakaway"):
        breakaway_points(tr, drive(lag=TAU), lambda q: np.zeros(6))


@pytest.mark.slow
def test_breakaway_program_on_simula_measures_table_4_5(tmp_path):
    """`calib record breakaway` for joint 5 on a lockstep simula (about a minute)."""
    from rcci.calib.breakaway_program import breakaway_plans, run_breakaway
    from rcci.calib.logs import load_traces
    from rcci.calib.robot import robot_info
    from rci.simula.process import SimulaProcess

    info = robot_info("puma260")
    fr = info.nominal["friction"]
    (plan,) = breakaway_plans(fr["static_pos"]["values"], info.drive.G, joints=[5])
    log = str(tmp_path / "b.rcilog")
    with SimulaProcess("-p", lockstep=True, seed=3) as sim:
        run_breakaway(sim.url, plan, log)
    (res,), _ = fit_breakaway(load_traces([log]), info.drive, lambda q: np.zeros(6))
    assert res.plus == pytest.approx(fr["static_pos"]["values"][4], rel=0.05)
    assert res.minus == pytest.approx(fr["static_neg"]["values"][4], rel=0.05)
