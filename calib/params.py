"""The parameter file calib writes and the runtime loads (TOML; schema in docs/calib.md).

Each fit updates only its own sections and keeps the others, so a sequence of fits
(sensitivity, then friction, then gravity, then static) builds one file.  The file is
written to a temporary name beside it and renamed over it (atomic on POSIX), so a fit
that fails, or a crash while writing, leaves the previous file exactly as it was.
"""
from __future__ import annotations

import datetime as _dt
import math
import os
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

import rcci.models.params
from rcci.calib.exceptions import CalibError
from rcci.models import FRICTION_KEYS, JointFriction, ModelError
from rcci.models.params import SCHEMA


def read_params(path: str) -> dict[str, Any]:
    """A parameter file as a dict (``rcci.models.params``, the one reader); CalibError naming the
    file when it is not one."""
    try:
        return rcci.models.params.read_params(path)
    except ModelError as exc:
        raise CalibError(str(exc)) from None


def update_params(path: str, robot: str, sections: Mapping[str, Mapping[str, Any]],
                  command: str, kind: str | None = None, assumed: list[str] | None = None,
                  truth: str = "", logs: list[str] | None = None) -> dict[str, Any]:
    """Merge ``sections`` into the file at ``path`` (created if absent), atomically.

    ``[calib] truth_KIND`` says what the logs of fit ``kind`` were recorded against
    (rcci.calib.truth.truth_label: the robot, or the simula's seed and parameter file with its
    hash), so that every value's origin is in the file and a later fit that takes it as an
    input can warn when its own logs are of another truth (rcci.calib.fitting.Inputs);
    ``[calib] logs_KIND`` names the logs (file names) the fit's values came from.

    ``[calib] assumed`` lists the values fits took from the robot data file instead of an
    earlier fit (``--assume-datafile``); the entries of fit ``kind`` are replaced by
    ``assumed`` (a refit without assumptions clears them)."""
    data: dict[str, Any] = {}
    if os.path.exists(path):
        data = read_params(path)
        old_robot = data["calib"].get("robot")
        if old_robot != robot:
            raise CalibError(f"{path}: holds parameters of robot {old_robot!r}, "
                             f"these logs are of {robot!r}; choose another --params file")
    data.setdefault("calib", {})
    data["calib"].update({"schema": SCHEMA, "robot": robot,
                          "updated_utc": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")})
    history = list(data["calib"].get("commands", []))
    history.append(command)
    data["calib"]["commands"] = history[-20:]
    if kind is not None:
        kept = [a for a in data["calib"].get("assumed", []) if not a.startswith(f"{kind}:")]
        data["calib"]["assumed"] = kept + list(assumed or [])
        if not data["calib"]["assumed"]:
            del data["calib"]["assumed"]
    if kind is not None and truth:
        data["calib"][f"truth_{kind}"] = truth
    if kind is not None and logs:
        data["calib"][f"logs_{kind}"] = [os.path.basename(p) for p in logs]
    for name, body in sections.items():
        data[name] = dict(body)
    head = ("# Calibration parameters fitted by `calib` (docs/calib.md); rebuilt by the\n"
            "# commands listed in [calib].commands.  SI units: N*m, N*m*s/rad, N*m/A, rad, m.\n"
            "# NaN: not fitted (simula --params keeps its own value there).\n")
    if data["calib"].get("assumed"):
        head += ("# NOT ALL MEASURED: [calib].assumed lists values taken from the robot data file\n"
                 "# (--assume-datafile) where a fit needed an earlier fit's result.\n")
    text = head + "\n" + dumps(data)
    atomic_write(path, text)
    return data


def writable_params(path: str) -> None:
    """Refuse (CalibError) a parameter file calib could not write: its folder missing or not
    writable, or the path a folder; checked before a fit so that its result is not lost."""
    folder = os.path.dirname(os.path.abspath(path))
    if os.path.isdir(path):
        raise CalibError(f"-p {path}: is a folder, not a parameter file")
    if not os.path.isdir(folder):
        raise CalibError(f"-p {path}: the folder {folder} does not exist; create it first (nothing was fitted)")
    if not os.access(folder, os.W_OK):
        raise CalibError(f"-p {path}: the folder {folder} is not writable (nothing was fitted)")


def atomic_write(path: str, text: str) -> None:
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix=".calib-", suffix=".tmp", dir=folder)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            # mkstemp makes the file 0600; give it the mode a plain open() would (a report or a
            # parameter file is for others to read too), or the mode of the file it replaces
            os.fchmod(f.fileno(), _mode_for(path))
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _mode_for(path: str) -> int:
    """The permission bits of ``path`` if it exists, else 0o666 less the process's umask."""
    try:
        return os.stat(path).st_mode & 0o7777
    except FileNotFoundError:
        mask = os.umask(0)
        os.umask(mask)
        return 0o666 & ~mask


def dumps(data: Mapping[str, Any]) -> str:
    """TOML for a two-level mapping of tables of scalars and lists (what calib writes)."""
    lines: list[str] = []
    for table, body in data.items():
        lines.append(f"[{table}]")
        for key, value in body.items():
            lines.append(f"{key} = {_value(value)}")
        lines.append("")
    return "\n".join(lines)


def _value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if hasattr(v, "tolist"):
        return _value(v.tolist())
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


@dataclass(frozen=True)
class Fitted(JointFriction):
    """The values a runtime program needs (zero gravity, compliance, 4.37/4.38), SI units:
    fitted where the parameter file has them, the robot data file's elsewhere. The friction
    of eq. 4.27 is the fields of ``JointFriction``."""

    robot: str
    sigma: np.ndarray
    gravity_coeffs: dict[str, float]
    source: str
    # the values that are the data file's, not fitted ("friction.coulomb_pos[3]", ...),
    # plus those the file itself says a fit assumed ([calib] assumed)
    assumed: tuple[str, ...] = ()


def load_fitted(path: str | None, robot: str) -> Fitted:
    """Fitted parameters of ``robot`` from the file at ``path`` (None: the data file's).

    Usage in a control program: ``p = load_fitted(args.params, "puma260")`` then
    ``Conversions.from_model(model, sigma=p.sigma)`` and ``gravity(q, p.gravity_coeffs)``;
    ``p.assumed`` names every value that is the data file's rather than fitted, for the
    program to print.
    """
    from rcci.calib.robot import robot_info

    nominal = robot_info(robot).nominal
    data = read_params(path) if path else {"calib": {"robot": robot}}
    if data["calib"].get("robot") != robot:
        raise CalibError(f"{path}: parameters are for robot {data['calib'].get('robot')!r}, not {robot!r}")

    assumed: list[str] = list(data["calib"].get("assumed", []))

    def vec(section: str, key: str, nom: list[float]) -> np.ndarray:
        out = np.array(nom, dtype=float)
        got = data.get(section, {}).get(key)
        if got is None:
            got = np.full(out.shape, np.nan)
        got = np.asarray(got, dtype=float)
        if got.shape != out.shape:
            raise CalibError(f"{path}: [{section}] {key} has {got.size} values, expected {out.size}")
        assumed.extend(f"{section}.{key}[{j + 1}]" for j in np.flatnonzero(~np.isfinite(got)))
        return np.where(np.isfinite(got), got, out)

    fr = nominal["friction"]
    grav = {k: float(v["value"]) for k, v in nominal["gravity_coeffs"].items()}
    for k in grav:
        x = data.get("gravity_coeffs", {}).get(k)
        if x is not None and np.isfinite(float(x)):
            grav[k] = float(x)
        else:
            assumed.append(f"gravity_coeffs.{k}")
    return Fitted(robot=robot,
                  sigma=vec("motors", "torque_sensitivity", nominal["motors"]["torque_sensitivity"]["values"]),
                  **{k: vec("friction", k, fr[k]["values"]) for k in FRICTION_KEYS},
                  gravity_coeffs=grav, source=path or "robot data file", assumed=tuple(assumed))
