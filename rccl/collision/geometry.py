"""An arm's collision geometry file (models/collision/<robot>.toml): capsules on link frames, allowed pairs.

The file holds, for one robot:

* ``[[capsules]]``: ``name``, ``frame`` (a link of the robot's URDF, e.g. "link3" or
  "upper_arm"), end points ``a`` and ``b`` (3-vectors in that frame) and ``radius``, each a
  quantity table ``{ value = ..., unit = "m" or "mm", source = "...", why = "..." }`` in
  the data files' style: ``source`` is where the number comes from (the URDF's visual
  geometry it encloses, a published figure) or ``"estimate"`` with a ``why``;
* ``[[boxes]]``: ``name``, ``frame``, ``center`` (3-vector in that frame) and ``size`` (the
  full edge lengths along the frame's x, y, z), for flat parts a capsule fits badly (a base
  plate);
* ``[[allowed]]``: ``pair = ["frame or capsule", "frame or capsule"]`` and ``why``: pairs
  that may touch (adjacent links at their joint, parts that overlap by construction). Two
  capsules on one rigid body (the same joint) are never checked against each other.

``load_geometry(path)`` reads and checks the file; every problem raises a
``CollisionFileError`` naming the file and the key. Lengths come back in m.
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..exceptions import CollisionFileError

_UNITS = {"m": 1.0, "mm": 1e-3}


@dataclass(frozen=True)
class Capsule:
    """A capsule on one link frame: the segment a-b (m, in ``frame``) swept by a sphere of ``radius`` (m)."""

    name: str
    frame: str
    a: np.ndarray
    b: np.ndarray
    radius: float


@dataclass(frozen=True)
class LinkBox:
    """A box on one link frame, its edges along the frame's axes: ``center`` and full edge lengths ``size`` (m)."""

    name: str
    frame: str
    center: np.ndarray
    size: np.ndarray


@dataclass(frozen=True)
class CollisionGeometry:
    """One robot's capsules and boxes, and the pairs allowed to touch (each pair a frozenset of two names)."""

    robot: str
    path: Path
    capsules: tuple[Capsule, ...]
    boxes: tuple[LinkBox, ...]
    allowed: tuple[frozenset, ...]
    reasons: dict


def geometry_path(robot: str) -> Path:
    """The shipped geometry file of ``robot`` (models/collision/<robot>.toml, beside the robot data files)."""
    import rcci.models

    return Path(rcci.models.__file__).resolve().parent / "collision" / f"{robot}.toml"


def _fail(path: Path, key: str, what: str) -> CollisionFileError:
    return CollisionFileError(f"{path}: {key}: {what}")


def _quantity(path: Path, key: str, table, shape: tuple[int, ...]) -> np.ndarray:
    """A quantity table's value in m (a number or a 3-vector), with its unit and source checked."""
    if not isinstance(table, dict):
        raise _fail(path, key, "must be a table { value = ..., unit = \"m\", source = \"...\" }")
    for must in ("value", "unit", "source"):
        if must not in table:
            raise _fail(path, key, f"has no {must!r}")
    unit = table["unit"]
    if unit not in _UNITS:
        raise _fail(path, key, f"unit {unit!r} is not one of {sorted(_UNITS)}")
    if table["source"] == "estimate" and not str(table.get("why", "")).strip():
        raise _fail(path, key, "an estimate needs a 'why'")
    try:
        value = np.asarray(table["value"], dtype=float) * _UNITS[unit]
    except (TypeError, ValueError):
        raise _fail(path, key, f"value {table['value']!r} is not a number or a list of numbers") from None
    if value.shape != shape or not np.all(np.isfinite(value)):
        want = "a number" if shape == () else f"{shape[0]} numbers"
        raise _fail(path, key, f"value {table['value']!r} must be {want}, finite")
    return value


def _named(path: Path, where: str, entry, keys: tuple[str, ...]) -> tuple[str, str]:
    """(name, frame) of a shape table that must hold ``keys``."""
    if not isinstance(entry, dict):
        raise _fail(path, where, "must be a table")
    for must in ("name", "frame", *keys):
        if must not in entry:
            raise _fail(path, f"{where}.{must}", "missing")
    name, frame = entry["name"], entry["frame"]
    if not (isinstance(name, str) and name.strip()) or not (isinstance(frame, str) and frame.strip()):
        raise _fail(path, f"{where}.name/frame", "must be non-empty strings")
    return name, frame


