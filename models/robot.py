"""The robot model record: DH joints, link inertials, motors, conversions, and the whole arm."""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping

import numpy as np

from .drive import Friction
from .quantities import Matrix, Source, Value, Vector

@dataclass(frozen=True)
class Joint:
    """One DH joint (thesis eq. 3.3); lengths in m, angles in rad.

    ``theta`` is the offset added to q for a revolute joint and the fixed angle of a
    prismatic one; ``d`` likewise for prismatic joints.  Limits are on q.
    """

    index: int
    name: str
    kind: str
    a: float
    alpha: float
    d: float
    theta: float
    lower: float
    upper: float
    max_velocity: float
    max_current: float
    max_acceleration: float | None = None  # rad/s^2 or m/s^2, when the data file gives it
    max_jerk: float | None = None          # rad/s^3 or m/s^3
    max_effort: float | None = None        # N*m or N: the published joint torque (force) limit

    @property
    def variable(self) -> str:
        """Which DH parameter moves: ``"theta"`` (revolute) or ``"d"`` (prismatic)."""
        return "theta" if self.kind == "revolute" else "d"

    def dh(self, q: float) -> tuple[float, float, float, float]:
        """(theta, d, a, alpha) at joint value q (rad or m)."""
        if self.kind == "revolute":
            return self.theta + q, self.d, self.a, self.alpha
        return self.theta, self.d + q, self.a, self.alpha

    def transform(self, q: float) -> np.ndarray:
        """A_i(q), the (4, 4) transform from frame i-1 to frame i (thesis eq. 3.3)."""
        theta, d, a, alpha = self.dh(q)
        ct, st, ca, sa = math.cos(theta), math.sin(theta), math.cos(alpha), math.sin(alpha)
        return np.array([
            [ct, -st * ca, st * sa, a * ct],
            [st, ct * ca, -ct * sa, a * st],
            [0.0, sa, ca, d],
            [0.0, 0.0, 0.0, 1.0],
        ])


@dataclass(frozen=True)
class LinkInertial:
    """Mass (kg), centre of mass (m, in DH frame k) and inertia about it (kg m^2, frame-k axes)."""

    index: int
    mass: float
    com: np.ndarray
    inertia: np.ndarray


@dataclass(frozen=True)
class GravityGrouping:
    """How the derivation groups the gravity vector into named coefficients (optional).

    ``com_form[k]``: the centre of mass of link k+1 assumed by the grouping, three SymPy
    expressions in frame k+1 (``"0"``, ``"x2"``, ...), as thesis eq. 4.21; ``meanings``:
    each coefficient of ``gravity_coeffs`` as a SymPy expression in the masses ``m1..m6``,
    the centre-of-mass symbols, ``g`` and the DH lengths (``a2``, ``d4``, ...), as
    eq. 4.24. Without a grouping the derivation finds the minimal identifiable set itself.
    """

    com_form: tuple[tuple[str, str, str], ...]
    meanings: Mapping[str, str]
    source: Source


@dataclass(frozen=True)
class Motors:
    """Motor constants: torque sensitivity sigma_i (eq. 4.3, N*m/A) and Table 4.1 extras."""

    torque_sensitivity: Vector
    torque_sensitivity_std: Vector | None = None
    torque_sensitivity_trials: Vector | None = None
    torque_sensitivity_manufacturer: Vector | None = None


@dataclass(frozen=True)
class Conversion:
    """Joint <-> motor <-> sensor conversions of thesis 4.4.3 (eqs. 4.28-4.38), Appendix D.

    ``gear_ratio`` G: motor angle = G q (4.28); ``encoder_ratio`` R: counts = R q (+
    ``encoder_offset``) (4.30) as printed; ``encoder_ratio_consistent``: R rebuilt as
    diag(counts per motor radian) G where the print is inconsistent (PUMA r65);
    ``adc_volts_per_count`` V_g, ``sense_resistance`` R_i, ``kappa`` kappa_i (4.32, 4.34).
    """

    gear_ratio: Matrix
    encoder_ratio: Matrix
    encoder_counts_per_motor_rev: Vector
    encoder_offset: Vector
    adc_volts_per_count: Value
    sense_resistance: Vector
    kappa: Vector
    encoder_ratio_consistent: Matrix | None = None


@dataclass(frozen=True)
class RobotModel:
    """One robot, SI units throughout.  Arrays are read-only."""

    name: str
    title: str
    path: Path
    urdf_path: Path
    n_joints: int
    joints: tuple[Joint, ...]
    lower: np.ndarray
    upper: np.ndarray
    max_velocity: np.ndarray
    max_current: np.ndarray
    gravity: float
    poses: Mapping[str, np.ndarray]
    links: tuple[LinkInertial, ...]
    gravity_coeffs: Mapping[str, Value]
    gravity_friction_error: Vector | None
    friction: Friction
    motors: Motors
    conversion: Conversion
    sources: Mapping[str, Source]
    gravity_grouping: "GravityGrouping | None" = None
    #: "standard" (thesis eq. 3.3) or "modified" (Craig): the convention of the data file's
    #: table; ``joints`` always hold the standard table (rcci.models.modified_dh)
    dh_convention: str = "standard"
    #: (n, 4, 4): standard frame k expressed in the data file's frame k (identity for a
    #: standard table; Craig's frame k for a modified one): links and shapes given in the
    #: data file's frames are moved by it
    data_frames: np.ndarray | None = None
    #: per-joint acceleration, jerk and effort limits (SI), or None when the file has none
    max_acceleration: np.ndarray | None = None
    max_jerk: np.ndarray | None = None
    max_effort: np.ndarray | None = None

    @property
    def kinds(self) -> tuple[str, ...]:
        """Joint kinds in order, ``"revolute"`` or ``"prismatic"``."""
        return tuple(j.kind for j in self.joints)

    def source(self, field: str) -> Source:
        """The source of a value, by dotted path: ``"joints.3.d"``, ``"robot.gravity"``,
        ``"links.6.com"``, ``"poses.ready"``, ``"gravity_coeffs.c12"``,
        ``"friction.coulomb_pos"`` (a trailing entry number, ``"friction.coulomb_pos.2"``,
        gives the source of the whole vector)."""
        if field in self.sources:
            return self.sources[field]
        head, _, tail = field.rpartition(".")
        if tail.isdigit() and head in self.sources:
            return self.sources[head]
        raise KeyError(f"{self.name}: no value {field!r}; known fields include "
                       f"{', '.join(sorted(self.sources)[:8])}, ...")

    def base_to_link(self, q: np.ndarray) -> np.ndarray:
        """T_1..T_n (thesis eq. 4.9) from the DH table: (n, 4, 4), frame k in the base frame."""
        q = np.asarray(q, dtype=float)
        if q.shape != (self.n_joints,):
            raise ValueError(f"{self.name}: q must have shape ({self.n_joints},), got {q.shape}")
        out = np.empty((self.n_joints, 4, 4))
        base_to_k = np.eye(4)
        for k, joint in enumerate(self.joints):
            base_to_k = base_to_k @ joint.transform(float(q[k]))
            out[k] = base_to_k
        return out

    def within_limits(self, q: np.ndarray) -> bool:
        """True when every joint value lies in [lower, upper]."""
        q = np.asarray(q, dtype=float)
        return bool(np.all(q >= self.lower) and np.all(q <= self.upper))
