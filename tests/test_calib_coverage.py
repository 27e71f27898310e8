"""Issue 14's acceptance: the fits on simula logs recorded against a non-thesis truth, two seeds
(the second under `-m slow`; the shipped logs are the default suite's second seed),
every fitted value within the uncertainty calib prints for it.

For each seed a short calibration set is recorded on real lockstep simula processes (two
recording at a time, each on its own simula) started
with calib/logs/simula-truth.toml (torque sensitivities 5-8 % off Table 4.1, friction 5-20 %
off Tables 4.2-4.5, gravity coefficients off Table 4.9, DH errors): sensitivity runs of the
motors the later fits need, friction sweeps of joints 2 and 6, the gravity sweeps of Table 4.8's
positions but j4 (with their repeats), and (first seed only: the touches are most of the recording
time, and the shipped logs' seed 1985 is the second seed they are held to) 30 kinematic
touches. The logs carry their truth
(meta.truth); the fits are chained through one parameter file exactly as `calib report` does
(no value assumed from the data file), and every value is compared with the truth the logs
name. The shipped logs (seed 1985, full length) are held to the same in test_calib_shipped.
"""
from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from rcci.calib.cli_extra import fit_all
from rcci.calib.experiments import friction_plans, gravity_plans, sensitivity_plans
from rcci.calib.program import run_plan
from rcci.calib.regen import record_kinematics
from rcci.calib.robot import robot_info
from rcci.calib.truth import truth_meta, truth_of

TRUTH = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "calib", "logs",
                     "simula-truth.toml")
SEEDS = (11, 23)
TOUCH_SEED = SEEDS[0]     # the seed whose set includes the kinematic touches
# the second seed is a long run (about a minute of recording): `-m slow` runs it; the default
# suite holds the fits to two seeds through this one and the shipped logs' (test_calib_shipped)
SEED_PARAMS = [pytest.param(s, marks=() if s == TOUCH_SEED else pytest.mark.slow) for s in SEEDS]
INFO = robot_info("puma260")


def _record(sim, plans, out: str, seed: int, args: list[str]) -> None:
    for plan in plans:
        plan.warmup = None        # a warm simula: the warm-up of the shipped runs is not needed
        run_plan(sim.url, plan, os.path.join(out, plan.name + ".rcilog"), rate_hz=plan.rate_hz,
                 extra_meta={"truth": truth_meta(seed, TRUTH, args)})


@pytest.fixture(scope="module", params=SEED_PARAMS, ids=[f"seed{s}" for s in SEEDS])
def calibrated(request, tmp_path_factory):
    """A short calibration set of one seed, fitted as `calib report` fits."""
    from rci.simula.process import SimulaProcess

    seed = request.param
    out = str(tmp_path_factory.mktemp(f"coverage{seed}"))
    args = ["--params", TRUTH, "--warm"]

    def friction(j: int, speeds: tuple[int, ...]) -> None:
        # each friction joint on a fresh, warm simula: a joint that stood a minute has cooled by
        # a few per cent (4.5.3), which the slow-to-fast sweep would read as viscous friction
        with SimulaProcess("-p", *args, lockstep=True, seed=seed) as sim:
            _record(sim, friction_plans([j], speeds_deg=speeds, trips=(1, 1, 2, 2, 3)), out, seed, args)

    def sensitivity() -> None:
        with SimulaProcess("-p", *args, "--test-channel", lockstep=True, seed=seed) as sim:
            # the pulley's mass hung on and taken off between runs (simula's control channel),
            # as a lab would (the channel's load command needs --test-channel), instead of a simula
            # per loaded run as regen-logs starts
            for plan in sensitivity_plans(None, 0.05, joints=(2, 3, 5, 6), speeds_deg=(25, 40), trips=3):
                load = plan.meta["load"]
                spec = (f"pulley:joint={plan.meta['joint']},mass={load['mass_kg']},radius={load['radius_m']}"
                        if load["mass_kg"] > 0 else "none")
                assert sim.command(f"load {spec}")["ok"]
                _record(sim, [plan], out, seed, args)

    def gravity() -> None:
        with SimulaProcess("-p", *args, lockstep=True, seed=seed) as sim:
            # every Table 4.8 position but j4 (whose motor's sensitivity this set does not fit): a
            # sweep's two directions are one observation of the fit
            # (rcci.calib.gravity.sweep_observations), so the three positions recorded before, for
            # three coefficients, would leave no residual to estimate the error from
            plans = [p for p in gravity_plans(INFO.regressor, INFO.lower, INFO.upper) if p.meta["joint"] != 4]
            _record(sim, plans, out, seed, args)

    def touches() -> None:
        record_kinematics(os.path.join(out, "kinematics.rcilog"), seed, TRUTH, touches_per_face=10)

    # every recording on a simula of its own, two at a time (a lockstep pair of simula and
    # controller keeps about one CPU busy): about half the wall time of one after the other.
    # Alone at load 1 (06:44 UTC 28 Nov) sensitivity took 28 s, touches 32 s, gravity 12 s and the
    # friction joints 5-7 s each: both friction joints beside the touches, 40 and 43 s a lane
    # (with joint 6 beside sensitivity and gravity that lane took 47 s, the other 37 s)
    lanes = [[sensitivity, gravity],
             [lambda: friction(2, (15, 25, 60, 100, 150)), lambda: friction(6, (20, 30, 80, 150, 250))]
             + ([touches] if seed == TOUCH_SEED else [])]

    def run_lane(lane) -> None:
        for job in lane:
            job()

    with ThreadPoolExecutor(max_workers=len(lanes)) as pool:
        for done in [pool.submit(run_lane, lane) for lane in lanes]:
            done.result()
    paths = sorted(os.path.join(out, f) for f in os.listdir(out) if f.endswith(".rcilog"))
    res = fit_all(paths, os.path.join(out, "fitted.toml"))
    res["truth"] = truth_of(res["traces"], INFO)
    return res


