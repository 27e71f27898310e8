"""Issue 14, items 1-4 and 7: calib never quietly assumes an input, never writes unfitted
values as measured, refuses or announces clipped ADC data and incomplete log sets, and
turns bad input into clear errors (synthetic recorder logs, no simulator)."""
from __future__ import annotations

import os

import numpy as np
import pytest

from rcci.calib.__main__ import main
from rcci.calib.params import read_params, update_params
from tests.test_calib_cli import _friction_log, sigma_params
from tests.test_calib_fits import FC_M, FC_P, FV_M, FV_P, rates
from tests.test_calib_synth import DEG, SIGMA, drive, friction_torque, sweep, to_trace, write_rcilog


def _sensitivity_logs(tmp_path, joints, sigma=SIGMA) -> list[str]:
    """Loaded and unloaded sensitivity logs of ``joints`` (1-based) with true ``sigma``."""
    from rcci.calib.sensitivity import GRAVITY

    rng = np.random.default_rng(4)
    d = drive(np.asarray(sigma, float))
    out = []
    for j in joints:
        t, q = sweep(np.zeros(6), j - 1, 0.0, 60 * DEG, [0.3] * 3)
        fric = friction_torque(rates(t, q), FC_P, FC_M, FV_P, FV_M)
        for mass, tag in ((2.0, "loaded"), (0.0, "unloaded")):
            tau = fric.copy()
            tau[:, j - 1] += mass * GRAVITY * 0.05
            meta = {"experiment": "sensitivity", "joint": j, "window": [0.0, 60 * DEG],
                    "load": {"mass_kg": mass, "radius_m": 0.05, "sign": 1}}
            tr = to_trace(t, q, tau, meta, d, rng)
            out.append(write_rcilog(str(tmp_path / f"sensitivity-j{j}-{tag}.rcilog"), tr))
    return out


# -- item 1: no silent fallbacks ---------------------------------------------------------

def test_friction_without_fitted_sensitivities_is_refused_with_the_command_that_fits_them(tmp_path, capsys):
    log = _friction_log(tmp_path, 3)
    params = str(tmp_path / "fitted.toml")
    assert main(["fit", "friction", log, "-p", params, "-q"]) == 2
    err = capsys.readouterr().err
    assert "torque sensitivities of motor(s) 3" in err
    assert "calib fit sensitivity" in err and "--assume-datafile" in err
    assert not os.path.exists(params)          # nothing written


@pytest.mark.parametrize("kind", ["static", "breakaway"])
def test_fits_that_subtract_gravity_refuse_without_fitted_coefficients(tmp_path, capsys, kind):
    from rcci.calib.fitting import run_fit
    from rcci.calib.exceptions import CalibError
    from rcci.calib.robot import robot_info
    from tests.test_calib_synth import to_trace as tt

    params = read_params(sigma_params(tmp_path))
    tr = tt(np.arange(10) / 36.0, np.zeros((10, 6)), np.zeros((10, 6)), {"experiment": kind, "joint": 1},
            drive(), np.random.default_rng(0))
    with pytest.raises(CalibError, match=r"gravity loading coefficients c12, c13, c15[\s\S]*calib fit gravity"):
        run_fit(kind, [tr], robot_info("puma260"), params, params_name="fitted.toml")


def test_assume_datafile_says_what_it_assumed_in_the_output_and_the_file(tmp_path, capsys):
    log = _friction_log(tmp_path, 3)
    params = str(tmp_path / "fitted.toml")
    assert main(["fit", "friction", log, "-p", params, "-q", "--assume-datafile"]) == 0
    out = capsys.readouterr().out
    assert "ASSUMED, not fitted (--assume-datafile):" in out
    assert "torque sensitivity of motor(s) 3 = 0.0786 N m/A, Table 4.1" in out
    data = read_params(params)
    assert data["calib"]["assumed"] == ["friction: torque sensitivity of motor(s) 3 = 0.0786 N m/A, "
                                        "Table 4.1 from models/puma260.toml"]
    assert "NOT ALL MEASURED" in open(params, encoding="utf-8").read()
    # a refit on fitted sensitivities clears the note
    update_params(params, "puma260", {"motors": {"torque_sensitivity": [float(x) for x in SIGMA]}}, "test")
    assert main(["fit", "friction", log, "-p", params, "-q"]) == 0
    assert "assumed" not in read_params(params)["calib"]


