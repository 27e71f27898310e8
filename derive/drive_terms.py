"""The drive's terms of the dynamics equation (thesis 4.6) as kernels: the friction f(qd) of
eq. 4.27 and the motors' rotor inertia R qdd, both from the robot data file.

``inverse_dynamics`` stays the rigid body (what Pinocchio's ``rnea`` gives on the shipped
URDF); the joint torque a motor must give is ``inverse_dynamics(q, qd, qdd) +
rotor_torque(qdd) + friction(qd)``.

* ``friction(qd)``: eq. 4.27 with the data file's ``[friction]`` magnitudes (Tables 4.2,
  4.3): f_j = Fc+_j + Fv+_j qd_j for qd_j > 0, -Fc-_j + Fv-_j qd_j for qd_j < 0, and 0 at
  rest (the static friction of a joint at rest is not a function of qd: Table 4.5 bounds it,
  the runtime's stick-slip logic decides it). Written with ``sign`` and ``Max``/``Min`` so
  that it stays straight-line code: Fc+ max(sign qd, 0) - Fc- max(-sign qd, 0) + Fv+ max(qd, 0)
  + Fv- min(qd, 0). The Coulomb step makes it discontinuous at qd = 0, as the model is.
* ``rotor_torque(qdd)``: R qdd with R = G^T diag(J_m) G (``RobotModel.rotor_matrix``: the
  joints' ``rotor_inertia`` turned into J_m per motor and reflected through the gear matrix G
  of eq. 4.28; off-diagonal where a drive couples joints, as the PUMA 260's wrist).
"""
from __future__ import annotations

import numpy as np
import sympy as sp

from derive.kernel import Arg, Kernel


def _number(x: float) -> sp.Expr:
    return sp.Float(float(x), 17) if x else sp.Integer(0)


def _rates(n: int) -> tuple[tuple[sp.Symbol, ...], tuple[sp.Symbol, ...]]:
    """qd1..qdn and qdd1..qddn, the symbols of derive.dynamics (QD, QDD) for an arm of n joints."""
    return sp.symbols(f"qd1:{n + 1}", real=True), sp.symbols(f"qdd1:{n + 1}", real=True)


def friction_kernel(robot: str, model) -> Kernel:
    """``friction(qd) -> f (n,)`` of ``model`` (rcci.models.RobotModel), eq. 4.27 kinetic part."""
    fr = model.friction
    cp, cn = fr.coulomb_pos.values, fr.coulomb_neg.values
    vp, vn = fr.viscous_pos.values, fr.viscous_neg.values
    QD = _rates(model.n_joints)[0]
    f = []
    for j, x in enumerate(QD):
        s = sp.sign(x)
        f.append(_number(cp[j]) * sp.Max(s, 0) - _number(cn[j]) * sp.Max(-s, 0)
                 + _number(vp[j]) * sp.Max(x, 0) + _number(vn[j]) * sp.Min(x, 0))
    return Kernel(robot, "friction", "f(qd): the data file's friction of eq. 4.27 (Coulomb and viscous "
                  "per direction; 0 at rest, where the static friction is the runtime's)",
                  (Arg("qd", sp.Matrix(QD), "joint rates (rad/s; m/s)"),),
                  (Arg("f", sp.Matrix(f), "N m (N on prismatic joints), opposing the motion"),),
                  source="4.27")


def rotor_kernel(robot: str, model) -> Kernel:
    """``rotor_torque(qdd) -> R qdd (n,)`` of ``model``: the reflected rotor inertias' torque."""
    r = np.asarray(model.rotor_matrix(), dtype=float)
    n = r.shape[0]
    QDD = _rates(n)[1]
    tau = sp.Matrix([sum((_number(r[i, j]) * QDD[j] for j in range(n) if r[i, j]), sp.Integer(0))
                     for i in range(n)])
    return Kernel(robot, "rotor_torque", "R qdd: the motors' rotor inertias reflected to the joints, "
                  "R = G^T diag(J_m) G (J_m from the data file's rotor_inertia; not in inverse_dynamics)",
                  (Arg("qdd", sp.Matrix(QDD), "joint accelerations (rad/s^2; m/s^2)"),),
                  (Arg("tau", tau, "N m (N on prismatic joints)"),),
                  source="4.6")


def drive_kernels(robot: str, model) -> list[Kernel]:
    """The friction and rotor kernels of one arm."""
    return [friction_kernel(robot, model), rotor_kernel(robot, model)]
