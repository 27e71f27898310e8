"""One fit of one kind over a set of logs: the results, their table, their parameter sections."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from calib.errors import CalibError
from calib.friction import fit_friction
from calib.gravity import fit_gravity
from calib.robot import GRAVITY_NAMES, RobotInfo
from calib.sensitivity import fit_sensitivity
from calib.static import fit_static
from calib.tables import table_4_1, table_4_2_4_3, table_4_5, table_4_6, table_4_8_4_9
from calib.trace import Trace

KINDS = ("sensitivity", "friction", "static", "gravity", "breakaway")


@dataclass
class FitOutcome:
    """What a fit produced: the printed table, TOML sections, and the raw results."""

    kind: str
    table: str
    sections: dict[str, dict[str, Any]]
    results: Any
    extra: dict[str, Any] = field(default_factory=dict)


def current_values(info: RobotInfo, params: dict | None) -> dict[str, np.ndarray]:
    """Torque sensitivities and gravity coefficients to use as inputs: the parameter
    file's fitted values where it has them, else the robot data file's."""
    sigma = np.asarray(info.drive.sigma, dtype=float)
    coeffs = np.array([info.nominal["gravity_coeffs"][n]["value"] for n in GRAVITY_NAMES])
    if params:
        if "motors" in params and "torque_sensitivity" in params["motors"]:
            sigma = np.asarray(params["motors"]["torque_sensitivity"], dtype=float)
        if "gravity_coeffs" in params:
            coeffs = np.array([params["gravity_coeffs"].get(n, c) for n, c in zip(GRAVITY_NAMES, coeffs)])
    return {"sigma": sigma, "gravity": coeffs}


def _merge(old: dict | None, key: str, base: np.ndarray, joints: list[int], new: list[float]) -> list[float]:
    arr = np.array(old[key], dtype=float) if old and key in old else np.array(base, dtype=float)
    for j, v in zip(joints, new):
        arr[j - 1] = v
    return [float(x) for x in arr]


def run_fit(kind: str, traces: list[Trace], info: RobotInfo, params: dict | None) -> FitOutcome:
    """Fit ``kind`` on ``traces``; inputs (sigma, gravity) from ``params`` or nominal."""
    if kind not in KINDS:
        raise CalibError(f"unknown fit kind {kind!r}; one of {', '.join(KINDS)}")
    inputs = current_values(info, params)
    drive = info.drive.with_sigma(inputs["sigma"])
    params = params or {}
    if kind == "sensitivity":
        res = fit_sensitivity(traces, drive)
        joints = [r.joint for r in res]
        old = params.get("motors")
        sec = {"torque_sensitivity": _merge(old, "torque_sensitivity", info.drive.sigma, joints, [r.mean for r in res]),
               "torque_sensitivity_std": _merge(old, "torque_sensitivity_std", np.full(6, np.nan), joints, [r.std for r in res]),
               "torque_sensitivity_error": _merge(old, "torque_sensitivity_error", np.full(6, np.nan), joints, [r.independent_error for r in res]),
               "torque_sensitivity_trials": [int(x) if np.isfinite(x) else 0 for x in _merge(old, "torque_sensitivity_trials", np.zeros(6), joints, [r.trials for r in res])],
               "unit": "N*m/A"}
        return FitOutcome(kind, table_4_1(res), {"motors": sec}, res)
    if kind == "friction":
        res, points = fit_friction(traces, drive)
        joints = [r.joint for r in res]
        old = params.get("friction")
        nom = info.nominal["friction"]
        sec: dict[str, Any] = {}
        for key, get in (("coulomb_pos", lambda r: r.plus.coulomb), ("coulomb_neg", lambda r: r.minus.coulomb),
                         ("viscous_pos", lambda r: r.plus.viscous), ("viscous_neg", lambda r: r.minus.viscous),
                         ("coulomb_pos_error", lambda r: r.plus.coulomb_err), ("coulomb_neg_error", lambda r: r.minus.coulomb_err),
                         ("viscous_pos_error", lambda r: r.plus.viscous_err), ("viscous_neg_error", lambda r: r.minus.viscous_err),
                         ("variation", lambda r: r.variation)):
            base = np.asarray(nom[key]["values"], float) if key in nom else np.full(6, np.nan)
            sec[key] = _merge(old, key, base, joints, [get(r) for r in res])
        for key in ("static_pos", "static_neg"):  # Table 4.5 is hand-measured: carried over
            sec[key] = list(old[key]) if old and key in old else [float(x) for x in nom[key]["values"]]
        return FitOutcome(kind, table_4_2_4_3(res), {"friction": sec}, res, {"points": points})
    if kind == "gravity":
        fr = params.get("friction") or {}
        nom = info.nominal["friction"]
        coulomb = 0.5 * (np.asarray(fr.get("coulomb_pos", nom["coulomb_pos"]["values"]), float)
                         + np.asarray(fr.get("coulomb_neg", nom["coulomb_neg"]["values"]), float))
        res = fit_gravity(traces, drive, info.regressor, GRAVITY_NAMES, noise=coulomb)
        sec = {n: float(v) for n, v in zip(res.names, res.value)}
        sec.update({f"{n}_error": float(e) for n, e in zip(res.names, res.error)})
        sec.update({f"{n}_friction_error": float(e) for n, e in zip(res.names, res.friction_error)})
        sec["unit"] = "N*m"
        return FitOutcome(kind, table_4_8_4_9(res), {"gravity_coeffs": sec}, res)
    if kind == "breakaway":
        from calib.breakaway import fit_breakaway

        res, pts = fit_breakaway(traces, drive, info.gravity(inputs["gravity"]))
        joints = [r.joint for r in res]
        old = dict(params.get("friction") or {})
        nom = info.nominal["friction"]
        sec = dict(old)
        for key, get in (("static_pos", lambda r: r.plus), ("static_neg", lambda r: r.minus)):
            sec[key] = _merge(old, key, np.asarray(nom[key]["values"], float), joints, [get(r) for r in res])
        return FitOutcome(kind, table_4_5(res), {"friction": sec}, res, {"points": pts})
    res, samples = fit_static(traces, drive, info.gravity(inputs["gravity"]))
    sec = {"samples": int(res[0].samples),
           "maximum": [r.maximum for r in res], "minimum": [r.minimum for r in res],
           "mean": [r.mean for r in res], "std": [r.std for r in res], "unit": "N*m"}
    return FitOutcome(kind, table_4_6(res), {"static_friction": sec}, res, {"samples": samples})