# -- item 2: sensitivities of some joints only --------------------------------------------

def test_sensitivity_of_some_joints_leaves_the_others_unfitted_nan(tmp_path, capsys):
    params = str(tmp_path / "fitted.toml")
    assert main(["fit", "sensitivity", *_sensitivity_logs(tmp_path, [2, 3]), "-p", params, "-q"]) == 0
    motors = read_params(params)["motors"]
    sigma = np.array(motors["torque_sensitivity"])
    assert np.isnan(sigma[[0, 3, 4, 5]]).all()
    assert sigma[1] == pytest.approx(SIGMA[1], rel=0.01) and sigma[2] == pytest.approx(SIGMA[2], rel=0.01)
    assert motors["torque_sensitivity_trials"] == [0, 3, 3, 0, 0, 0]
    # a later fit that needs motor 1 is refused (not fed Table 4.1); joint 3's is fine
    assert main(["fit", "friction", _friction_log(tmp_path, 1), "-p", params, "-q"]) == 2
    assert "motor(s) 1 " in capsys.readouterr().err
    assert main(["fit", "friction", _friction_log(tmp_path, 3), "-p", params, "-q"]) == 0


def test_simula_keeps_its_own_value_where_the_file_says_nan(tmp_path):
    from rcci.models import load_robot
    from rci.simula.params import load_params, truth_from_model

    params = str(tmp_path / "fitted.toml")
    assert main(["fit", "sensitivity", *_sensitivity_logs(tmp_path, [2]), "-p", params, "-q"]) == 0
    base = truth_from_model(load_robot("puma260"))
    t = load_params(params, "puma260", base)
    assert t.sigma[0] == base.sigma[0] and t.sigma[1] == pytest.approx(SIGMA[1], rel=0.01)


# -- item 4: clipped ADC data -------------------------------------------------------------

def _clipped_friction_log(tmp_path, joint: int, rail_fraction: float) -> str:
    """A friction log whose ADC channel of ``joint`` sits at the rail on the first
    ``rail_fraction`` of the passes (the current saturated the sense amplifier)."""
    from rcci.calib.trace import Trace

    rng = np.random.default_rng(joint)
    t, q = sweep(np.zeros(6), joint - 1, -0.5, 0.5, [0.1, 0.4, 0.8, 1.2] * 2)
    tau = friction_torque(rates(t, q), FC_P, FC_M, FV_P, FV_M)
    tr = to_trace(t, q, tau, {"experiment": "friction", "joint": joint, "window": [-0.5, 0.5]}, drive(), rng)
    adc = tr.adc.copy()
    cut = int(rail_fraction * len(t))
    adc[:cut, joint - 1] = np.sign(adc[:cut, joint - 1] + 1e-9) * 2047
    clipped = Trace(tr.path, tr.robot, tr.rate_hz, tr.meta, tr.t, tr.counts, adc)
    return write_rcilog(str(tmp_path / f"friction-j{joint}-clipped{rail_fraction}.rcilog"), clipped)


def test_friction_at_the_rail_throughout_is_refused(tmp_path, capsys):
    log = _clipped_friction_log(tmp_path, 2, 1.0)
    assert main(["fit", "friction", log, "-p", sigma_params(tmp_path), "-q"]) == 2
    err = capsys.readouterr().err
    assert log in err and "ADC's rails" in err


def test_friction_half_at_the_rail_leaves_those_passes_out_and_says_so(tmp_path, capsys):
    log = _clipped_friction_log(tmp_path, 2, 0.5)
    params = sigma_params(tmp_path)
    assert main(["fit", "friction", log, "-p", params, "-q"]) == 0
    out = capsys.readouterr().out
    assert "warning:" in out and "passes left out: ADC channel(s) 2 read at the rail" in out
    fc = read_params(params)["friction"]["coulomb_pos"][1]
    assert fc == pytest.approx(FC_P[1], rel=0.03)       # not 40 % low


