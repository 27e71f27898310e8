"""The numbers and structure the derivation needs from a robot's model file.

Everything comes from ``models/<robot>.toml`` through ``rcci.models.load_robot``: the DH table
(``derive.dh.dh_from_model``: fixed lengths become symbols such as a2, d3, substituted only
when code is emitted), joint kinds and ranges, gravity, and the optional gravity grouping
(centre-of-mass form and coefficient meanings, as thesis eqs. 4.21 and 4.24). No robot is
known by name: a new arm is a model file (and its URDF) under models/.
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from derive.dh import DHRobot, dh_from_model
from derive.gravity import g0
from derive.inverse import class_reasons

#: the configuration signs of each inverse-kinematics class
CONFIG_FIELDS = {"articulated (PUMA class)": ("arm", "elbow", "wrist"),
                 "cylindrical (Microbo class)": ("wrist",),
                 "spherical (Stanford class)": ("arm", "boom", "wrist"),
                 "redundant (7 joints)": ("shoulder", "elbow", "wrist")}  # derive.inverse_redundant


@dataclass(frozen=True)
class RobotSpec:
    """A robot as the emitters see it: symbolic table plus the model file's numbers."""

    name: str
    dh: DHRobot
    params: dict[sp.Symbol, float]  # the table's length symbols and g (SI)
    kinds: tuple[str, ...]
    lower: tuple[float, ...]
    upper: tuple[float, ...]
    config_fields: tuple[str, ...]
    gravity_coeffs: tuple[str, ...]
    model_path: str
    com_form: tuple[tuple[str, str, str], ...] | None = None  # eq. 4.21-style assumptions
    meanings: tuple[tuple[str, str], ...] | None = None  # (coefficient, expression), eq. 4.24
    thesis: bool = False  # the DH table is the thesis's (Table 3.1 / 3.2): audit against the print


def robot_names() -> tuple[str, ...]:
    """Every robot with a data file under models/ (``rcci.models.available_robots``)."""
    from rcci.models import available_robots

    return tuple(available_robots())


def load_spec(name: str) -> RobotSpec:
    """Read ``models/<name>.toml`` into the derivation's view of the robot."""
    from rcci.models import load_robot

    model = load_robot(name)
    dh, lengths = dh_from_model(model)
    params: dict[sp.Symbol, float] = {g0: float(model.gravity), **lengths}
    fields = ()
    for cls, reasons in class_reasons(dh).items():
        if not reasons:
            fields = CONFIG_FIELDS[cls]
            break
    grouping = model.gravity_grouping
    thesis = all(model.source(f"joints.{j.index}.{f}").tag.startswith("thesis ")
                 for j in model.joints for f in ("a", "alpha", "d"))
    return RobotSpec(
        name=name, dh=dh, params=params, kinds=tuple(j.kind for j in model.joints),
        lower=tuple(float(x) for x in model.lower), upper=tuple(float(x) for x in model.upper),
        config_fields=fields, gravity_coeffs=tuple(model.gravity_coeffs),
        model_path=str(model.path),
        com_form=grouping.com_form if grouping else None,
        meanings=tuple(grouping.meanings.items()) if grouping else None,
        thesis=thesis,
    )
