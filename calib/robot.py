"""What calib needs to know about a robot: its drive conversions and its gravity model.

Both come from the runtime (rci.conversions and the models package for the drive, the
generated rccl.kinematics module for the gravity regressor, 4.24 for the PUMA 260 and the
derivation's minimal set of coefficients for any other arm), so calib fits the very model
the controller uses, whatever the arm: nothing here depends on the robot's name.
"""
from __future__ import annotations

import tomllib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rcci.calib.drive import Drive
from rcci.calib.exceptions import CalibError

@dataclass(frozen=True)
class RobotInfo:
    """A robot's drive, gravity model and nominal (data-file) parameters, SI units."""

    name: str
    drive: Drive
    regressor: Callable[[np.ndarray], np.ndarray]
    nominal: dict
    lower: np.ndarray
    upper: np.ndarray
    gravity_names: tuple[str, ...]    # the regressor's columns (PUMA 260: c12, c13, c15)
    kinds: tuple[str, ...]            # "revolute" or "prismatic" per joint

    def gravity(self, coeffs: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
        """tau_g(q) (N m) for the coefficients in the order of ``gravity_names``."""
        c = np.asarray(coeffs, dtype=float)
        return lambda q: np.asarray(self.regressor(q)) @ c


def _data_file(path: Path) -> dict:
    """The data file's raw tables (its own units), read from where ``rcci.models.load_robot``
    found and validated it (``$RCCI_MODELS`` or the models package)."""
    try:
        with open(path, "rb") as f:
            return tomllib.load(f)
    except OSError as exc:
        raise CalibError(f"{path}: cannot read robot data file: {exc.strerror}") from None


def _gravity_model(name: str) -> tuple[Callable[[np.ndarray], np.ndarray], tuple[str, ...]]:
    """The generated module's gravity regressor (q (n,) rad -> (n, k)) and its column names."""
    from rccl.kinematics import KinematicsNotFound, load

    try:
        kin = load(name)
        reg, names = kin.gravity_regressor, tuple(kin.GRAVITY_COEFFS)
    except (KinematicsNotFound, AttributeError):
        raise CalibError(f"robot {name!r}: no generated gravity regressor (rccl.kinematics.{name}."
                         "gravity_regressor); run `make derive` after adding its model file") from None
    return (lambda q: np.asarray(reg(np.asarray(q, dtype=float)), dtype=float).reshape(len(q), -1)), names


def robot_info(name: str) -> RobotInfo:
    """Drive conversions, gravity regressor and nominal parameters of robot ``name``.

    The drive is rci.conversions' (the encoder ratio matrix in the form the runtime
    uses), the ranges the models package's; the nominal values are the data file's.
    """
    from rci.conversions import Conversions
    from rcci.models import ModelError, load_robot

    try:
        model = load_robot(name)
        conv = Conversions.from_model(model)
    except (ModelError, ValueError) as exc:
        raise CalibError(f"robot {name!r}: {exc}") from None
    drive = Drive(R=np.array(conv.R), G=np.array(conv.G),
                  amps_per_adc=conv.v_g / np.array(conv.sense_resistance),
                  sigma=np.array(conv.sigma), encoder_offset=np.array(conv.encoder_offset))
    regressor, names = _gravity_model(model.name)
    return RobotInfo(name, drive, regressor, _data_file(model.path),
                     np.array(model.lower, dtype=float), np.array(model.upper, dtype=float),
                     names, tuple(model.kinds))
