"""Specification strings of limit/comply/lock (thesis 5.4.1, 5.4.3): tool-frame component names and values.

Components are tool-frame quantities, one token each, separated by blanks or commas:

    forces       fx fy fz   (N, exerted by the tool on the world)
    torques      mx my mz   (N*m; tx ty tz are accepted as the same)
    deviations   dx dy dz   (m, measured path minus planned path)
    rotations    rx ry rz   (rad, idem)

``limit("fz dx", 10.0, 0.005)`` parses to {("force", 2): 10.0, ("dev", 0): 0.005}.
"""
from __future__ import annotations

import math
from typing import Iterable

from .exceptions import SpecError

_FORCE = {"fx": 0, "fy": 1, "fz": 2, "mx": 3, "my": 4, "mz": 5, "tx": 3, "ty": 4, "tz": 5}
_DEV = {"dx": 0, "dy": 1, "dz": 2, "rx": 3, "ry": 4, "rz": 5}
NAMES = ("x", "y", "z", "rot x", "rot y", "rot z")
FORCE_NAMES = ("fx", "fy", "fz", "mx", "my", "mz")
DEV_NAMES = ("dx", "dy", "dz", "rx", "ry", "rz")


def tokens(spec: str, where: str) -> list[str]:
    """The component tokens of ``spec`` (lower case); SpecError if it is not a non-empty string."""
    if not isinstance(spec, str):
        raise SpecError(f"{where}: the specification must be a string such as \"fz dx\", got {spec!r}")
    toks = spec.replace(",", " ").lower().split()
    if not toks:
        raise SpecError(f"{where}: empty specification string")
    return toks


def component(tok: str, where: str, allow_dev: bool = True) -> tuple[str, int]:
    """("force", index) or ("dev", index) of one token."""
    if tok in _FORCE:
        return "force", _FORCE[tok]
    if allow_dev and tok in _DEV:
        return "dev", _DEV[tok]
    known = "fx fy fz mx my mz" + (" dx dy dz rx ry rz" if allow_dev else "")
    raise SpecError(f"{where}: {tok!r} is not a tool-frame component ({known})")


def parse(spec: str, values: Iterable[float], where: str, *, allow_dev: bool = True,
          positive: bool = True) -> dict[tuple[str, int], float]:
    """Map each component of ``spec`` to its value; one finite value per token, positive if asked."""
    toks = tokens(spec, where)
    vals = list(values)
    if len(vals) != len(toks):
        raise SpecError(f"{where}: {len(toks)} component(s) in {spec!r} but {len(vals)} value(s)")
    out: dict[tuple[str, int], float] = {}
    for tok, v in zip(toks, vals):
        key = component(tok, where, allow_dev)
        if key in out:
            raise SpecError(f"{where}: {tok!r} is given twice in {spec!r}")
        try:
            x = float(v)
        except (TypeError, ValueError):
            raise SpecError(f"{where}: value {v!r} for {tok!r} is not a number") from None
        if not math.isfinite(x) or (positive and x <= 0):
            need = "a positive finite" if positive else "a finite"
            raise SpecError(f"{where}: value {v!r} for {tok!r} must be {need} number (SI units)")
        out[key] = x
    return out
