"""Run the whole derivation for one robot (chapter 3 and section 4.4.1), from its model
file alone: the DH table picks the inverse-kinematics class and the Jacobian's reduction,
the model's gravity grouping (or the minimal identifiable set) the gravity coefficients."""
from __future__ import annotations

from derive.forward import t6
from derive.gravity import gravity_model
from derive.inverse import solve_ik
from derive.jacobian import differential
from derive.kernels import Derivation
from derive.robots import load_spec, robot_names


def parallel_23(dh) -> bool:
    """Joints 2 and 3 revolute with parallel axes (alpha2 = 0): the Jacobian is reduced
    with Y of 3.63 (dq2 + dq3 as one rate), as the PUMA's 4J' (3.62-3.67)."""
    l2, l3 = dh.links[1], dh.links[2]
    return not l2.prismatic and not l3.prismatic and l2.alpha == 0


def derive_robot(name: str) -> Derivation:
    spec = load_spec(name)
    return Derivation(spec, t6(spec.dh), solve_ik(spec.dh),
                      differential(spec.dh, reduce_23=parallel_23(spec.dh)), gravity_model(spec))


__all__ = ["derive_robot", "robot_names"]
