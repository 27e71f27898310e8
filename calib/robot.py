"""What calib needs to know about a robot: its drive conversions and its gravity model.

Both come from the runtime when it offers them (rci.conversions and rci.robot_model for
the drive, the generated rccl.kinematics module for the gravity regressor of 4.24), so
calib fits the very model the controller uses.  Where one of those is not importable,
calib reads the same robot data file (models/<robot>.toml) itself and uses 4.24 in the
form the data file documents.
"""
from __future__ import annotations

import importlib
import tomllib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calib.drive import Drive
from calib.errors import CalibError

MODELS = Path(__file__).resolve().parent.parent / "models"
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


def _data_file(name: str) -> dict:
    path = MODELS / f"{name}.toml"
    try:
        with open(path, "rb") as f:
            return tomllib.load(f)
    except OSError:
        raise CalibError(f"no robot data file {path} for robot {name!r}") from None


def _vals(data: dict, *keys: str) -> np.ndarray:
    node = data
    for k in keys:
        node = node[k]
    return np.asarray(node["values"] if isinstance(node, dict) else node, dtype=float)


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
    """Drive conversions, gravity regressor and nominal parameters of robot ``name``."""
    data = _data_file(name)
    try:
        conv = data["conversion"]
        G = _vals(conv, "gear_ratio")
        R = _vals(conv, "encoder_ratio")
        offset = _vals(conv, "encoder_offset") if "encoder_offset" in conv else np.zeros(6)
        vg = float(_scalar(conv, "adc_volts_per_count", "V_g", "vg"))
        rs = _vals(conv, _first(conv, "sense_resistance", "sense_resistor", "R_sense"))
        sigma = _vals(data, "motors", "torque_sensitivity")
    except (KeyError, TypeError, ValueError) as exc:
        raise CalibError(f"{MODELS / (name + '.toml')}: conversion constants incomplete ({exc})") from None
    drive = Drive(R=R, G=G, amps_per_adc=vg / rs, sigma=sigma,
                  encoder_offset=offset if offset.shape == (6,) else np.zeros(6))
    drive = _prefer_runtime(name, drive)
    joints = data.get("joints", [])
    lower = np.radians([j["lower"]["value"] for j in joints]) if joints else np.full(6, -np.inf)
    upper = np.radians([j["upper"]["value"] for j in joints]) if joints else np.full(6, np.inf)
    return RobotInfo(name, drive, _regressor(name), data, lower, upper)


def _first(table: dict, *keys: str) -> str:
    for k in keys:
        if k in table:
            return k
    raise KeyError(" or ".join(keys))


def _scalar(table: dict, *keys: str) -> float:
    node = table[_first(table, *keys)]
    return float(node["value"] if isinstance(node, dict) else node)


def _prefer_runtime(name: str, drive: Drive) -> Drive:
    """The runtime's conversion constants when rci.conversions offers them."""
    try:
        conv = importlib.import_module("rci.conversions")
    except ImportError:
        return drive
    factory = getattr(conv, "calib_drive", None)
    if factory is None:
        return drive
    return factory(name, drive)
