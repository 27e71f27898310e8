"""Homogeneous transforms: RCCL's TRSF (thesis 1.4.1, 5.3.1) and the differential/force maps of 1.4.2-1.4.4.

A ``Trsf`` is a named 4x4 homogeneous transform (columns n, o, a, p; metres) with a *kind*
that tells the trajectory generator how to read it while a motion that uses it runs:

- ``const``: fixed once built; writing to it raises ``ConstTransformError``.
- ``variable``: the planning level may change it at any time; the generator reads it
  at every sample, so changing it moves every position that contains it.
- ``hold``: the value is frozen into the motion request when ``move()`` queues it;
  later changes affect later requests only.
- ``functional``: a function ``fn(trsf)`` bound to it is called by the generator once
  per sample (at the control level) while a motion to a position containing it runs
  (thesis 5.4.4); the function updates the transform in place.

``T6`` is the manipulator's special transform (link 6 in the base frame, thesis 3.3): it
marks the unknown in a position equation and is never written by the user.

Pure helpers work on plain (4,4) arrays: ``trsl``, ``rot``, ``rpy``, ``euler``, ``noap``,
``inverse``, ``to_rpy``, ``to_euler``, ``axis_angle``, the differential matrix (1.8),
the differential map D (1.13) and the force map F (1.22-1.23).
"""
from __future__ import annotations

import math
from typing import Callable, Iterable

import numpy as np

from .exceptions import ConstTransformError, TransformError

KINDS = ("const", "variable", "hold", "functional")
AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}
# Thesis names of the unit axes (RCCL's xunit, yunit, zunit).
xunit = np.array(AXES["x"])
yunit = np.array(AXES["y"])
zunit = np.array(AXES["z"])


# --------------------------------------------------------------------------------------
# plain-array constructors
# --------------------------------------------------------------------------------------
def trsl(x: float, y: float, z: float) -> np.ndarray:
    """Pure translation by (x, y, z) metres."""
    t = np.eye(4)
    t[0, 3], t[1, 3], t[2, 3] = x, y, z
    return t


def _unit_axis(axis) -> np.ndarray:
    if isinstance(axis, str):
        if axis.lower() not in AXES:
            raise TransformError(f"rotation axis {axis!r}: expected 'x', 'y', 'z' or a 3-vector")
        return np.array(AXES[axis.lower()])
    k = np.asarray(axis, dtype=float).reshape(-1)
    if k.shape != (3,) or not np.all(np.isfinite(k)):
        raise TransformError(f"rotation axis {axis!r}: expected a finite 3-vector")
    norm = float(np.linalg.norm(k))
    if norm < 1e-12:
        raise TransformError(f"rotation axis {axis!r} has zero length")
    return k / norm


def rot_matrix(axis, angle: float) -> np.ndarray:
    """3x3 rotation by ``angle`` radians about ``axis`` ('x'/'y'/'z' or a 3-vector), Rodrigues' formula."""
    kx, ky, kz = _unit_axis(axis)
    c, s = math.cos(angle), math.sin(angle)
    v = 1.0 - c
    return np.array([
        [kx * kx * v + c, kx * ky * v - kz * s, kx * kz * v + ky * s],
        [kx * ky * v + kz * s, ky * ky * v + c, ky * kz * v - kx * s],
        [kx * kz * v - ky * s, ky * kz * v + kx * s, kz * kz * v + c],
    ])


def rot(axis, angle: float) -> np.ndarray:
    """Pure rotation by ``angle`` radians about ``axis`` through the origin."""
    t = np.eye(4)
    t[:3, :3] = rot_matrix(axis, angle)
    return t


def rpy(yaw: float, pitch: float, roll: float) -> np.ndarray:
    """Yaw-pitch-roll (thesis 1.4.1): rotations about x, y, z of the original frame, in that order.

    Rotations about fixed axes compose by premultiplying: R = Rz(roll) Ry(pitch) Rx(yaw).
    """
    return rot("z", roll) @ rot("y", pitch) @ rot("x", yaw)


