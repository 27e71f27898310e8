"""Fits of the logs shipped in calib/logs/ (recorded on simula by `calib regen-logs`)
against the simulator's ground truth, with the thesis's stated uncertainties."""
from __future__ import annotations

import glob
import os

import numpy as np
import pytest

from calib.cli_extra import LOG_DIR, fit_all
from calib.params import read_params
from calib.truth import simulator_truth

LOGS = sorted(glob.glob(os.path.join(LOG_DIR, "*.rcilog.*")))
pytestmark = pytest.mark.skipif(not LOGS, reason="no shipped logs: run `calib regen-logs`")


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    params = str(tmp_path_factory.mktemp("calib") / "fitted.toml")
    res = fit_all(LOGS, params)
    res["params"] = params
    res["truth"] = simulator_truth(res["info"])
    return res


def test_shipped_logs_are_small_and_cover_every_experiment():
    total = sum(os.path.getsize(p) for p in LOGS)
    assert total < 10e6, f"shipped logs are {total / 1e6:.1f} MB"
    kinds = {os.path.basename(p).split("-")[0].split(".")[0] for p in LOGS}
    assert kinds == {"friction", "gravity", "sensitivity", "static", "breakaway"}


def test_gravity_coefficients_within_table_4_9_uncertainty(fitted):
    g = fitted["outcomes"]["gravity"].results
    truth = fitted["truth"].gravity
    tol = {"c12": 0.15, "c13": 0.04, "c15": 0.005}
    for k, name in enumerate(g.names):
        assert abs(g.value[k] - truth[k]) <= tol[name], (name, g.value[k], truth[k])


def test_coulomb_friction_within_table_4_2_bounds(fitted):
    fr = fitted["info"].nominal["friction"]
    truth = fitted["truth"]
    for r in fitted["outcomes"]["friction"].results:
        j = r.joint - 1
        assert abs(r.plus.coulomb - truth.coulomb_pos[j]) <= fr["coulomb_pos"]["uncertainty"][j], r
        assert abs(r.minus.coulomb - truth.coulomb_neg[j]) <= fr["coulomb_neg"]["uncertainty"][j], r


# Every row of Table 4.3, joint 5 included: its bounds (+-0.04e-3, +-0.05e-3, 6 % of the
# coefficient) are met because its fast passes are read at every servo tick (the ripple
# cancels) and each pass is weighted with smooth edges (docs/calib.md, "Joint 5"); the
# fast passes of joints 2, 3, 4 and 6 are read the same way.
VISCOUS = [(j, key) for j in range(1, 7) for key in ("viscous_pos", "viscous_neg")]


@pytest.mark.parametrize("joint,key", VISCOUS)
def test_viscous_friction_within_table_4_3_bounds(fitted, joint, key):
    """Table 4.3's stated uncertainty (e.g. +-0.9e-3 on joint 1, +-0.04e-3 on joint 6)."""
    fr = fitted["info"].nominal["friction"]
    tv = getattr(fitted["truth"], key)[joint - 1]
    (r,) = [r for r in fitted["outcomes"]["friction"].results if r.joint == joint]
    fit = r.plus if key == "viscous_pos" else r.minus
    assert abs(fit.viscous - tv) <= fr[key]["uncertainty"][joint - 1], (joint, key, fit, tv)


def test_viscous_friction_error_bars_are_honest(fitted):
    """The fit's own error (twice its standard deviation, 4.5.4) is not an understatement:
    the truth lies within three standard deviations (1.5 x the error) for all 12
    coefficients. (At two, one of 12 falls outside by chance about half the time; the
    shipped logs put joint 6's + coefficient at 1.07 x its error.)"""
    truth = fitted["truth"]
    for r in fitted["outcomes"]["friction"].results:
        j = r.joint - 1
        for fit, tv in ((r.plus, truth.viscous_pos[j]), (r.minus, truth.viscous_neg[j])):
            assert abs(fit.viscous - tv) <= 1.5 * fit.viscous_err, (r.joint, fit, tv)


