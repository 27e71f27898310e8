"""`calib fit gravity` on an arm other than the thesis's: the PUMA 560 and its ten minimal
coefficients (models/puma560.toml, derive.gravity.minimal_gravity).

Table 4.7's sweeps were chosen for the PUMA 260's three coefficients; for the PUMA 560 calib
chooses its own (rcci.calib.poses.identifying_sweeps): the fewest 180-degree sweeps whose
regressor rows identify all ten. They are recorded here by calib's own measurement program
(rcci.calib.program.run_plan, as `calib record gravity --robot puma560` runs it) on a real
lockstep `simula --robot puma560` whose truth is not the data file's (a parameter file moves
five coefficients, cz4/cx5/cx6 stay 0), then fitted by the `calib fit gravity` command; every
coefficient must lie within the uncertainty it prints of the simulated arm's truth (the
Pinocchio gravity of simula's URDF, fitted to the regressor by rcci.calib.truth).
"""
from __future__ import annotations

import glob
import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from rcci.calib.exceptions import CalibError
from rcci.calib.robot import robot_info

ROBOT = "puma560"
TRUTH = {"cy2": 1.5, "cz3": 9.2, "cx4": 0.05, "cz5": 0.06, "cy6": -0.02}
SPEED_DEG = 60.0     # deg/s: three times the thesis's 20, to keep the run short


def test_table_4_7_does_not_serve_the_puma560_and_ten_sweeps_do():
    from rcci.calib.fits.gravity import plans
    from rcci.calib.poses import TABLE_4_8_SWEEPS, main_sweep, table_4_7_identifies, unidentified

    info = robot_info(ROBOT)
    assert not table_4_7_identifies(info.regressor, info.lower, info.upper, info.kinds)
    rows = []                            # what the thesis's positions would measure, were they reachable
    for name, joint in TABLE_4_8_SWEEPS:
        q = main_sweep(name, joint).q_start
        rows.append(info.regressor(q)[joint - 1])
    assert np.linalg.matrix_rank(np.array(rows)) == 5          # five combinations of the ten
    assert "cz5" not in unidentified(np.array(rows), info.gravity_names)
    ps = plans(info, SPEED_DEG, extra=0)
    assert len(ps) == len(info.gravity_names) == 10
    A = []
    for p in ps:
        q = np.array(p.meta["q_start"])
        q[p.meta["joint"] - 1] = p.meta["phi_low"]
        A.append(info.regressor(q)[p.meta["joint"] - 1])
        for path in (p.path, p.warmup):      # sweeps, turns and warm-ups inside the joint ranges
            s = path.sample(36)
            assert np.all(s >= info.lower) and np.all(s <= info.upper), p.name
    assert unidentified(np.array(A), info.gravity_names) == []
    # what `calib record gravity` records: eight to spare, the fit's degrees of freedom
    # (a sweep is one observation: rcci.calib.gravity.sweep_observations)
    assert len(plans(info)) == 18


def test_coefficients_no_sweep_can_measure_are_named():
    """The Microbo's c12 is the weight its vertical lift carries: no revolute sweep sees it."""
    from rcci.calib.fits.gravity import plans

    with pytest.raises(CalibError, match=r"gravity coefficients c12 cannot be identified"):
        plans(robot_info("microbo"))