def euler(phi: float, theta: float, psi: float) -> np.ndarray:
    """Euler angles (Paul 81, 2.4): rotate phi about z, then theta about the new y, then psi about the new z."""
    return rot("z", phi) @ rot("y", theta) @ rot("z", psi)


def noap(n, o, a, p) -> np.ndarray:
    """Transform from its column vectors n, o, a (unit, orthogonal, right-handed) and p (metres)."""
    t = np.eye(4)
    t[:3, 0], t[:3, 1], t[:3, 2], t[:3, 3] = n, o, a, p
    check_rigid(t, "noap")
    return t


def check_rigid(t: np.ndarray, where: str, tol: float = 1e-6) -> None:
    """Raise ``TransformError`` unless ``t`` is a finite 4x4 rigid transform (orthonormal, det +1)."""
    t = np.asarray(t, dtype=float)
    if t.shape != (4, 4):
        raise TransformError(f"{where}: expected a 4x4 transform, got shape {t.shape}")
    if not np.all(np.isfinite(t)):
        raise TransformError(f"{where}: transform holds NaN or inf:\n{t}")
    r = t[:3, :3]
    err = float(np.max(np.abs(r.T @ r - np.eye(3))))
    if err > tol or float(np.linalg.det(r)) < 0 or np.any(np.abs(t[3] - (0, 0, 0, 1)) > tol):
        raise TransformError(f"{where}: not a rigid transform (orthonormality error {err:.2e}):\n{t}")


def inverse(t: np.ndarray) -> np.ndarray:
    """Inverse of a rigid transform: (R, p)^-1 = (R^T, -R^T p)."""
    out = np.empty((4, 4))
    rt = out[:3, :3] = t[:3, :3].T
    out[:3, 3] = -(rt @ t[:3, 3])
    out[3] = (0.0, 0.0, 0.0, 1.0)
    return out


def to_rpy(t: np.ndarray) -> tuple[float, float, float]:
    """(yaw, pitch, roll) radians with ``rpy(*to_rpy(t))`` equal to t's rotation (pitch in [-pi/2, pi/2])."""
    r = np.asarray(t)[:3, :3]
    pitch = math.atan2(-r[2, 0], math.hypot(r[0, 0], r[1, 0]))
    if math.hypot(r[0, 0], r[1, 0]) < 1e-12:  # gimbal lock: only yaw -/+ roll is defined; put it in yaw
        return math.atan2(math.copysign(1.0, pitch) * r[0, 1], r[1, 1]), pitch, 0.0
    roll = math.atan2(r[1, 0], r[0, 0])
    yaw = math.atan2(r[2, 1], r[2, 2])
    return yaw, pitch, roll


def to_euler(t: np.ndarray) -> tuple[float, float, float]:
    """(phi, theta, psi) radians with ``euler(*to_euler(t))`` equal to t's rotation (theta in [0, pi])."""
    r = np.asarray(t)[:3, :3]
    st = math.hypot(r[0, 2], r[1, 2])
    theta = math.atan2(st, r[2, 2])
    if st < 1e-12:  # a parallel to z: only phi + psi (or phi - psi) is defined; put it all in psi
        psi = math.atan2(r[1, 0], r[0, 0]) if r[2, 2] > 0 else math.atan2(-r[1, 0], -r[0, 0])
        return 0.0, theta, psi
    phi = math.atan2(r[1, 2], r[0, 2])
    psi = math.atan2(r[2, 1], -r[2, 0])
    return phi, theta, psi


