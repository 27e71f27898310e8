"""The plug-in point of a redundant (7-joint) arm's inverse kinematics in the derivation.

Paul's method (derive.inverse) solves six joint variables from one pose; a 7-joint arm has
a free parameter (one joint, the Panda's q7, or an arm angle), so ``solve_ik`` returns None
for it and everything else (forward kinematics, the 6 x 7 Jacobians, gravity, dynamics) is
derived as for the 6-joint arms. Its closed-form solver is a separate module,
``derive.inverse_redundant``; when that module exists, its function

    ik_kernels(derivation: derive.kernels.Derivation) -> list[derive.kernel.Kernel]

returns the arm's IK kernels (inputs: the pose T of the last link, ``base_to_link7``, and
the free value; outputs: the joint variables and guards, as the 6-joint ``ik`` kernels),
and build_kernels emits them with the others. Until it exists the generated module has no
``ik`` kernel and its ``ik``/``ik_all``/``config_of`` raise ``KinematicsError`` naming the
missing solver (rccl.kinematics.runtime.Robot): no numerical iteration stands in for it.
"""
from __future__ import annotations

import importlib.util

#: the module that provides a redundant arm's closed-form inverse kinematics
SOLVER_MODULE = "derive.inverse_redundant"


def solver_available() -> bool:
    """True when ``derive.inverse_redundant`` exists (the redundant IK has been written)."""
    return importlib.util.find_spec(SOLVER_MODULE) is not None


def redundant_ik_kernels(derivation) -> list:
    """The redundant arm's IK kernels from ``derive.inverse_redundant.ik_kernels``, or []
    while that solver does not exist."""
    if not solver_available():
        return []
    module = importlib.import_module(SOLVER_MODULE)
    return list(module.ik_kernels(derivation))


def class_reasons(r) -> list[str]:
    """The conditions of the redundant class that the 7-joint table ``r`` fails, from
    ``derive.inverse_redundant.class_reasons`` (empty = its closed form applies); empty while
    that solver does not exist (the generated ``ik`` then raises NoSolver)."""
    if not solver_available():
        return []
    return list(importlib.import_module(SOLVER_MODULE).class_reasons(r))
