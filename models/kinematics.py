"""The kinematics contract: what every generated kinematics module of a robot provides.

``derive`` writes one module per robot (``rccl/kinematics/<robot>.py``, plus C and CasADi
versions) and ``rccl.kinematics`` runs them; both sides import this module, so the names
and errors they agree on are written once. Units are SI (rad, m, N, N m); a pose is a 4x4
homogeneous transform of link 6 in the base frame (thesis eq. 3.16-3.18); ``n`` is the
robot's number of joints (6 for the thesis's arms; 7 for a redundant arm such as the Panda,
whose "T6" is its last link frame, link 7, and whose "frame 6" in the Jacobian functions is
that last frame), ``k`` its number of gravity coefficients. Every function taking ``q`` also
takes a batch ``(N, n)`` and then returns ``(N, ...)``.

A redundant arm (n = 7): ``jacobian4``/``jacobian6`` are 6 x 7; ``joint_from_cartesian`` is
the minimum-norm solution dq = J^+ dc (exact where J has rank 6) and ``force_from_torque``
the least-squares f = (J^T)^+ tau, both raising ``Singular`` where J loses rank
(rccl/kinematics/redundant.py). Its ``ik``/``ik_all`` come from a closed-form solver with
a free parameter (derive/redundant.py is the plug-in point); until it exists they raise
``NoSolver`` (a KinematicsError and NotImplementedError) naming it, and ``config_of``
returns the single record ``NoConfig()``.
"""
from __future__ import annotations

from typing import Mapping

#: the public functions of a generated module, in the order the module binds them, with
#: (arguments, result shape for one configuration)
FUNCTIONS: Mapping[str, tuple[str, str]] = {
    "fk": ("q (n,)", "(4, 4) T6"),
    "ik": ("T (4, 4), config, q_ref (n,) | None", "(n,) q"),
    "ik_all": ("T (4, 4), q_ref (n,) | None", "list of (config, (n,) q)"),
    "config_of": ("q (n,)", "config"),
    "jacobian4": ("q (n,)", "(6, n) 4J, frame 4 (eq. 3.54-3.61)"),
    "jacobian6": ("q (n,)", "(6, n) 6J, frame 6"),
    "cartesian_from_joint": ("q (n,), dq (n,), frame 4 | 6", "(6,) dc (eq. 3.71, 3.75)"),
    "torque_from_force": ("q (n,), f (6,), frame 4 | 6", "(n,) tau (eq. 3.72, 3.76)"),
    "joint_from_cartesian": ("q (n,), dc (6,), frame 4 | 6", "(n,) dq (eq. 3.73, 3.77)"),
    "force_from_torque": ("q (n,), tau (n,), frame 4 | 6", "(6,) f (eq. 3.74, 3.78)"),
    "gravity": ("q (n,), coeffs (k,) | mapping", "(n,) tau (eq. 4.24)"),
    "gravity_regressor": ("q (n,)", "(n, k) Y, gravity = Y coeffs"),
    "gravity_links": ("q (n,), masses (n,), coms (n, 3)", "(n,) tau (eq. 4.20)"),
    "coefficients_from_links": ("masses (n,), coms (n, 3)", "dict of k coefficients"),
    "tool_load": ("coeffs, mass, com", "dict of k coefficients (eq. 4.26)"),
}

#: the public function names, in binding order
PUBLIC: tuple[str, ...] = tuple(FUNCTIONS)

#: a redundant 7-joint arm (the Panda) names its free parameter: the value of joint 7, q7
#: (rad). Its inverse (derive.inverse_redundant; runtime rccl.kinematics.redundant_ik) takes
#: the pose T of the flange (frame 7) and q7; config has the fields shoulder, elbow, wrist;
#: every returned q reproduces T and lies in the joint ranges
REDUNDANT: Mapping[str, tuple[str, str]] = {
    "ik": ("T (4, 4), config, q_ref (7,) | None, q7 (keyword, rad)", "(7,) q"),
    "ik_all": ("T (4, 4), q7 (rad), q_ref (7,) | None", "list of (config, (7,) q), every solution for that q7"),
}

#: the dynamics (thesis eq. 4.6, ``derive.dynamics``) of a generated module, bound after the
#: functions above; ``b`` is the robot's number of base parameters (``BASE_PARAMETERS``)
DYNAMICS: Mapping[str, tuple[str, str]] = {
    "inverse_dynamics": ("q (n,), qd (n,), qdd (n,)", "(n,) t_j = D qdd + c + t_g, data-file inertials"),
    "inertia_matrix": ("q (n,)", "(n, n) D, symmetric positive definite"),
    "coriolis": ("q (n,), qd (n,)", "(n,) c, Coriolis and centrifugal torques"),
    "coriolis_matrix": ("q (n,), qd (n,)", "(n, n) C, c = C qd, D' - 2C skew-symmetric"),
    "base_regressor": ("q (n,), qd (n,), qdd (n,)", "(n, b) Y, t_j = Y beta (rotor inertias included)"),
    "base_parameters": ("m (n,), com (n, 3), inertia (n, 6), rotor (n,)", "(b,) beta"),
}


class KinematicsError(ValueError):
    """Base class: the input lies outside the domain of a kinematic function."""


class Unreachable(KinematicsError):
    """No joint configuration reaches the pose (out of reach or outside a joint range)."""


class Singular(KinematicsError):
    """The configuration is singular: the solution is not unique or does not exist."""


class InvalidInput(KinematicsError):
    """An argument has the wrong shape, is not finite, or is not a rigid transform."""


class NoSolver(KinematicsError, NotImplementedError):
    """The arm's inverse kinematics has not been derived (a redundant arm before its
    closed-form solver exists: derive/redundant.py)."""


#: the error names a generated guard may raise (``GuardInfo.error``), by class
ERRORS: Mapping[str, type[KinematicsError]] = {
    "Unreachable": Unreachable, "Singular": Singular, "InvalidInput": InvalidInput,
}