def axis_angle(r: np.ndarray) -> tuple[np.ndarray, float]:
    """Unit axis k and angle in [0, pi] of a rotation matrix (3x3 or the rotation of a 4x4).

    For angle 0 the axis is z (any axis would do). Near pi the axis comes from the
    symmetric part, which is well conditioned there.
    """
    r = np.asarray(r)[:3, :3]
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = r.tolist()   # floats: this runs at segment starts
    c = max(-1.0, min(1.0, (r00 + r11 + r22 - 1.0) / 2.0))
    wx, wy, wz = r21 - r12, r02 - r20, r10 - r01
    s = 0.5 * math.sqrt(wx * wx + wy * wy + wz * wz)
    angle = math.atan2(s, c)
    if angle < 1e-12:
        return zunit.copy(), 0.0
    if angle < math.pi - 1e-4:
        return np.array([wx, wy, wz]) / (2.0 * s), angle
    w = np.array([wx, wy, wz])
    # near pi: R ~ 2kk^T - I; take the best-conditioned column of (R + I) / 2
    b = (r + np.eye(3)) / 2.0
    i = int(np.argmax(np.diag(b)))
    k = b[:, i] / math.sqrt(max(b[i, i], 1e-300))
    if float(np.dot(k, w)) < 0:  # keep the sign consistent with the skew part
        k = -k
    return k / np.linalg.norm(k), angle


# --------------------------------------------------------------------------------------
# differential changes and forces (thesis 1.4.2-1.4.4)
# --------------------------------------------------------------------------------------
def delta_matrix(dc) -> np.ndarray:
    """Differential matrix Delta (1.8) of dc = (dx, dy, dz, dx_rot, dy_rot, dz_rot); dC = C Delta (1.7)."""
    dx, dy, dz, rx, ry, rz = (float(v) for v in dc)
    return np.array([[0.0, -rz, ry, dx], [rz, 0.0, -rx, dy], [-ry, rx, 0.0, dz], [0.0, 0.0, 0.0, 0.0]])


def delta_vector(delta: np.ndarray) -> np.ndarray:
    """dc from a differential matrix (inverse of ``delta_matrix``)."""
    return np.array([delta[0, 3], delta[1, 3], delta[2, 3], delta[2, 1], delta[0, 2], delta[1, 0]])


def diff_map(base_to_x: np.ndarray) -> np.ndarray:
    """D (1.13): maps a differential change vector seen in frame O to the same change seen in frame X.

    ``base_to_x`` is the transform from O to X (columns n, o, a, p). The print of (1.13)
    lost its cross products and a sign (it reads "(p . n)" and "-o_y"); the derivation
    from (1.12) gives, row-wise, [n^T, (p x n)^T], [o^T, (p x o)^T], [a^T, (p x a)^T],
    [0, n^T], [0, o^T], [0, a^T] (Paul 81, 4.6), which is what is built here.
    """
    r = base_to_x[:3, :3]
    p = base_to_x[:3, 3]
    d = np.zeros((6, 6))
    d[:3, :3] = r.T
    d[3:, 3:] = r.T
    d[:3, 3:] = np.cross(p, r.T).reshape(3, 3)  # row i: p x (column i of R)
    return d


def force_map(base_to_x: np.ndarray) -> np.ndarray:
    """F (1.22-1.23) = D^-T: maps a force vector (fx, fy, fz, mx, my, mz) seen in O to the same force seen in X."""
    r = base_to_x[:3, :3]
    p = base_to_x[:3, 3]
    f = np.zeros((6, 6))
    f[:3, :3] = r.T
    f[3:, 3:] = r.T
    f[3:, :3] = np.cross(p, r.T).reshape(3, 3)
    return f


