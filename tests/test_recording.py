"""Recording an RCCL run and looking at it (issue 29, items 2 and 3): examples/record_rccl.py and python -m rci.plot.

The example runs as a user runs it (its own simula; lockstep, so that a loaded machine cannot make
its cycles late) and writes the log, the PNG and
the MCAP file; the log's commanded T6 goes round the square, the measured T6 follows it, and
the picture has the six panels' curves in it.
"""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import matplotlib.image
import numpy as np
import pytest

from rci.log_units import log_in_si
from rci.plot import default_out
from rci.recorder import read_log

ROOT = Path(__file__).resolve().parent.parent


def _run(*args: str, timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, *args], capture_output=True, text=True, timeout=timeout, cwd=ROOT,
                          stdin=subprocess.DEVNULL)


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("rec")
    r = _run("examples/record_rccl.py", "--log", str(out / "run.rcilog"), "--png", str(out / "run.png"),
             "--mcap", str(out / "run.mcap"), "--lockstep")
    assert r.returncode == 0, r.stderr
    assert "recorded" in r.stdout and "lost 0" in r.stdout
    return out


def test_the_recorded_rccl_run_goes_round_the_square(run):
    sys.path.insert(0, str(ROOT / "examples"))
    try:
        import record_rccl as ex
    finally:
        sys.path.pop(0)
    log = read_log(run / "run.rcilog", strict=True)
    assert log.meta["robot"] == "puma260" and log.meta["meta"]["program"] == "examples/record_rccl.py"
    si = log_in_si(log)
    commanded = np.all(np.isfinite(si.q_cmd), axis=1)
    assert commanded.mean() > 0.95                       # RCCL sends POS to every joint each cycle
    p = si.T6_cmd[commanded, :3, 3]
    corners = [ex.CORNER + ex.SIDE * np.array(d) for d in ((0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0))]
    for c in corners:                                    # the transitions round the corners (Paul's quartic)
        assert np.min(np.linalg.norm(p - c, axis=1)) < 0.01, c
    on_plane = np.abs(p[:, 2] - ex.CORNER[2]) < 1e-4
    assert on_plane.sum() > 50                           # the square's straight lines stay in their plane
    # the arm (simula's Pinocchio world) follows the commanded T6
    lag = np.linalg.norm(si.T6[commanded, :3, 3] - p, axis=1)
    assert np.max(lag) < 0.01, np.max(lag)


def test_the_picture_of_the_run(run):
    png = matplotlib.image.imread(run / "run.png")
    assert png.shape[:2] == (1210, 1430)
    ink = png[..., :3].min(axis=2) < 0.9
    assert 0.03 < ink.mean() < 0.5
    orange = (png[..., 0] > 0.9) & (np.abs(png[..., 1] - 0.5) < 0.1) & (png[..., 2] < 0.2)
    assert orange.sum() > 500                            # the commanded path and joint 2's curves
    assert (run / "run.mcap").stat().st_size > 10_000


def test_the_plot_command(run, tmp_path):
    log = tmp_path / "copy.rcilog"
    log.write_bytes((run / "run.rcilog").read_bytes())
    r = _run("-m", "rci.plot", str(log))
    assert r.returncode == 0, r.stderr
    assert default_out(log) == tmp_path / "copy.png" and (tmp_path / "copy.png").stat().st_size > 50_000
    assert default_out("calib/logs/kinematics.rcilog.xz") == Path("calib/logs/kinematics.png")
    bad = tmp_path / "bad.rcilog"
    bad.write_bytes(b"RCILOG\x00\x01" + b"\xff" * 40)
    r = _run("-m", "rci.plot", str(bad), "--out", str(tmp_path / "bad.png"))
    assert r.returncode == 2 and str(bad) in r.stderr and not (tmp_path / "bad.png").exists()
