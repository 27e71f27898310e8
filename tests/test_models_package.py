"""The models package as its users meet it: old import paths, ``$RCCI_MODELS`` everywhere,
one parameter-file reader, one friction record."""
from __future__ import annotations

import dataclasses
import shutil
from pathlib import Path

import numpy as np
import pytest

import rcci.models
from rcci.models import FRICTION_KEYS, JointFriction, ModelError, load_robot
from rcci.models.params import SCHEMA, ParamsFileError, read_params


def test_old_import_paths_name_the_same_objects():
    import rci
    import rci.exceptions
    import rci.robot_model

    assert rci.robot_model.load_robot is rcci.models.load_robot
    assert rci.robot_model.RobotModel is rcci.models.RobotModel
    assert rci.ModelError is rci.exceptions.ModelError is ModelError
    assert not issubclass(ModelError, rci.RCIError)   # its own root, below rci


def test_calib_reads_the_data_file_from_rcci_models(tmp_path, monkeypatch):
    """calib's nominal values come from where the loader found the robot, $RCCI_MODELS included."""
    from rcci.calib.robot import robot_info

    shutil.copytree(rcci.models.models_dir(), tmp_path / "m", ignore=shutil.ignore_patterns("*.py", "__pycache__"))
    path = tmp_path / "m" / "puma260.toml"
    text = path.read_text()
    assert 'title = "Unimation PUMA 260"' in text
    path.write_text(text.replace('title = "Unimation PUMA 260"', 'title = "PUMA 260 from RCCI_MODELS"'))
    monkeypatch.setenv("RCCI_MODELS", str(tmp_path / "m"))
    assert robot_info("puma260").nominal["robot"]["title"] == "PUMA 260 from RCCI_MODELS"


@pytest.mark.parametrize("text, field", [
    ("not toml [", "<file>"),
    ('[calib]\nschema = "other/1"\nrobot = "puma260"\n', "calib.schema"),
    ('[motors]\nx = 1\n', "calib.schema"),
])
def test_one_reader_for_calib_and_simula(tmp_path, text, field):
    """calib and simula refuse the same files with the same message (the one reader's)."""
    from rcci.calib.exceptions import CalibError
    from rcci.calib.params import read_params as calib_read
    from rci.simula.exceptions import ParamsError
    from rci.simula.params import load_params, truth_from_model

    bad = tmp_path / "bad.toml"
    bad.write_text(text)
    with pytest.raises(ParamsFileError) as info:
        read_params(bad)
    assert info.value.field == field and str(bad) in str(info.value)
    with pytest.raises(CalibError) as from_calib:
        calib_read(str(bad))
    with pytest.raises(ParamsError) as from_simula:
        load_params(bad, "puma260", truth_from_model(load_robot("puma260")))
    assert str(from_calib.value) == str(from_simula.value) == str(info.value)


def test_a_file_calib_writes_is_one_simula_reads(tmp_path):
    from rcci.calib.params import update_params
    from rci.simula.params import load_params, truth_from_model

    path = tmp_path / "p.toml"
    update_params(str(path), "puma260", {"friction": {"coulomb_pos": [0.5] * 6}}, command="test")
    assert read_params(path)["calib"]["schema"] == SCHEMA
    truth = load_params(path, "puma260", truth_from_model(load_robot("puma260")))
    np.testing.assert_array_equal(truth.coulomb_pos, [0.5] * 6)


def test_simula_calib_and_the_force_model_share_one_friction_record():
    from rcci.calib.params import Fitted, load_fitted
    from rccl.adaptive.force import JointModel
    from rci.simula.params import Truth, truth_from_model

    puma = load_robot("puma260")
    records = (truth_from_model(puma), load_fitted(None, "puma260"), JointModel.for_robot("puma260"))
    for cls, rec in zip((Truth, Fitted, JointModel), records):
        assert issubclass(cls, JointFriction) and isinstance(rec, cls)
        assert [f.name for f in dataclasses.fields(cls)][:6] == list(FRICTION_KEYS)
        for key in FRICTION_KEYS:   # all three start from the data file's Table 4.2/4.3/4.5 values
            np.testing.assert_allclose(getattr(rec, key), getattr(puma.friction, key).values)
