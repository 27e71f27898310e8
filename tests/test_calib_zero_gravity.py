"""The zero-gravity program (thesis 2.2.2) on calib's fitted parameters (issue 7)."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from rcci.calib.params import update_params

ROOT = Path(__file__).resolve().parent.parent
NOMINAL_C12 = 5.509          # models/puma260.toml, Table 4.9


def _run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "examples/zero_gravity.py", *args], capture_output=True,
                          text=True, timeout=90, cwd=ROOT, stdin=subprocess.DEVNULL)


def _drift(r: subprocess.CompletedProcess) -> list[float]:
    assert r.returncode == 0, r.stderr
    return [float(x) for x in r.stdout.split("[")[1].split("]")[0].split()]


def test_zero_gravity_floats_an_arm_whose_gravity_only_the_fitted_file_knows(tmp_path):
    """simula runs on a parameter file whose c12 is 60 % above the data file's (an arm
    carrying a tool, say); zero_gravity --params FILE compensates it and holds the arm,
    while with the data file's c12 joint 2 falls onto its mechanical stop."""
    params = str(tmp_path / "fitted.toml")
    update_params(params, "puma260", {"gravity_coeffs": {"c12": 1.6 * NOMINAL_C12}}, "test")
    sim = f"-c --warm --params {params}"
    held = _drift(_run("--simula", sim, "--cycles", "72", "--params", params))
    assert max(abs(x) for x in held) < 0.06, held           # degrees
    fell = _run("--simula", sim, "--cycles", "72")           # data-file gravity: the arm drops
    assert fell.returncode != 0 and "mechanical stop" in fell.stdout + fell.stderr, fell.stdout


def test_zero_gravity_names_a_bad_parameter_file(tmp_path):
    bad = tmp_path / "other.toml"
    update_params(str(bad), "microbo", {"gravity_coeffs": {"c15": 0.1}}, "test")
    r = _run("--params", str(bad), "--cycles", "1")
    assert r.returncode != 0 and "other.toml" in r.stderr and "puma260" in r.stderr
