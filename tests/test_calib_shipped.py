"""Fits of the logs shipped in calib/logs/ (recorded on simula by `calib regen-logs --params
calib/logs/simula-truth.toml`, a non-thesis truth) against the ground truth the logs say they
were recorded against, with the thesis's stated uncertainties and with calib's own."""
from __future__ import annotations

import glob
import os

import numpy as np
import pytest

from rcci.calib.cli_extra import fit_all
from rcci.calib.logs import LOG_DIR
from rcci.calib.params import read_params
from rcci.calib.truth import truth_of

LOGS = sorted(glob.glob(os.path.join(LOG_DIR, "*.rcilog.*")))


def test_the_logs_are_shipped():
    """A clone carries calib/logs/ (make demo calibrates from them); without them every test
    below would check nothing, so their absence is a failure, not a skip."""
    assert LOGS, f"no shipped logs under {LOG_DIR}: run `calib regen-logs`"


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    params = str(tmp_path_factory.mktemp("calib") / "fitted.toml")
    res = fit_all(LOGS, params)
    res["params"] = params
    res["truth"] = truth_of(res["traces"], res["info"])
    return res


def test_shipped_logs_carry_their_non_thesis_truth(fitted):
    truth = fitted["truth"]
    assert truth.source == "simula on calib/logs/simula-truth.toml" and truth.seeds == (1985,)
    table_4_1 = np.asarray(fitted["info"].nominal["motors"]["torque_sensitivity"]["values"])
    assert np.all(np.abs(truth.sigma / table_4_1 - 1) > 0.04)


def test_every_value_within_its_printed_uncertainty(fitted):
    """Issue 14's acceptance on the full-length logs: friction (99.73 %), gravity (Table 4.9's
    combination), torque sensitivities (independent error), kinematic errors (99.73 %)."""
    truth, out = fitted["truth"], fitted["outcomes"]
    for r in out["sensitivity"].results:
        assert abs(r.mean - truth.sigma[r.joint - 1]) <= r.independent_error, r
    for r in out["friction"].results:
        j = r.joint - 1
        for fit, fc, fv in ((r.plus, truth.coulomb_pos[j], truth.viscous_pos[j]),
                            (r.minus, truth.coulomb_neg[j], truth.viscous_neg[j])):
            assert abs(fit.coulomb - fc) <= fit.coulomb_err, (r.joint, fit, fc)
            assert abs(fit.viscous - fv) <= fit.viscous_err, (r.joint, fit, fv)
    g = out["gravity"].results
    assert np.all(np.abs(g.value - truth.gravity) <= g.error), (g.value, g.error, truth.gravity)
    k = out["kinematics"].results
    E = truth.dh_errors.ravel()
    assert k.rank == 22
    assert np.all(np.abs(k.e - E)[k.identifiable] <= k.factor * k.std[k.identifiable])
    for name, value, sd, unit, coef in k.combinations():
        assert abs(value - coef @ E) <= k.factor * sd, name


def test_shipped_logs_are_small_and_cover_every_experiment():
    total = sum(os.path.getsize(p) for p in LOGS)
    assert total < 10e6, f"shipped logs are {total / 1e6:.1f} MB"
    kinds = {os.path.basename(p).split("-")[0].split(".")[0] for p in LOGS}
    assert kinds == {"friction", "gravity", "sensitivity", "static", "breakaway", "kinematics"}


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


def test_coulomb_errors_are_not_the_fit_alone(fitted):
    """Issue 14, item 5: the printed Coulomb error carries the position pattern's window mean
    (it was 8-17 times too small on joints 2, 3 and 5 with the fit's scatter alone)."""
    for r in fitted["outcomes"]["friction"].results:
        for fit in (r.plus, r.minus):
            assert fit.coulomb_pattern_sd > 0
            assert fit.coulomb_err >= 3 * fit.coulomb_pattern_sd


def test_friction_logs_read_fast_passes_of_joints_2_to_6_at_every_servo_tick(fitted):
    rates = {(t.meta["joint"], os.path.basename(t.path)): t.rate_hz
             for t in fitted["traces"] if t.experiment == "friction"}
    for j in (2, 3, 4, 5, 6):
        assert rates[(j, f"friction-j{j}-servo.rcilog.xz")] == 1000
        assert rates[(j, f"friction-j{j}.rcilog.xz")] == 72


