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
