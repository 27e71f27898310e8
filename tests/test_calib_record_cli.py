"""Issue 30, item 2 and the campaign: every `calib record --simula` option reaches the plans or
is refused, `calib record all` interrupted after its first log records only what is missing
when run again (and shows a line per log on stderr, not a terminal), and `calib report`
prints its coverage table (progress itself: tests/test_calib_progress.py).

The recordings run on lockstep simulas of a hidden truth (rcci.calib.hidden_truth seed 1:
sensitivities and friction 10-30 % off the data file) with simula seed 4, not the shipped 1985.
"""
from __future__ import annotations

import io
import os
import signal
import subprocess
import sys
import time

import pytest

from rcci.calib.hidden_truth import write_hidden_truth
from rcci.calib.logs import load_trace
from rcci.calib.regen import campaign_plans
from rcci.calib.registry import OwnSimula, RecordOptions, RegenContext
from rcci.calib.robot import robot_info

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


@pytest.fixture(scope="module")
def truth(tmp_path_factory) -> str:
    path = str(tmp_path_factory.mktemp("truth") / "hidden.toml")
    write_hidden_truth(path, "puma260", 1)
    return path


def test_every_honoured_option_reaches_the_plans(tmp_path, truth):
    """--joints, --mass, --radius, --rate, --halts as the campaign plans them (--touches: in the
    recorded log of the campaign test below; refusals: tests/test_calib_campaign.py)."""
    opts = RecordOptions(joints=(6,), mass=0.5, radius=0.04, rate=6, halts=3, touches=3)
    ctx = RegenContext(str(tmp_path), str(tmp_path), 4, truth, robot_info("puma260"), opts)
    plans, refused = campaign_plans(ctx, ("breakaway", "friction", "gravity", "static", "sensitivity"))
    assert refused == {}
    by_kind: dict[str, list] = {}
    for _, p in plans:
        kind = "breakaway" if isinstance(p, OwnSimula) else p.meta["experiment"]
        by_kind.setdefault(kind, []).append(p)
    assert [p.name for p in by_kind["friction"]] == ["friction-j6", "friction-j6-servo"]
    assert by_kind["breakaway"][0].log_names() == ("breakaway-j6",)
    loaded, unloaded = sorted(by_kind["sensitivity"], key=lambda p: -p.meta["load"]["mass_kg"])
    assert loaded.name == "sensitivity-j6-loaded" and unloaded.name == "sensitivity-j6-unloaded"
    assert loaded.meta["load"]["mass_kg"] == 0.5 and loaded.meta["load"]["radius_m"] == 0.04
    assert "mass=0.5" in loaded.simula_args[-1] and "radius=0.04" in loaded.simula_args[-1]
    assert by_kind["static"][0].meta["halts"] == 3
    assert len(by_kind["gravity"]) >= 4                  # --joints is not gravity's: every sweep
    for kind in ("friction", "gravity", "static", "sensitivity"):
        assert {p.rate_hz for p in by_kind[kind]} == {6}, kind


@pytest.mark.parametrize("words, why", [
    (["record", "static", "--simula", "--seed 4", "--against", "robot"], "--against does not apply"),
    (["record", "static", "--url", "socket://127.0.0.1:9", "--fresh"], "--fresh does not apply"),
    (["record", "static", "--simula", "--seed 4 --load pulley:joint=1"], "only --seed and --params"),
])
def test_options_of_the_other_path_are_refused(words, why, tmp_path, capsys):
    from rcci.calib.__main__ import main

    assert main([*words, "--out", str(tmp_path / "x")]) == 2
    assert why in capsys.readouterr().err
    assert not os.path.exists(tmp_path / "x")