def test_logs_carry_a_non_thesis_truth(calibrated):
    truth = calibrated["truth"]
    assert "simula-truth.toml" in truth.source and len(truth.seeds) == 1
    table_4_1 = np.asarray(INFO.nominal["motors"]["torque_sensitivity"]["values"])
    assert np.all(np.abs(truth.sigma / table_4_1 - 1) > 0.04)
    assert np.abs(truth.dh_errors).max() > 1e-4


def test_nothing_was_assumed(calibrated):
    for kind, out in calibrated["outcomes"].items():
        assert out.assumed == [], kind


def test_torque_sensitivities_within_their_independent_error(calibrated):
    truth = calibrated["truth"]
    for r in calibrated["outcomes"]["sensitivity"].results:
        assert abs(r.mean - truth.sigma[r.joint - 1]) <= r.independent_error, r


def test_friction_within_its_printed_uncertainty(calibrated):
    """Coulomb (fit and position pattern, 3 sd) and viscous (3 sd) of both directions."""
    truth = calibrated["truth"]
    res = calibrated["outcomes"]["friction"].results
    assert [r.joint for r in res] == [2, 6]
    for r in res:
        j = r.joint - 1
        for fit, fc, fv in ((r.plus, truth.coulomb_pos[j], truth.viscous_pos[j]),
                            (r.minus, truth.coulomb_neg[j], truth.viscous_neg[j])):
            assert abs(fit.coulomb - fc) <= fit.coulomb_err, (r.joint, fit, fc)
            assert abs(fit.viscous - fv) <= fit.viscous_err, (r.joint, fit, fv)
            assert fit.coulomb_pattern_sd > 0


def test_gravity_coefficients_within_their_printed_error(calibrated):
    g = calibrated["outcomes"]["gravity"].results
    truth = calibrated["truth"].gravity
    for k, name in enumerate(g.names):
        assert abs(g.value[k] - truth[k]) <= g.error[k], (name, g.value[k], g.error[k], truth[k], g.fit_std,
                                                          g.direction_diff, [(r.position, r.joint, r.direction, r.tau0) for r in g.rows])


@pytest.mark.parametrize("calibrated", [TOUCH_SEED], indirect=True, ids=[f"seed{TOUCH_SEED}"])
def test_kinematic_errors_within_their_printed_uncertainty(calibrated):
    fit = calibrated["outcomes"]["kinematics"].results
    E = calibrated["truth"].dh_errors.ravel()
    assert fit.rank == 22
    ident = fit.identifiable
    assert ident.sum() == 20
    assert np.all(np.abs(fit.e - E)[ident] <= fit.factor * fit.std[ident])
    names = [c[0] for c in fit.combinations()]
    assert names[0] == "dd2 + dd3"
    for name, value, sd, unit, coef in fit.combinations():
        assert abs(value - coef @ E) <= fit.factor * sd, name
    # the touches themselves: from the nominal table's half millimetre to the encoders' floor
    assert fit.rms_position_before > 2e-4 and fit.rms_position_after < 2e-5


@pytest.mark.parametrize("calibrated", [TOUCH_SEED], indirect=True, ids=[f"seed{TOUCH_SEED}"])
def test_the_parameter_file_is_a_truth_simula_and_rccl_take(calibrated):
    """What calib wrote loads in simula (--params) and in RCCL (rccl.calibrated)."""
    from rccl.calibrated import load_calibrated
    from rcci.models import load_robot
    from rci.simula.params import load_params, truth_from_model

    path = os.path.join(os.path.dirname(calibrated["traces"][0].path), "fitted.toml")
    t = load_params(path, "puma260", truth_from_model(load_robot("puma260")))
    assert t.dh_errors is not None and np.isfinite(t.sigma).all()
    kin = load_calibrated(path)
    q = np.array([1.5, 1.0, -2.0, 0.4, -0.9, 0.3])
    assert np.abs(kin.fk(q) - kin.nominal.fk(q))[:3, 3].max() > 1e-4   # not the nominal arm
