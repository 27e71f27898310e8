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
import tomllib
from collections.abc import Mapping
from typing import Any

from calib.errors import CalibError

SCHEMA = "rcci-calib-params/1"


def read_params(path: str) -> dict[str, Any]:
    """A parameter file as a dict; CalibError naming the file when it is not one."""
    try:
        with open(path, "rb") as f:
            data = tomllib.load(f)
    except OSError as exc:
        raise CalibError(f"{path}: cannot read parameter file: {exc.strerror}") from None
    except tomllib.TOMLDecodeError as exc:
        raise CalibError(f"{path}: not a valid TOML parameter file: {exc}") from None
    if data.get("calib", {}).get("schema") != SCHEMA:
        raise CalibError(f"{path}: [calib] schema is {data.get('calib', {}).get('schema')!r}, "
                         f"expected {SCHEMA!r}")
    return data


def update_params(path: str, robot: str, sections: Mapping[str, Mapping[str, Any]],
                  command: str) -> dict[str, Any]:
    """Merge ``sections`` into the file at ``path`` (created if absent), atomically."""
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
    for name, body in sections.items():
        data[name] = dict(body)
    text = ("# Calibration parameters fitted by `calib` (docs/calib.md); rebuilt by the\n"
            "# commands listed in [calib].commands.  SI units: N*m, N*m*s/rad, N*m/A.\n\n"
            + dumps(data))
    _atomic_write(path, text)
    return data


def _atomic_write(path: str, text: str) -> None:
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix=".calib-", suffix=".tmp", dir=folder)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


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