def test_friction_logs_read_fast_passes_of_joints_2_to_6_at_every_servo_tick(fitted):
    rates = {(t.meta["joint"], os.path.basename(t.path)): t.rate_hz
             for t in fitted["traces"] if t.experiment == "friction"}
    for j in (2, 3, 4, 5, 6):
        assert rates[(j, f"friction-j{j}-servo.rcilog.xz")] == 1000
        assert rates[(j, f"friction-j{j}.rcilog.xz")] == 72


def test_variation_within_a_fifth_of_the_pattern_in_the_window(fitted):
    """Table 4.4 gives approximate values, no bounds: the fit is held to 20 % of the same
    statistic of simula's pattern over the window (calib.truth.simula_variation)."""
    from calib.truth import simula_variation

    windows = {t.meta["joint"]: (int(t.meta["simula_seed"]), tuple(t.meta["window"]))
               for t in fitted["traces"] if t.experiment == "friction"}
    for r in fitted["outcomes"]["friction"].results:
        seed, window = windows[r.joint]
        _, truth = simula_variation(fitted["info"].name, seed, r.joint, window)
        assert abs(r.variation - truth) <= 0.2 * truth, (r.joint, r.variation, truth)


def test_every_table_4_8_row_within_table_4_9_uncertainty(fitted):
    """Each sweep of Table 4.8 solved for its leading coefficient (the others from the
    fit), as the thesis's 'Result' column, within Table 4.9's bound of the truth."""
    from calib.gravity import row_result

    g = fitted["outcomes"]["gravity"].results
    truth = dict(zip(g.names, fitted["truth"].gravity))
    tol = {"c12": 0.15, "c13": 0.04, "c15": 0.005}
    assert len(g.rows) == 12
    for r in g.rows:
        name, val = row_result(r, g)
        assert abs(val - truth[name]) <= tol[name], (r.position, r.joint, r.direction, name, val)


def test_static_friction_coefficients_within_tolerance_of_table_4_5(fitted):
    """Breakaway ramps (calib record breakaway) against the data file's Table 4.5, which
    simula uses as its breakaway threshold. The thesis states no uncertainty for these
    hand-tuned values; calib.breakaway.TOLERANCE is this project's (5 %, joint 4 10 %)."""
    from calib.breakaway import TOLERANCE

    fr = fitted["info"].nominal["friction"]
    res = fitted["outcomes"]["breakaway"].results
    assert [r.joint for r in res] == [1, 2, 3, 4, 5, 6]
    for r in res:
        j, tol = r.joint - 1, TOLERANCE[r.joint]
        assert abs(r.plus - fr["static_pos"]["values"][j]) <= tol * fr["static_pos"]["values"][j], r
        assert abs(r.minus - fr["static_neg"]["values"][j]) <= tol * fr["static_neg"]["values"][j], r


def test_torque_sensitivities_within_table_4_1_error(fitted):
    err = fitted["info"].nominal["motors"]["torque_sensitivity"]["uncertainty"]
    truth = fitted["truth"].sigma
    res = fitted["outcomes"]["sensitivity"].results
    assert [r.joint for r in res] == [1, 2, 3, 4, 5, 6]
    for r in res:
        assert abs(r.mean - truth[r.joint - 1]) <= err[r.joint - 1], r


def test_static_friction_statistics_match_the_simulated_halts(fitted):
    fr = fitted["info"].nominal["friction"]
    res = fitted["outcomes"]["static"].results
    for r in res:
        j = r.joint - 1
        mean, std = fr["static_typical_mean"]["values"][j], fr["static_typical_std"]["values"][j]
        assert r.samples == 275
        assert abs(r.mean - mean) <= 4 * std / np.sqrt(r.samples), r
        assert abs(r.std - std) <= 0.2 * std, r


def test_fitted_parameter_file_holds_every_section(fitted):
    data = read_params(fitted["params"])
    for section in ("motors", "friction", "gravity_coeffs", "static_friction"):
        assert section in data
    assert np.all(np.isfinite(data["friction"]["coulomb_pos"]))


def test_simula_runs_on_the_fitted_parameters(fitted):
    """The file calib writes is one the runtime loads: simula --params starts on it."""
    from rci.simula.process import SimulaProcess

    with SimulaProcess("-p", "--params", fitted["params"], lockstep=True) as sim:
        assert sim.url
        reply = sim.command("status")
    assert reply
