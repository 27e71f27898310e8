"""Issue 30: recording a calibration on a truth that is not the data file's, as a user runs it.

The truth is rcci.calib.hidden_truth seed 1 (torque sensitivities 18-29 % off Table 4.1, joint 5's
18 % low; friction 10-30 % off; gravity 3-10 % off; DH errors), recorded on lockstep simulas
seeded 4 and 3, not the shipped logs' 1985: the loaded sensitivity run of joint 5 that aborted
with R_MAXCUR on the straight approach from ready is carried on the route calib chooses, a
failed recording keeps its partial log, every `calib record --simula` option is honoured or
refused, and a campaign resumes without recording a finished log again.
"""
from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from rcci.calib import headroom
from rcci.calib.exceptions import CalibError
from rcci.calib.experiments import sensitivity_plans
from rcci.calib.hidden_truth import hidden_truth, write_hidden_truth
from rcci.calib.logs import load_trace
from rcci.calib.program import run_plan
from rcci.calib.regen import regen
from rcci.calib.registry import RecordOptions
from rcci.calib.robot import robot_info

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
INFO = robot_info("puma260")
NOMINAL_SIGMA = INFO.drive.sigma


@pytest.fixture(scope="module")
def truth(tmp_path_factory) -> str:
    path = str(tmp_path_factory.mktemp("truth") / "hidden.toml")
    write_hidden_truth(path, "puma260", 1)
    return path


def test_the_hidden_truth_is_10_to_30_percent_away_and_valid():
    t = hidden_truth("puma260", 1)
    factors = [s / n for s, n in zip(t["motors"]["torque_sensitivity"], NOMINAL_SIGMA)]
    assert all(0.69 <= abs(f) <= 0.91 or 1.09 <= f <= 1.31 for f in factors), factors
    assert factors[4] < 0.9                       # joint 5's motor weaker: the issue's case, harder
    assert hidden_truth("puma260", 1) == t        # a seed is one truth


def _calib(*args: str, cwd: str = ROOT) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "rcci.calib", *args], capture_output=True, text=True, cwd=cwd,
                          timeout=600)


def test_loaded_j5_is_carried_from_ready_on_a_weaker_motor(truth, tmp_path):
    """The straight approach trips R_MAXCUR on this truth; the plan calib makes goes another way,
    says so, and records (short arcs: the approach is what is tested)."""
    from rci.simula.process import SimulaProcess

    notes: list[str] = []
    plan = sensitivity_plans(None, 0.05, joints=[5], speeds_deg=(40,), trips=1, robot=INFO, notes=notes)[0]
    assert plan.meta["load"]["mass_kg"] > 0 and plan.via and "load_note" in plan.meta
    assert any("sensitivity-j5-loaded" in n and "approach" in n for n in notes)
    plan.warmup = None
    straight = sensitivity_plans(None, 0.05, joints=[5], speeds_deg=(40,), trips=1, robot=INFO)[0]
    straight.warmup, straight.via = None, ()
    with SimulaProcess("-p", "--params", truth, *plan.simula_args, lockstep=True, seed=3) as sim:
        with pytest.raises(CalibError, match="R_MAXCUR"):
            run_plan(sim.url, straight, str(tmp_path / "straight.rcilog"))
    with SimulaProcess("-p", "--params", truth, *plan.simula_args, lockstep=True, seed=3) as sim:
        run = run_plan(sim.url, plan, str(tmp_path / "routed.rcilog"))
    assert run.records > 100
    assert load_trace(run.path).meta["load"]["mass_kg"] == plan.meta["load"]["mass_kg"]


def test_a_failed_recording_keeps_the_log_its_error_names(truth, tmp_path, monkeypatch):
    """With the headroom check blinded (no margins, any current allowed) the campaign takes the
    straight approach and aborts; the partial log the error names is still there."""
    monkeypatch.setattr(headroom, "MARGINS", {"sigma": 0.0, "friction": 0.0, "gravity": 0.0})
    monkeypatch.setattr(headroom, "HEADROOM", 10.0)
    out = str(tmp_path / "logs")
    os.makedirs(out)
    # the unloaded run counts as recorded (resume), so the loaded one, which fails, comes first
    open(os.path.join(out, "sensitivity-j5-unloaded.rcilog.xz"), "wb").close()
    with pytest.raises(CalibError, match="R_MAXCUR") as exc:
        regen(out, 3, ("sensitivity",), truth, quiet=True, options=RecordOptions(joints=(5,)), resume=True)
    named = str(exc.value).split("partial log: ")[1].rstrip(")")
    assert os.path.exists(named) and named.startswith(os.path.join(out, ".work"))