def _box(path: Path, i: int, entry) -> LinkBox:
    where = f"boxes[{i}]"
    name, frame = _named(path, where, entry, ("center", "size"))
    center = _quantity(path, f"{where}.center ({name})", entry["center"], (3,))
    size = _quantity(path, f"{where}.size ({name})", entry["size"], (3,))
    if not np.all(size > 0):
        raise _fail(path, f"{where}.size ({name})", f"{size.tolist()} m must all be > 0")
    return LinkBox(name, frame, center, size)


def _capsule(path: Path, i: int, entry) -> Capsule:
    where = f"capsules[{i}]"
    name, frame = _named(path, where, entry, ("a", "b", "radius"))
    radius = float(_quantity(path, f"{where}.radius ({name})", entry["radius"], ()))
    if not radius > 0:
        raise _fail(path, f"{where}.radius ({name})", f"{radius} m must be > 0")
    a = _quantity(path, f"{where}.a ({name})", entry["a"], (3,))
    b = _quantity(path, f"{where}.b ({name})", entry["b"], (3,))
    return Capsule(name, frame, a, b, radius)


def parse_geometry(data: dict, path: Path) -> CollisionGeometry:
    """A CollisionGeometry from a file's parsed TOML ``data`` (``path`` for the messages)."""
    head = data.get("collision")
    if not isinstance(head, dict) or not isinstance(head.get("robot"), str):
        raise _fail(path, "collision.robot", "missing: the file starts with [collision] robot = \"<name>\"")
    entries = data.get("capsules")
    if not isinstance(entries, list) or not entries:
        raise _fail(path, "capsules", "missing or empty: give at least one [[capsules]] table")
    capsules = tuple(_capsule(path, i, e) for i, e in enumerate(entries))
    box_entries = data.get("boxes", [])
    if not isinstance(box_entries, list):
        raise _fail(path, "boxes", "must be an array of [[boxes]] tables")
    boxes = tuple(_box(path, i, e) for i, e in enumerate(box_entries))
    names = [c.name for c in capsules] + [b.name for b in boxes]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise _fail(path, "capsules/boxes name", f"{dup} appear more than once")
    known = set(names) | {c.frame for c in capsules + boxes}
    allowed, reasons = [], {}
    allowed_entries = data.get("allowed", [])
    if not isinstance(allowed_entries, list):
        raise _fail(path, "allowed", "must be an array of [[allowed]] tables")
    for i, entry in enumerate(allowed_entries):
        where = f"allowed[{i}]"
        pair = entry.get("pair") if isinstance(entry, dict) else None
        if not (isinstance(pair, list) and len(pair) == 2 and all(isinstance(p, str) for p in pair)):
            raise _fail(path, f"{where}.pair", f"{pair!r} must be two capsule or frame names")
        unknown = [p for p in pair if p not in known]
        if unknown:
            raise _fail(path, f"{where}.pair", f"{unknown} name no capsule or frame of this file")
        why = entry.get("why")
        if not (isinstance(why, str) and why.strip()):
            raise _fail(path, f"{where}.why", f"pair {pair} needs the reason it may touch")
        key = frozenset(pair)
        allowed.append(key)
        reasons[key] = why
    return CollisionGeometry(head["robot"], path, capsules, boxes, tuple(allowed), reasons)


def load_geometry(path: str | Path) -> CollisionGeometry:
    """Read and check a collision geometry file; CollisionFileError names the file and key of a problem."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise CollisionFileError(f"{path}: no such collision geometry file") from None
    except tomllib.TOMLDecodeError as exc:
        raise CollisionFileError(f"{path}: not valid TOML: {exc}") from None
    return parse_geometry(data, path)


def segment_length(c: Capsule) -> float:
    """Length (m) of a capsule's segment."""
    return math.dist(c.a.tolist(), c.b.tolist())
