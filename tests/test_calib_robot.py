"""calib's robot model comes from the generated kinematics of any arm, by its data, not its name."""
from __future__ import annotations

import numpy as np
import pytest

from rcci.calib.exceptions import CalibError
from rcci.calib.robot import robot_info
from tests.test_calib_synth import regressor as thesis_424


def test_the_puma260_regressor_is_the_thesis_424():
    """The generated regressor calib fits with is eq. 4.24 as printed (the hand-written oracle
    of tests/test_calib_synth.py), column for column, on random configurations."""
    info = robot_info("puma260")
    assert info.gravity_names == ("c12", "c13", "c15")
    rng = np.random.default_rng(4)
    for q in rng.uniform(-2 * np.pi, 2 * np.pi, (500, 6)):
        assert np.abs(info.regressor(q) - thesis_424(q)).max() < 1e-14


def test_another_arm_brings_its_own_coefficients():
    """The PUMA 560's minimal set (derive.gravity.minimal_gravity), its regressor reproducing
    the data file's gravity vector (Pinocchio on its URDF)."""
    import pinocchio as pin

    from rcci.models import load_robot

    info = robot_info("puma560")
    assert info.gravity_names == ("cx2", "cy2", "cx3", "cz3", "cx4", "cz4", "cx5", "cz5", "cx6", "cy6")
    assert info.kinds == ("revolute",) * 6
    model = load_robot("puma560")
    pm = pin.buildModelFromUrdf(str(model.urdf_path))
    pm.gravity.linear = np.array([0.0, 0.0, -model.gravity])
    data = pm.createData()
    c = np.array([model.gravity_coeffs[n].value for n in info.gravity_names])
    for q in np.random.default_rng(5).uniform(info.lower, info.upper, (50, 6)):
        assert np.abs(info.gravity(c)(q) - pin.computeGeneralizedGravity(pm, data, q)).max() < 1e-6


def test_an_arm_without_generated_kinematics_is_refused(tmp_path, monkeypatch):
    """A model file added without `make derive`: a clear refusal naming the robot and the cure."""
    import shutil

    import rcci.models

    text = (rcci.models.models_dir() / "puma260.toml").read_text()
    (tmp_path / "nogenerated.toml").write_text(text.replace('name = "puma260"', 'name = "nogenerated"'))
    shutil.copytree(rcci.models.models_dir() / "urdf", tmp_path / "urdf")
    monkeypatch.setenv("RCCI_MODELS", str(tmp_path))
    with pytest.raises(CalibError, match=r"'nogenerated'.*no generated gravity regressor.*make derive"):
        robot_info("nogenerated")