@pytest.mark.parametrize("kind, option", [
    ("gravity", ["--joints", "2"]), ("static", ["--joints", "2"]), ("kinematics", ["--joints", "1"]),
    ("friction", ["--mass", "1"]), ("gravity", ["--radius", "0.1"]), ("friction", ["--halts", "5"]),
    ("static", ["--touches", "9"]), ("kinematics", ["--rate", "100"]), ("breakaway", ["--rate", "100"]),
    ("sensitivity", ["--loaded"]), ("friction", ["--joints", "7"]), ("all", ["--loaded"]),
])
def test_simula_refuses_an_option_it_cannot_honour(kind, option, tmp_path, capsys):
    from rcci.calib.__main__ import main

    assert main(["record", kind, "--simula", "--seed 4", *option, "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert option[0] in err and "does not apply" in err or "--loaded is for --url" in err or "has joints" in err
    assert not os.path.exists(tmp_path / "x")          # refused before anything is made


def test_simula_options_are_honoured_and_a_campaign_resumes(truth, tmp_path):
    out = str(tmp_path / "logs")
    first = _calib("record", "static", "--simula", f"--seed 4 --params {truth}", "--halts", "2",
                   "--rate", "50", "--out", out, "-q")
    assert first.returncode == 0, first.stderr
    path = os.path.join(out, "static.rcilog.xz")
    meta = load_trace(path).meta
    assert meta["halts"] == 2 and meta["rate_hz"] == 50 and meta["truth"]["seed"] == 4
    assert "recorded 1 log(s) in" in first.stdout and not os.path.exists(os.path.join(out, ".work"))
    stamp = os.stat(path).st_mtime_ns
    again = _calib("record", "static", "--simula", f"--seed 4 --params {truth}", "--halts", "2",
                   "--rate", "50", "--out", out, "-q")
    assert again.returncode == 0, again.stderr
    assert "already in" in again.stdout and "recorded 0 log(s)" in again.stdout
    assert os.stat(path).st_mtime_ns == stamp
    _fits_name_their_truth(out, path, str(tmp_path))


def test_record_all_names_what_an_arm_cannot_support(tmp_path):
    """The Microbo: its prismatic joints 2 and 3 are left out of friction and sensitivity by name;
    the Stanford arm's joint 2, whose every window gravity works on, is planned on a gravity-loaded
    arc (its work cancels in 4.43); the touches are planned on each arm's own fixture
    (rcci.calib.touch.FIXTURES: the PUMA 260's corner is out of their reach)."""
    from rcci.calib.regen import campaign_plans
    from rcci.calib.registry import RegenContext

    ctx = RegenContext(str(tmp_path), str(tmp_path), 4, None, robot_info("stanford"))
    plans, refused = campaign_plans(ctx, ("kinematics", "sensitivity", "gravity", "static"), skip_refused=True)
    assert refused == {} and not any(n.startswith("sensitivity: not recorded") for n in ctx.notes)
    names = {p.name for _, p in plans}
    assert {"sensitivity-j3-loaded", "sensitivity-j2-loaded"} <= names
    assert {p.meta["experiment"] for _, p in plans if hasattr(p, "meta")} >= {"gravity", "static", "sensitivity"}
    assert "kinematics" in names
    ctx = RegenContext(str(tmp_path), str(tmp_path), 4, None, robot_info("microbo"))
    plans, _ = campaign_plans(ctx, ("kinematics", "friction", "sensitivity"), skip_refused=True)
    for kind in ("friction", "sensitivity"):
        for j in (2, 3):
            assert any(n.startswith(f"{kind}: not recorded") and f"joint {j}" in n for n in ctx.notes)
    assert "kinematics" in {p.name for _, p in plans}


def _fits_name_their_truth(out: str, static_log: str, tmp: str) -> None:
    """The refusal points at logs of this truth (not calib/logs/, another truth); a parameter
    file says what each fit's logs were recorded against; a fit that takes an input fitted on
    another truth's logs says so."""
    refused = _calib("fit", "static", static_log)
    assert refused.returncode == 2
    assert os.path.join(out, "sensitivity-*.rcilog*") in refused.stderr and "calib/logs/" not in refused.stderr
    params = os.path.join(tmp, "p.toml")
    shipped = [os.path.join(ROOT, "calib", "logs", f"sensitivity-j5-{t}.rcilog.xz") for t in ("loaded", "unloaded")]
    assert _calib("fit", "sensitivity", *shipped, "-p", params, "-q").returncode == 0
    text = open(params, encoding="utf-8").read()
    assert "truth_sensitivity = \"simula puma260 seed 1985 on" in text
    assert 'logs_sensitivity = ["sensitivity-j5-loaded.rcilog.xz", "sensitivity-j5-unloaded.rcilog.xz"]' in text
    mixed = _calib("fit", "static", static_log, "-p", params, "--assume-datafile", "-q")
    assert mixed.returncode == 0, mixed.stderr
    assert "mixes two truths" in mixed.stdout and "seed 1985" in mixed.stdout and "seed 4" in mixed.stdout
    assert "truth_static = \"simula puma260 seed 4 on" in open(params, encoding="utf-8").read()


def test_a_parameter_file_in_a_missing_folder_is_refused_before_the_fit(tmp_path):
    log = os.path.join(ROOT, "calib", "logs", "sensitivity-j5-loaded.rcilog.xz")
    out = _calib("fit", "sensitivity", log, "-p", str(tmp_path / "no" / "p.toml"))
    assert out.returncode == 2 and "does not exist" in out.stderr and "nothing was fitted" in out.stderr
    assert "Table 4.1" not in out.stdout


def _j5_logs():
    return [load_trace(os.path.join(ROOT, "calib", "logs", f"sensitivity-j5-{t}.rcilog.xz"))
            for t in ("loaded", "unloaded")]


def test_sensitivity_at_the_adc_rail_is_named():
    """Every pass of joint 5 at the rail: refused, naming the rail; all but one round trip: one
    trial, and a note that its spread is unknown."""
    from rcci.calib.logs import ADC_RAIL
    from rcci.calib.sensitivity import fit_sensitivity
    from rcci.calib.work import find_passes

    loaded, unloaded = _j5_logs()
    full = loaded.adc.copy()
    loaded.adc[:, 4] = ADC_RAIL
    with pytest.raises(Exception, match=r"ADC channel off its rails \(\+-2047\)"):
        fit_sensitivity([loaded, unloaded], INFO.drive)
    loaded.adc[:] = full
    theta = INFO.drive.current_angles(loaded.t, loaded.counts)[:, 4]
    passes = find_passes(theta, *loaded.meta["window"])
    for p in passes[2:]:                       # the first round trip kept, every later one clipped
        loaded.adc[p.first, 4] = ADC_RAIL
    notes: list[str] = []
    (res,) = fit_sensitivity([loaded, unloaded], INFO.drive, notes)
    assert res.trials == 1
    assert any("1 trial" in n and "unknown" in n for n in notes)
    assert any("at the rail" in n for n in notes)


def test_other_arms_get_friction_and_sensitivity_plans_where_gravity_allows():
    """Stanford's prismatic joint 3: a window inside its range, the axis horizontal (no work by
    gravity), speeds in m/s, the pulley pulling the slide with m g; PUMA 560 joint 1: a window of
    its own inside +-160 deg; joints whose centres of mass lie off the links get gravity-loaded windows
    (the friction fit takes g_w off; in the sensitivity arcs it cancels)."""
    from rcci.calib.experiments import check_friction_pose, friction_plans

    stanford = robot_info("stanford")
    fr = friction_plans([3], robot=stanford)[0]
    lo, hi = fr.meta["window"]
    assert stanford.lower[2] < lo < hi < stanford.upper[2] and hi - lo > 0.5
    check_friction_pose(stanford, 3, lo, hi, np.array(fr.meta["pose"]))
    assert max(fr.meta["speeds"]) < 1.0                         # m/s
    loaded, unloaded = sensitivity_plans(None, 0.05, joints=[3], robot=stanford)
    assert loaded.meta["load"]["radius_m"] == 1.0 and loaded.meta["load"]["mass_kg"] > 0
    assert "radius=1.0" in loaded.simula_args[0]
    puma560 = robot_info("puma560")
    j1 = friction_plans([1], robot=puma560)[0]
    assert puma560.lower[0] < j1.meta["window"][0] and j1.meta["window"][1] < puma560.upper[0]
    for robot, j in ((puma560, 2), (puma560, 3), (stanford, 2)):
        # no window frees these joints of gravity's work: one with little of it, taken off by the fit
        fr = friction_plans([j], robot=robot)[0]
        lo, hi = fr.meta["window"]
        assert fr.meta["gravity_loaded"] and robot.lower[j - 1] < lo < hi < robot.upper[j - 1]
        arcs = sensitivity_plans(None, 0.05, joints=[j], robot=robot)       # gravity cancels in 4.43
        assert [p.meta["pose"] for p in arcs] == [fr.meta["pose"]] * 2
