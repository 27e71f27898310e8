"""Run the whole derivation for one robot (chapter 3 and section 4.4.1)."""
from __future__ import annotations

from derive.forward import t6
from derive.gravity import microbo_gravity, puma_gravity
from derive.inverse import microbo_ik, puma_ik
from derive.jacobian import differential
from derive.kernels import Derivation
from derive.robots import load_spec

ROBOT_NAMES = ("puma260", "microbo")


def derive_robot(name: str) -> Derivation:
    spec = load_spec(name)
    if name == "puma260":
        return Derivation(spec, t6(spec.dh), puma_ik(), differential(spec.dh, reduce_23=True), puma_gravity())
    return Derivation(spec, t6(spec.dh), microbo_ik(), differential(spec.dh, reduce_23=False), microbo_gravity())
