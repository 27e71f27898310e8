"""The four RCI example programs, each run against a real simula process (lockstep)."""
from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rci import codes
from rci.conversions import Conversions
from rci.session import Session
from rci.simula.process import SimulaProcess

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
CONV = Conversions.for_robot("puma260")


def load(name: str):
    spec = importlib.util.spec_from_file_location(f"rci_example_{name}", EXAMPLES / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def run_example(*args: str, timeout: float = 60.0) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, *args], capture_output=True, text=True, timeout=timeout,
                          cwd=EXAMPLES.parent, stdin=subprocess.DEVNULL)


def test_zero_gravity_holds_and_moves_when_pushed():
    zg = load("zero_gravity")
    with SimulaProcess("-c", "--warm", "--test-channel", lockstep=True) as sim:
        with Session(sim.url, "puma260", rate_hz=36, lock_memory=False) as s:
            w = zg.Weightless(s)
            s.control(None, w)
            s.chg.power_on.com = 1
            assert s.wait(until=lambda: s.how.power, seconds=5)
            start_cycle = s.how.cycle
            q0 = CONV.counts_to_angles(s.how.pos)
            assert s.wait(until=lambda: s.how.cycle - start_cycle >= 72, seconds=30)    # 2 simulated s
            held = CONV.counts_to_angles(s.how.pos) - q0
            assert np.max(np.abs(held)) < 1e-3, held
            assert sim.command("torque 2 3.0")["ok"]                                   # a hand pushes joint 2
            c1 = s.how.cycle
            assert s.wait(until=lambda: s.how.cycle - c1 >= 18, seconds=30)
            moved = CONV.counts_to_angles(s.how.pos) - q0
            assert moved[1] > 0.01 and np.max(np.abs(moved[[0, 3, 4, 5]])) < 1e-3, moved
            assert np.all(np.isfinite(w.torques)) and abs(w.torques[1]) > 1.0          # it does carry gravity
            s.release()


def test_zero_gravity_command_line():
    # a 2 s HOW timeout: the lockstep default (0.25 s) ended the run at a load of 14 on 2 cores
    r = run_example("examples/zero_gravity.py", "--simula", "-c --warm", "--cycles", "72", "--timeout", "2")
    assert r.returncode == 0, r.stderr
    drift = [float(x) for x in r.stdout.split("[")[1].split("]")[0].split()]
    assert len(drift) == 6 and max(abs(x) for x in drift) < 0.06       # degrees


def test_calibration_program_calibrates_an_uncalibrated_simula():
    cal_mod = load("calibrate")
    with SimulaProcess(seed=5, lockstep=True) as sim:
        with Session(sim.url, "puma260", lock_memory=False) as s:
            assert not s.how.state & codes.CALIB_OK
            cal = cal_mod.calibrate(s, timeout=60)
            assert s.how.state & codes.CALIB_OK and s.how.state & codes.ZINDEX_OK
            truth = sim.command("state")["state"]
            np.testing.assert_allclose(CONV.counts_to_angles(s.how.pos), truth["q"], atol=3e-4)
            assert truth["calibrated"] is True or all(truth["calibrated"])
            assert cal.marks is not None


def test_teach_program_with_scripted_keys(tmp_path):
    teach = load("teach")
    lines: list[str] = []
    with SimulaProcess("-p", lockstep=True) as sim:
        with Session(sim.url, "puma260", lock_memory=False) as s:
            q0 = CONV.counts_to_angles(np.array(sim.command("state")["state"]["counters"]))
            poses = teach.teach(s, iter("2++++r3--rs3+rpq"), echo=lines.append)
    poses = np.array(poses)
    assert poses.shape == (3, 6)
    d1 = np.degrees(poses[0] - q0)
    d2 = np.degrees(poses[1] - poses[0])
    d3 = np.degrees(poses[2] - poses[1])
    np.testing.assert_allclose(d1, [0, 8, 0, 0, 0, 0], atol=0.05)
    np.testing.assert_allclose(d2, [0, 0, -4, 0, 0, 0], atol=0.05)
    np.testing.assert_allclose(d3, [0, 0, 1, 0, 0, 0], atol=0.05)          # 's' halved the step
    assert any(x.startswith("pose (deg)") for x in lines)
    out = tmp_path / "poses.json"
    r = run_example("examples/teach.py", "--simula=-p", "--keys", "1+r q", "--out", str(out))
    assert r.returncode == 0, r.stderr
    saved = json.loads(out.read_text())
    assert saved["unit"] == "rad" and len(saved["poses"]) == 1


def test_error_recovery_example_recovers():
    r = run_example("examples/error_recovery.py", "--simula=-p", "--speed", "1.6", "--angle", "10")
    assert r.returncode == 0, r.stderr
    out = r.stdout.splitlines()
    assert out[0].startswith("TERMINATE/ error handler") and out[0].endswith("/ requested velocity too great (joint 1)")
    assert "R_REQVEL: slower" in out and out[-1] == "done at 0.80 x the speed limit"


def test_teach_program_on_a_terminal(tmp_path):
    """Keys typed on a real terminal (a pty in cbreak mode) drive the teach program."""
    import os
    import time
    out = tmp_path / "tty.json"
    master, slave = os.openpty()
    proc = subprocess.Popen([sys.executable, "examples/teach.py", "--simula=-p", "--out", str(out)],
                            cwd=EXAMPLES.parent, stdin=slave, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    os.close(slave)
    try:
        deadline = time.monotonic() + 30
        assert proc.stdout.readline().startswith("ready:")     # keys typed from now on act at once
        for key in "1++r":
            os.write(master, key.encode())
            time.sleep(0.1)
        while not out.exists() and time.monotonic() < deadline:
            os.write(master, b"q")
            time.sleep(0.3)
            if proc.poll() is not None:
                break
        proc.wait(timeout=max(1.0, deadline - time.monotonic()))
    finally:
        if proc.poll() is None:
            proc.kill()
        os.close(master)
    assert proc.returncode == 0, proc.stderr.read()
    poses = json.loads(out.read_text())["poses"]
    assert len(poses) == 1
    from rcci.models import load_robot
    ready = load_robot("puma260").poses["ready"]
    np.testing.assert_allclose(np.degrees(np.array(poses[0]) - ready), [4, 0, 0, 0, 0, 0], atol=0.05)