def test_variation_within_a_fifth_of_the_pattern_in_the_window(fitted):
    """Table 4.4 gives approximate values, no bounds: the fit is held to 20 % of the same
    statistic of simula's pattern over the window (rcci.calib.truth.simula_variation)."""
    from rcci.calib.truth import simula_variation

    import tomllib

    from rcci.calib.truth import log_truth

    windows = {t.meta["joint"]: (log_truth(t), tuple(t.meta["window"]))
               for t in fitted["traces"] if t.experiment == "friction"}
    for r in fitted["outcomes"]["friction"].results:
        t, window = windows[r.joint]
        _, truth = simula_variation(fitted["info"].name, int(t["seed"]), r.joint, window,
                                    tomllib.loads(t["params_toml"]))
        assert abs(r.variation - truth) <= 0.2 * truth, (r.joint, r.variation, truth)


def test_every_table_4_8_row_within_table_4_9_uncertainty(fitted):
    """Each sweep of Table 4.8 solved for its leading coefficient (the others from the
    fit), as the thesis's 'Result' column, within Table 4.9's bound of the truth."""
    from rcci.calib.gravity import row_result

    g = fitted["outcomes"]["gravity"].results
    truth = dict(zip(g.names, fitted["truth"].gravity))
    tol = {"c12": 0.15, "c13": 0.04, "c15": 0.005}
    assert len(g.rows) == 12
    for r in g.rows:
        name, val = row_result(r, g)
        assert abs(val - truth[name]) <= tol[name], (r.position, r.joint, r.direction, name, val)


def test_static_friction_coefficients_within_tolerance_of_table_4_5(fitted):
    """Breakaway ramps (calib record breakaway) against simula's breakaway threshold (the
    truth's Table 4.5). The thesis states no uncertainty for these hand-tuned values;
    rcci.calib.breakaway.TOLERANCE is this project's (5 %, joint 4 10 %)."""
    from rcci.calib.breakaway import TOLERANCE

    truth = fitted["truth"]
    res = fitted["outcomes"]["breakaway"].results
    assert [r.joint for r in res] == [1, 2, 3, 4, 5, 6]
    for r in res:
        j, tol = r.joint - 1, TOLERANCE[r.joint]
        assert abs(r.plus - truth.static_pos[j]) <= tol * truth.static_pos[j], r
        assert abs(r.minus - truth.static_neg[j]) <= tol * truth.static_neg[j], r


def test_torque_sensitivities_within_table_4_1_error(fitted):
    err = fitted["info"].nominal["motors"]["torque_sensitivity"]["uncertainty"]
    truth = fitted["truth"].sigma
    res = fitted["outcomes"]["sensitivity"].results
    assert [r.joint for r in res] == [1, 2, 3, 4, 5, 6]
    for r in res:
        assert abs(r.mean - truth[r.joint - 1]) <= err[r.joint - 1], r


def test_static_friction_statistics_match_the_simulated_halts(fitted):
    truth = fitted["truth"]
    res = fitted["outcomes"]["static"].results
    for r in res:
        j = r.joint - 1
        mean, std = truth.hold_mean[j], truth.hold_std[j]
        assert r.samples == 275
        assert abs(r.mean - mean) <= 4 * std / np.sqrt(r.samples), r
        assert abs(r.std - std) <= 0.2 * std, r


def test_fitted_parameter_file_holds_every_section(fitted):
    data = read_params(fitted["params"])
    for section in ("motors", "friction", "gravity_coeffs", "static_friction", "kinematics"):
        assert section in data
    assert "assumed" not in data["calib"]
    assert np.all(np.isfinite(data["friction"]["coulomb_pos"]))


def test_simula_runs_on_the_fitted_parameters(fitted):
    """The file calib writes is one the runtime loads: simula --params starts on it."""
    from rci.simula.process import SimulaProcess

    with SimulaProcess("-p", "--params", fitted["params"], lockstep=True) as sim:
        assert sim.url
        reply = sim.command("status")
    assert reply
