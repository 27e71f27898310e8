"""The numbers the derivation needs from a robot's model file, and their cross-check.

The symbolic DH tables of ``derive.dh`` fix the structure (which parameters are zero,
the alpha signs, joint kinds); the numbers (a2, d3, d4, gravity, joint ranges) come from
``models/<robot>.toml`` through ``models.load_robot``. Before anything is
emitted, every DH entry of the data file is compared with the symbolic table, so a model
file that disagrees with the derivation stops ``make derive`` with a clear message.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import sympy as sp

from derive.dh import MICROBO, PUMA260, DHRobot, a2, d3, d4
from derive.gravity import g0


@dataclass(frozen=True)
class RobotSpec:
    """A robot as the emitters see it: symbolic table plus the model file's numbers."""

    name: str
    dh: DHRobot
    params: dict[sp.Symbol, float]  # a2, d3, d4, g (SI)
    kinds: tuple[str, ...]
    lower: tuple[float, ...]
    upper: tuple[float, ...]
    config_fields: tuple[str, ...]
    gravity_coeffs: tuple[str, ...]
    model_path: str


def _dh_value(link, field: str, params: dict[sp.Symbol, float]) -> float | None:
    """Numeric value of a DH entry, or None if it is the joint variable."""
    expr = getattr(link, field)
    expr = sp.sympify(expr)
    if expr.free_symbols - set(params):
        return None
    return float(expr.subs(params))


def load_spec(name: str) -> RobotSpec:
    """Read ``models/<name>.toml`` and check it against the symbolic DH table."""
    from models import load_robot

    model = load_robot(name)
    dh = {"puma260": PUMA260, "microbo": MICROBO}[name]
    joints = model.joints
    params: dict[sp.Symbol, float] = {g0: float(model.gravity)}
    if name == "puma260":
        params.update({a2: joints[1].a, d3: joints[2].d, d4: joints[3].d})
    for i, (link, joint) in enumerate(zip(dh.links, joints), start=1):
        kind = "prismatic" if link.prismatic else "revolute"
        if joint.kind != kind:
            raise ValueError(f"{model.path}: joints.{i}.kind: data file says {joint.kind}, "
                             f"the derivation (Table 3.1/3.2) needs {kind}")
        for field in ("a", "alpha", "d", "theta"):
            want = _dh_value(link, field, params)
            got = getattr(joint, field)
            if want is None:  # the joint variable: the data file must have no offset
                if abs(got) > 1e-12:
                    raise ValueError(f"{model.path}: joints.{i}.{field}: offset {got} on the "
                                     "joint variable is not supported by the derivation")
                continue
            if not math.isclose(got, want, rel_tol=1e-12, abs_tol=1e-12):
                raise ValueError(f"{model.path}: joints.{i}.{field}: data file has {got}, "
                                 f"the derivation's table (A matrices 3.4-3.15) needs {want}")
    fields = ("arm", "elbow", "wrist") if name == "puma260" else ("wrist",)
    return RobotSpec(
        name=name, dh=dh, params=params, kinds=tuple(j.kind for j in joints),
        lower=tuple(float(x) for x in model.lower), upper=tuple(float(x) for x in model.upper),
        config_fields=fields, gravity_coeffs=tuple(model.gravity_coeffs),
        model_path=str(model.path),
    )