# --------------------------------------------------------------------------------------
# TRSF: a named transform with a kind
# --------------------------------------------------------------------------------------
class Trsf:
    """RCCL's TRSF: a named homogeneous transform (metres) with a kind (const/variable/hold/functional).

    The value is replaced, never mutated in place, by every setter, so the control level
    always reads a consistent matrix even while the planning level writes.
    """

    __slots__ = ("name", "_kind", "_m", "fn")

    def __init__(self, name: str, matrix=None, kind: str = "const",
                 fn: Callable[["Trsf"], None] | None = None) -> None:
        if kind not in KINDS:
            raise TransformError(f"transform {name!r}: kind {kind!r} is not one of {KINDS}")
        if kind == "functional" and fn is None:
            raise TransformError(f"transform {name!r}: a functional transform needs fn")
        m = np.eye(4) if matrix is None else np.array(matrix, dtype=float)
        check_rigid(m, f"transform {name!r}")
        self.name = name
        self._kind = kind
        self._m = m
        self.fn = fn

    # -- constructors in the thesis's gentr_* spirit ----------------------------------
    @classmethod
    def trsl(cls, name: str, x: float, y: float, z: float, kind: str = "const") -> "Trsf":
        """``gentr_trsl``: a translation by (x, y, z) metres."""
        return cls(name, trsl(x, y, z), kind)

    @classmethod
    def rot(cls, name: str, axis, angle: float, kind: str = "const", at=(0.0, 0.0, 0.0)) -> "Trsf":
        """``gentr_rot``: a rotation of ``angle`` radians about ``axis``, placed at translation ``at`` (m)."""
        m = rot(axis, angle)
        m[:3, 3] = at
        return cls(name, m, kind)

    @classmethod
    def rpy(cls, name: str, x: float, y: float, z: float, yaw: float, pitch: float, roll: float,
            kind: str = "const") -> "Trsf":
        """``gentr_rpy``: translation (m) then yaw-pitch-roll (rad, about fixed x, y, z)."""
        m = rpy(yaw, pitch, roll)
        m[:3, 3] = (x, y, z)
        return cls(name, m, kind)

    @classmethod
    def euler(cls, name: str, x: float, y: float, z: float, phi: float, theta: float, psi: float,
              kind: str = "const") -> "Trsf":
        """``gentr_eul``: translation (m) then z-y-z Euler angles (rad)."""
        m = euler(phi, theta, psi)
        m[:3, 3] = (x, y, z)
        return cls(name, m, kind)

    @classmethod
    def noap(cls, name: str, n, o, a, p, kind: str = "const") -> "Trsf":
        """``gentr_noap``: from the column vectors n, o, a, p."""
        return cls(name, noap(n, o, a, p), kind)

    # -- value ------------------------------------------------------------------------
    @property
    def kind(self) -> str:
        return self._kind

    @kind.setter
    def kind(self, value: str) -> None:
        if value not in KINDS:
            raise TransformError(f"transform {self.name!r}: kind {value!r} is not one of {KINDS}")
        if value == "functional" and self.fn is None:
            raise TransformError(f"transform {self.name!r}: bind fn before making it functional")
        self._kind = value

    def bind(self, fn: Callable[["Trsf"], None] | None) -> None:
        """Bind a modifying function (5.4.4; ``t->fn = f``); ``None`` makes the transform const again."""
        if fn is None:
            self.fn, self._kind = None, "const"
        else:
            if not callable(fn):
                raise TransformError(f"transform {self.name!r}: fn {fn!r} is not callable")
            self.fn, self._kind = fn, "functional"

    @property
    def value_array(self) -> np.ndarray:
        """The current 4x4 value itself, not a copy, for the solvers' inner loops: never modify
        it. Every change of value replaces the array, so ``is`` tells whether it changed."""
        return self._m

    @property
    def matrix(self) -> np.ndarray:
        """The current 4x4 value (a read-only view; use ``set`` or the component setters to change it)."""
        v = self._m.view()
        v.flags.writeable = False
        return v

    def set(self, matrix) -> None:
        """Replace the value (not allowed for const transforms)."""
        if self._kind == "const":
            raise ConstTransformError(f"transform {self.name!r} is const; make it 'variable' to change it")
        m = np.array(matrix, dtype=float)
        check_rigid(m, f"transform {self.name!r}")
        self._m = m

    def _replace(self, col: int, value) -> None:
        if self._kind == "const":
            raise ConstTransformError(f"transform {self.name!r} is const; make it 'variable' to change it")
        v = np.asarray(value, dtype=float).reshape(-1)
        if v.shape != (3,) or not np.all(np.isfinite(v)):
            raise TransformError(f"transform {self.name!r}: column {'noap'[col]} must be a finite 3-vector, got {value!r}")
        m = self._m.copy()
        m[:3, col] = v
        self._m = m

    n = property(lambda self: self._m[:3, 0].copy(), lambda self, v: self._replace(0, v), doc="normal vector")
    o = property(lambda self: self._m[:3, 1].copy(), lambda self, v: self._replace(1, v), doc="orientation vector")
    a = property(lambda self: self._m[:3, 2].copy(), lambda self, v: self._replace(2, v), doc="approach vector")
    p = property(lambda self: self._m[:3, 3].copy(), lambda self, v: self._replace(3, v), doc="position (m)")

    # -- algebra ----------------------------------------------------------------------
    def __matmul__(self, other) -> "Trsf":
        om = other._m if isinstance(other, Trsf) else np.asarray(other, dtype=float)
        oname = other.name if isinstance(other, Trsf) else "M"
        return Trsf(f"{self.name}*{oname}", self._m @ om)

    def __rmatmul__(self, other) -> "Trsf":
        return Trsf(f"M*{self.name}", np.asarray(other, dtype=float) @ self._m)

    def inv(self, name: str | None = None) -> "Trsf":
        """The inverse, as a new const transform."""
        return Trsf(name or f"{self.name}^-1", inverse(self._m))

    def copy(self, name: str | None = None, kind: str = "const") -> "Trsf":
        return Trsf(name or self.name, self._m, kind if kind != "functional" else "const")

    def __repr__(self) -> str:
        p = self._m[:3, 3]
        return f"Trsf({self.name!r}, {self._kind}, p=({p[0]:.4f}, {p[1]:.4f}, {p[2]:.4f}) m)"