# -- item 7: incomplete sets and clear errors ---------------------------------------------

def test_a_friction_log_without_its_servo_rate_log_is_named(tmp_path, capsys):
    log = _friction_log(tmp_path, 2, meta_extra={"log_name": "friction-j2",
                                                 "log_set": ["friction-j2", "friction-j2-servo"]})
    assert main(["fit", "friction", log, "-p", sigma_params(tmp_path), "-q"]) == 0
    out = capsys.readouterr().out
    assert "recorded together with log 'friction-j2-servo', which is not among the inputs" in out
    assert "viscous coefficient" in out


def test_a_non_numeric_rate_in_the_header_is_a_clear_error(tmp_path, capsys):
    from rci.how import How
    from rci.recorder import Recorder

    path = str(tmp_path / "bad-rate.rcilog")
    with Recorder(path, robot="puma260", rate_hz="fast", meta={"experiment": "static"}) as rec:
        for k in range(3):
            rec.append(How(cycle=k, rate_hz=36), None)
    assert main(["fit", "static", path, "-q", "--assume-datafile"]) == 2
    err = capsys.readouterr().err
    assert path in err and "'rate_hz' = 'fast' is not a sample rate" in err


def test_plots_into_a_folder_that_cannot_be_made_fail_before_the_fit(tmp_path, capsys):
    blocker = tmp_path / "afile"
    blocker.write_text("x")
    params = sigma_params(tmp_path)
    before = open(params, "rb").read()
    rc = main(["fit", "friction", _friction_log(tmp_path, 1), "-p", params, "-q",
               "--plots", str(blocker / "plots")])
    assert rc == 2
    err = capsys.readouterr().err
    assert "--plots" in err and "cannot create the folder" in err
    assert open(params, "rb").read() == before


def test_fit_kinematics_given_other_logs_or_binary_files_says_what_it_takes(tmp_path, capsys):
    log = _friction_log(tmp_path, 1)
    assert main(["fit", "kinematics", log, "-q"]) == 2
    assert "is a 'friction' log, not a 'kinematics' one" in capsys.readouterr().err
    binary = tmp_path / "poses.csv"
    binary.write_bytes(b"\xfd7zXZ\x00\x00\x04\xe6\xd6\xb4F")
    assert main(["fit", "kinematics", str(binary)]) == 2
    assert "not a text CSV of measured poses" in capsys.readouterr().err


def test_a_non_utf8_parameter_file_is_a_clear_error(tmp_path, capsys):
    bad = tmp_path / "fitted.toml"
    bad.write_bytes(b"[calib]\nschema = \"\xff\xfe\"\n")
    assert main(["fit", "friction", _friction_log(tmp_path, 1), "-p", str(bad), "-q"]) == 2
    err = capsys.readouterr().err
    assert str(bad) in err and "not a text (UTF-8)" in err


def test_friction_plot_panels_span_the_data_and_the_fit(tmp_path):
    """Each direction has its panel, and its y-axis spans the points and the fitted line
    (not 0 to the top, where a 1.6 N m friction's few per cent of viscous rise is flat)."""
    import matplotlib.image as mpimg

    from rcci.calib.friction import fit_friction
    from rcci.calib.logs import load_trace
    from rcci.calib.plots import friction_plots, y_limits

    tr = load_trace(_friction_log(tmp_path, 2))
    res, points = fit_friction([tr], drive())
    (path,) = friction_plots(res, points, str(tmp_path / "plots"))
    assert mpimg.imread(path).shape[1] > 700          # two panels side by side
    pts = [p for p in points if p.direction > 0]
    lo, hi = y_limits(np.array([p.friction for p in pts]), res[0].plus, max(p.speed for p in pts))
    assert lo > 0.5 * FC_P[1] and hi < 1.5 * FC_P[1]
    assert lo <= min(p.friction for p in pts) and hi >= max(p.friction for p in pts)
