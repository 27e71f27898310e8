"""rccl.kinematics.load, the one loader of the generated kinematics: a robot's module by name,
and a refusal that names the robot and the cure (the robots there are, or `make derive`)."""
from __future__ import annotations

import shutil
import sys

import pytest

import rcci.models
import rccl.kinematics
from rccl.kinematics import KinematicsNotFound, load


def test_each_robot_with_a_data_file_loads_its_generated_module():
    for robot in rcci.models.available_robots():
        mod = load(robot)
        assert mod is sys.modules[f"rccl.kinematics.{robot}"]
        assert mod.fk(mod.LOWER * 0.0).shape == (4, 4)      # a real module of the contract, not a stub


def test_an_unknown_robot_is_refused_naming_the_robots_there_are():
    with pytest.raises(KinematicsNotFound, match=r"robot='puma': no such robot; known: .*puma260.*models/ROBOT.toml"):
        load("puma")
    with pytest.raises(ValueError, match=r"robot=6: no such robot"):    # a ValueError for rccl.open's callers
        load(6)


def test_a_data_file_without_make_derive_is_refused_with_the_cure(tmp_path, monkeypatch):
    text = (rcci.models.models_dir() / "puma260.toml").read_text()
    (tmp_path / "nogenerated.toml").write_text(text.replace('name = "puma260"', 'name = "nogenerated"'))
    shutil.copytree(rcci.models.models_dir() / "urdf", tmp_path / "urdf")
    monkeypatch.setenv("RCCI_MODELS", str(tmp_path))
    with pytest.raises(ImportError, match=r"robot='nogenerated': no generated kinematics "
                                          r"\(rccl/kinematics/nogenerated.py\); run `make derive`"):
        load("nogenerated")


def test_an_import_error_inside_a_generated_module_is_not_hidden(monkeypatch):
    """Only the robot's own module missing means `make derive`; a module it needs is another fault."""
    def broken(name):
        raise ModuleNotFoundError("No module named 'casadi'", name="casadi")

    monkeypatch.setattr(rccl.kinematics.loader.importlib, "import_module", broken)
    with pytest.raises(ModuleNotFoundError, match="casadi") as err:
        load("puma260")
    assert not isinstance(err.value, KinematicsNotFound)
