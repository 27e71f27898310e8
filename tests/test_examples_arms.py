"""The examples of the arms added by their data files (issue 29, item 6): examples/puma560.py and
examples/stanford.py, each run against its own lockstep ``simula --robot ROBOT``; every target
reached to within 1 mm as the encoders say (the world side is simula's Pinocchio model)."""
from __future__ import annotations

import importlib.util
import warnings
from pathlib import Path

import numpy as np
import pytest

import rccl.kinematics
from rci.simula.process import SimulaProcess

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def load(name: str):
    spec = importlib.util.spec_from_file_location(f"example_{name}", EXAMPLES / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.mark.parametrize("robot", ["puma560", "stanford"])
def test_the_arm_reaches_the_targets_of_its_example(robot, capsys):
    ex = load(robot)
    assert ex.ROBOT == robot
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        with SimulaProcess("-p", "--power-on", robot=robot, lockstep=True) as sim:
            reached = ex.run(sim.url, timeout=2.0)
    assert list(reached) == list(ex.TARGETS)
    for name, (error, q) in reached.items():
        assert error < 1e-3, (name, error)
        goal = ex.tool_down(*ex.TARGETS[name][0], ex.TARGETS[name][1])
        kin = rccl.kinematics.load(robot)
        assert np.allclose(kin.fk(q)[:3, :3], goal[:3, :3], atol=2e-3), name    # the tool's orientation too
    out = capsys.readouterr().out
    assert all(f"{name}: T6 at" in out for name in ex.TARGETS)
    if robot == "stanford":                   # along the boom from P1 to P2: the prismatic joint slides
        assert reached["P2"][1][2] - reached["P1"][1][2] > 0.1


def test_the_panda_example_runs_its_lines_and_self_motion(capsys):
    """examples/panda_line.py on a lockstep simula --robot panda: each stop reached as programmed (the
    encoders within 1 mm), the self-motion leaves the flange where it was and turns q7 by SELF_TURN."""
    ex = load("panda_line")
    assert ex.ROBOT == "panda"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        with SimulaProcess("-p", "--power-on", robot="panda", lockstep=True) as sim:
            out = ex.run(sim.url, timeout=2.0)
    assert list(out) == ["OUT", "SELF", "BACK", "SIDE"]
    kin = rccl.kinematics.load("panda")
    from rcci.models import load_robot
    start = kin.fk(np.array(load_robot("panda").poses["ready"], dtype=float))[:3, 3]
    assert np.linalg.norm(out["OUT"][0] - (start + ex.OUT)) < 1e-3
    assert np.linalg.norm(out["SELF"][0] - out["OUT"][0]) < 1e-3          # the flange stood still
    assert out["SELF"][1] - out["OUT"][1] == pytest.approx(ex.SELF_TURN, abs=1e-3)
    assert np.linalg.norm(out["BACK"][0] - start) < 1e-3
    assert np.linalg.norm(out["SIDE"][0] - (start + ex.SIDEWAYS)) < 1e-3
    printed = capsys.readouterr().out
    assert all(f"{name}: T6 at" in printed for name in out)