def test_calib_fit_gravity_on_the_puma560(tmp_path, capsys):
    from rcci.calib.__main__ import main
    from rcci.calib.fits.gravity import plans
    from rcci.calib.logs import load_trace
    from rcci.calib.program import run_plan
    from rcci.calib.truth import truth_meta, truth_of
    from rci.simula.process import SimulaProcess

    truth_file = tmp_path / "truth.toml"
    truth_file.write_text(f'[calib]\nschema = "rcci-calib-params/1"\nrobot = "{ROBOT}"\n\n[gravity_coeffs]\n'
                          + "".join(f"{n} = {v}\n" for n, v in TRUTH.items()))
    info = robot_info(ROBOT)
    args = ["--warm", "--params", str(truth_file)]

    def record(lane) -> None:
        with SimulaProcess("-p", *args, robot=ROBOT, lockstep=True, seed=5) as sim:
            for plan in lane:
                plan.warmup = None           # a warm simula (--warm): no warm-up needed
                run_plan(sim.url, plan, str(tmp_path / f"{plan.name}.rcilog"), ROBOT, rate_hz=36,
                         extra_meta={"truth": truth_meta(5, str(truth_file), args)})

    # twelve sweeps (two beyond the fewest: the error needs residual degrees of freedom) on two
    # simulas side by side (each lockstep pair keeps about one CPU busy)
    sweeps = plans(info, SPEED_DEG, extra=2)
    with ThreadPoolExecutor(max_workers=2) as pool:
        for done in [pool.submit(record, sweeps[k::2]) for k in range(2)]:
            done.result()
    logs = sorted(glob.glob(str(tmp_path / "*.rcilog")))
    params = str(tmp_path / "fitted.toml")
    assert main(["fit", "gravity", *logs, "--assume-datafile", "-q", "-p", params]) == 0
    printed = capsys.readouterr().out
    assert f"12 log(s) of robot {ROBOT}" in printed
    from rcci.calib.params import read_params

    fitted = read_params(params)
    assert fitted["calib"]["robot"] == ROBOT
    truth = truth_of([load_trace(p) for p in logs], info)
    assert truth.gravity_fit_residual < 1e-9
    for k, name in enumerate(info.gravity_names):
        want = TRUTH.get(name, info.nominal["gravity_coeffs"][name]["value"])
        assert truth.gravity[k] == pytest.approx(want, abs=1e-9)
        value, error = fitted["gravity_coeffs"][name], fitted["gravity_coeffs"][f"{name}_error"]
        assert f"{name:>11}  {value:7.3f} +- {error:5.3f}" in printed
        assert abs(value - truth.gravity[k]) <= error, (name, value, error, truth.gravity[k])
    # a fit of another arm's logs with --robot naming the PUMA 260 is refused, not reinterpreted
    assert main(["fit", "gravity", *logs, "--robot", "puma260", "--assume-datafile", "-q"]) == 2
    assert "the logs are of robot 'puma560'" in capsys.readouterr().err


def test_the_dh_errors_do_not_move_what_the_sweeps_measure():
    """The truth's coefficients are fitted to its gravity over the whole workspace, DH errors
    included (rcci.calib.truth.simulator_truth); the sweeps see that gravity at their start poses
    only. On hidden truths 1-3 the coefficients that fit the sweeps' noise-free start torques are
    the truth's within 1 mN m: what the intervals must cover is the measurement's error, not a
    model mismatch (docs/calib.md, "Gravity intervals")."""
    import pinocchio as pin

    from rcci.calib.fits.gravity import plans
    from rcci.calib.hidden_truth import hidden_truth
    from rcci.calib.truth import simulator_truth
    from rcci.models import load_robot
    from rci.simula.arm import SimulatedArm
    from rci.simula.params import apply_params, truth_from_model

    info = robot_info(ROBOT)
    for seed in (1, 2, 3):
        data = hidden_truth(ROBOT, seed)
        assert np.abs(data["kinematics"]["dtheta"]).max() > 1e-3        # joint offsets of 0.05-0.25 deg
        truth = simulator_truth(info, data)
        arm = SimulatedArm(load_robot(ROBOT), apply_params(data, "test", ROBOT, truth_from_model(load_robot(ROBOT))),
                           seed=0, start="ready")
        pd = arm.pm.createData()
        A, y = [], []
        for p in plans(info):
            j = p.meta["joint"] - 1
            q = np.array(p.meta["q_start"], float)
            q[j] = p.meta["phi_low"]
            A.append(info.regressor(q)[j])
            y.append(pin.computeGeneralizedGravity(arm.pm, pd, q)[j])
        c, *_ = np.linalg.lstsq(np.array(A), np.array(y), rcond=None)
        assert np.abs(c - truth.gravity).max() < 1e-3, (seed, c - truth.gravity)


def test_the_coverage_report_counts_and_lists_each_sweeps_errors():
    """`calib coverage --report`: the count inside, each coefficient's |fit - truth| / error, and
    each sweep's two errors (rows of a fit against the truth's coefficients)."""
    from rcci.calib.coverage import SWEEP_ERRORS, report_text, sweep_errors
    from rcci.calib.gravity import GravityRow

    truth = np.array([2.0, 0.5])
    r = np.array([1.0, 0.0])
    rows = [GravityRow("g01", 2, 1, 2.03, 2.03, r, r, 1), GravityRow("g01", 2, -1, -2.03, -2.03, -r, -r, 1)]
    assert sweep_errors(rows, truth) == [("g01", 2, pytest.approx(0.03), pytest.approx(-0.03))]
    SWEEP_ERRORS[("puma560", 9)] = sweep_errors(rows, truth)
    text = report_text("puma560", 20.0, True, {9: [("c1", 2.03, 0.05, 2.0), ("c2", 0.6, 0.05, 0.5)]},
                       "calib coverage --robot puma560 --seeds 9", 60.0)
    assert "**1 of 2 coefficients (50 %) inside" in text
    assert "| 9 | 1/2 | 0.60 | 2.00 |" in text and "| 9 | g01 | 2 | +0.0300 | -0.0300 |" in text