class _T6(Trsf):
    """The manipulator's link-6 transform, the unknown of every position equation (thesis 5.3.1)."""

    __slots__ = ()

    def __init__(self) -> None:
        super().__init__("T6", np.eye(4), "variable")

    def set(self, matrix) -> None:  # noqa: D102 - T6 is solved for, never set
        raise TransformError("T6 is solved for by the trajectory generator; it cannot be set")

    def _replace(self, col: int, value) -> None:
        raise TransformError("T6 is solved for by the trajectory generator; it cannot be set")


T6 = _T6()
t6 = T6  # the thesis spells it t6


def product(items: Iterable[np.ndarray]) -> np.ndarray:
    """Left-to-right product of 4x4 arrays (identity if empty)."""
    out = np.eye(4)
    for m in items:
        out = out @ m
    return out


# --------------------------------------------------------------------------------------
# the thesis's allocation primitives (5.3.4), SI units
# --------------------------------------------------------------------------------------
def gentr_trsl(name: str, x: float, y: float, z: float, kind: str = "const") -> Trsf:
    """``gentr_trsl("T", x, y, z)``: a named translation (metres)."""
    return Trsf.trsl(name, x, y, z, kind)


def gentr_rot(name: str, x: float, y: float, z: float, axis, angle: float, kind: str = "const") -> Trsf:
    """``gentr_rot("B", x, y, z, axis, angle)``: translation (m) and rotation of ``angle`` rad about ``axis``."""
    return Trsf.rot(name, axis, angle, kind, at=(x, y, z))


def gentr_rpy(name: str, x: float, y: float, z: float, yaw: float, pitch: float, roll: float,
              kind: str = "const") -> Trsf:
    """``gentr_rpy``: translation (m) and yaw-pitch-roll (rad)."""
    return Trsf.rpy(name, x, y, z, yaw, pitch, roll, kind)


def gentr_eul(name: str, x: float, y: float, z: float, phi: float, theta: float, psi: float,
              kind: str = "const") -> Trsf:
    """``gentr_eul``: translation (m) and Euler angles (rad)."""
    return Trsf.euler(name, x, y, z, phi, theta, psi, kind)


def gentr_noap(name: str, n, o, a, p, kind: str = "const") -> Trsf:
    """``gentr_noap``: from the n, o, a, p column vectors."""
    return Trsf.noap(name, n, o, a, p, kind)
