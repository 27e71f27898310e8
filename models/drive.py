"""The friction of a joint drive, thesis eq. 4.27 (Tables 4.2-4.6), in two forms.

* :class:`Friction`: as the robot data file states it, each vector with its source and
  uncertainty (part of :class:`rcci.models.robot.RobotModel`).
* :class:`JointFriction`: the six coefficients as plain SI arrays, the one record every user
  of eq. 4.27 extends: the simulated arm's truth (``rci.simula.params.Truth``), a fit
  (``rcci.calib.params.Fitted``) and the adaptive force model's belief
  (``rccl.adaptive.force.JointModel``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .quantities import Vector

#: the coefficients of eq. 4.27, in the order of the data file and the parameter file
FRICTION_KEYS = ("coulomb_pos", "coulomb_neg", "viscous_pos", "viscous_neg", "static_pos", "static_neg")


@dataclass(frozen=True)
class Friction:
    """Friction model of thesis eq. 4.27, joint level (N*m or N; N*m*s/rad or N*s/m).

    All magnitudes are positive: f = Fc+ + Fv+ qd (qd > 0), f = -Fc- + Fv- qd (qd < 0),
    |f| <= Fs (qd = 0).  The Table 4.6 statistics exist only for the PUMA.
    """

    coulomb_pos: Vector
    coulomb_neg: Vector
    viscous_pos: Vector
    viscous_neg: Vector
    static_pos: Vector
    static_neg: Vector
    variation: Vector | None = None
    static_typical_max: Vector | None = None
    static_typical_min: Vector | None = None
    static_typical_mean: Vector | None = None
    static_typical_std: Vector | None = None


@dataclass(frozen=True)
class JointFriction:
    """The coefficients of eq. 4.27 per joint, SI, all magnitudes positive: Coulomb (N*m or N),
    viscous (N*m*s/rad or N*s/m) and static (N*m or N), for positive and negative motion."""

    coulomb_pos: np.ndarray
    coulomb_neg: np.ndarray
    viscous_pos: np.ndarray
    viscous_neg: np.ndarray
    static_pos: np.ndarray
    static_neg: np.ndarray

    @staticmethod
    def arrays(friction: Friction) -> dict[str, np.ndarray]:
        """The six coefficients of a data file's :class:`Friction` as float arrays, by name
        (keyword arguments for any :class:`JointFriction` record)."""
        return {k: np.array(getattr(friction, k).values, dtype=float) for k in FRICTION_KEYS}
