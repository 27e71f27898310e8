"""What calib needs to know about a robot: its drive conversions and its gravity model.

Both come from the runtime (rci.conversions and the models package for the drive, the
generated rccl.kinematics module for the gravity regressor of 4.24), so calib fits the
very model the controller uses; until the generated module offers a regressor, calib
uses 4.24 in the form the data file documents (thesis_regressor).
"""
from __future__ import annotations

import importlib
import tomllib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calib.drive import Drive
from calib.exceptions import CalibError

GRAVITY_NAMES = ("c12", "c13", "c15")


@dataclass(frozen=True)
class RobotInfo:
    """A robot's drive, gravity model and nominal (data-file) parameters, SI units."""

    name: str
    drive: Drive
    regressor: Callable[[np.ndarray], np.ndarray]
    nominal: dict
    lower: np.ndarray
    upper: np.ndarray

    def gravity(self, coeffs: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
        """tau_g(q) (N m) for the coefficients (c12, c13, c15)."""
        c = np.asarray(coeffs, dtype=float)
        return lambda q: np.asarray(self.regressor(q)) @ c


def _data_file(path: Path) -> dict:
    """The data file's raw tables (its own units), read from where ``models.load_robot``
    found and validated it (``$RCCI_MODELS`` or the models package)."""
    try:
        with open(path, "rb") as f:
            return tomllib.load(f)
    except OSError as exc:
        raise CalibError(f"{path}: cannot read robot data file: {exc.strerror}") from None


def thesis_regressor(q: np.ndarray) -> np.ndarray:
    """Eq. 4.24 as a regressor (6,3) in (c12, c13, c15): tau_g = Y(q) c, q in rad."""
    t1, t2, t3, t4, t5, t6 = np.asarray(q, dtype=float)
    s23, c23 = np.sin(t2 + t3), np.cos(t2 + t3)
    w = c23 * np.cos(t4) * np.sin(t5) + np.cos(t5) * s23
    Y = np.zeros((6, 3))
    Y[1] = [np.cos(t2), s23, w]
    Y[2] = [0.0, s23, w]
    Y[3, 2] = -s23 * np.sin(t4) * np.sin(t5)
    Y[4, 2] = c23 * np.sin(t5) + np.cos(t4) * np.cos(t5) * s23
    return Y


def _regressor(name: str) -> Callable[[np.ndarray], np.ndarray]:
    try:
        kin = importlib.import_module(f"rccl.kinematics.{name}")
        reg = kin.gravity_regressor
    except (ImportError, AttributeError):
        if name != "puma260":
            raise CalibError(f"no gravity model for robot {name!r}") from None
        return thesis_regressor
    return lambda q: np.asarray(reg(np.asarray(q, dtype=float)), dtype=float).reshape(6, -1)


def robot_info(name: str) -> RobotInfo:
    """Drive conversions, gravity regressor and nominal parameters of robot ``name``.

    The drive is rci.conversions' (the encoder ratio matrix in the form the runtime
    uses), the ranges the models package's; the nominal values are the data file's.
    """
    from rci.conversions import Conversions
    from models import ModelError, load_robot

    try:
        model = load_robot(name)
        conv = Conversions.from_model(model)
    except (ModelError, ValueError) as exc:
        raise CalibError(f"robot {name!r}: {exc}") from None
    drive = Drive(R=np.array(conv.R), G=np.array(conv.G),
                  amps_per_adc=conv.v_g / np.array(conv.sense_resistance),
                  sigma=np.array(conv.sigma), encoder_offset=np.array(conv.encoder_offset))
    return RobotInfo(name, drive, _regressor(name), _data_file(model.path),
                     np.array(model.lower, dtype=float), np.array(model.upper, dtype=float))