def _calib(args: list[str], out: str, err: str) -> subprocess.Popen:
    """`calib ARGS` as a terminal starts it: with Ctrl-C's default disposition. A suite run in the
    background (a shell's `&`, nohup) ignores SIGINT, and a child inherits that: its Python then
    keeps ignoring Ctrl-C except while rci's handler is installed (inside a session), so the test's
    SIGINT between two programs did nothing and the campaign ran to its end."""
    return subprocess.Popen([sys.executable, "-m", "rcci.calib", *args], cwd=ROOT,
                            stdout=open(out, "w"), stderr=open(err, "w"), text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


def _wait_for(cond, proc: subprocess.Popen, what: str, timeout: float = 240.0) -> None:
    t0 = time.monotonic()
    while not cond():
        if proc.poll() is not None:
            raise AssertionError(f"calib exited ({proc.returncode}) before {what}")
        if time.monotonic() - t0 > timeout:
            proc.kill()
            raise AssertionError(f"no {what} after {timeout} s")
        time.sleep(0.2)


def test_record_all_resumes_after_an_interrupt(truth, tmp_path):
    """`calib record all --simula` interrupted (Ctrl-C) once its first log (the touches) is written:
    run again, it says the log is there, does not record it again and goes on with the next
    program (interrupted in turn: the rest of a campaign is minutes)."""
    logs = str(tmp_path / "logs")
    args = ["record", "all", "--simula", f"--seed 4 --params {truth}", "--out", logs,
            "--joints", "6", "--rate", "6", "--halts", "2", "--touches", "3"]
    first = os.path.join(logs, "kinematics.rcilog.xz")
    o1, e1 = str(tmp_path / "out1"), str(tmp_path / "err1")
    run = _calib(args, o1, e1)
    _wait_for(lambda: os.path.exists(first), run, "first log")
    run.send_signal(signal.SIGINT)
    assert run.wait(90) == 130
    stamp = os.stat(first).st_mtime_ns
    err = open(e1).read()
    assert "recording [1/" in err and "] kinematics" in err and "calib: interrupted" in err
    assert load_trace(first).meta["touches"] == 3 and load_trace(first).meta["truth"]["seed"] == 4

    o2, e2 = str(tmp_path / "out2"), str(tmp_path / "err2")
    again = _calib(args, o2, e2)
    _wait_for(lambda: "] breakaway" in open(e2).read(), again, "the second program")
    again.send_signal(signal.SIGINT)
    assert again.wait(90) == 130
    out, err = open(o2).read(), open(e2).read()
    assert "1 log(s) already in" in out and "not recorded again: kinematics" in out
    assert "] kinematics" not in err and "recording [1/" in err
    assert os.stat(first).st_mtime_ns == stamp


def test_report_prints_its_coverage_table(tmp_path):
    """`calib report` prints, per table, how many values lie inside their intervals when the logs'
    truth is known (here the shipped joint-5 sensitivity logs: simula's truth in their metadata)."""
    import shutil

    logs = tmp_path / "logs"
    logs.mkdir()
    for t in ("loaded", "unloaded"):
        shutil.copy(os.path.join(ROOT, "calib", "logs", f"sensitivity-j5-{t}.rcilog.xz"), logs)
    run = subprocess.run([sys.executable, "-m", "rcci.calib", "report", "--logs", str(logs), "--out",
                          str(tmp_path / "r.md"), "--no-accuracy", "-q"], capture_output=True, text=True,
                         cwd=ROOT, timeout=300)
    assert run.returncode == 0, run.stderr
    assert "Coverage of the printed intervals:" in run.stdout
    assert "| 4.1 | 1 | 1 | 100 % | 1/1 |" in run.stdout
    assert "| 4.1 | 1 | 1 | 100 % | 1/1 |" in (tmp_path / "r.md").read_text()


def test_the_shipped_report_says_the_codes_touch_speed_and_table_4_1s_kinds_of_error():
    """Issue 30 item 6: reports/calibration.md (rebuilt by `calib report`) quotes the measuring
    approach from rcci.calib.touch.SLOW, and Table 4.1's columns say which error is a spread (1 sd)
    and which an a priori bound, unlike the 99.73 % intervals of the other tables."""
    from rcci.calib.touch import SLOW

    text = open(os.path.join(ROOT, "reports", "calibration.md"), encoding="utf-8").read()
    assert f"approaching each face along its normal at {1e3 * SLOW:.1f} mm/s (rcci.calib.touch.SLOW)" in text
    assert "fit std (1 sd)" in text and "fit indep. error (a priori bound)" in text
    assert "not a 99.73 % interval" in text


def test_pose_files_into_a_missing_folder_are_refused_before_the_fit(tmp_path, capsys):
    """Item 6 for `calib fit kinematics POSES.csv -p`: the folder is checked before the file is
    read (a file that would fail to parse shows the order), as for logs."""
    from rcci.calib.__main__ import main

    poses = tmp_path / "poses.csv"
    poses.write_text("1,2,3\n")
    assert main(["fit", "kinematics", str(poses), "-p", str(tmp_path / "no" / "p.toml")]) == 2
    err = capsys.readouterr().err
    assert "does not exist" in err and "nothing was fitted" in err and "record 1" not in err
