"""RCCL's kinematics for a calibrated arm: the DH table plus the errors calib measured (thesis 3.83-3.84).

The generated closed-form kinematics (rccl.kinematics.<robot>) are those of the nominal
DH table. A real arm differs (3.83: A_i + dA_i), and ``calib fit kinematics -p FILE``
writes the errors it identified to the parameter file's ``[kinematics]`` section (per
joint d theta, d d, d a, d alpha; docs/calib.md). ``CalibratedKinematics`` offers the
kinematics contract (``fk``, ``ik``, ``config_of``, ``Config``, ...) for that arm:

* ``fk`` is the A-matrix product (eq. 3.3) with the corrected parameters, exact;
* ``ik`` starts from the nominal closed form (the errors are small, so it lands within a
  few millimetres and in the right configuration and branch) and refines it by Newton
  steps on the calibrated arm, with its own geometric Jacobian (quadratic convergence:
  three steps take the nominal solution's millimetres to rounding; along a path, where
  each call starts from the last call's correction, one step does);
* everything else (Jacobians, gravity, the force computations) is the nominal module's:
  first-order quantities, whose relative change is the size of the errors.

Use: ``rccl.open(url, kinematics=calibrated_kinematics("fitted.toml"))``.
"""
from __future__ import annotations

import math
import tomllib
from typing import Any

import numpy as np

from .exceptions import BadRequest
from .kinematics import load

DH_ERRORS = ("dtheta", "dd", "da", "dalpha")   # the [kinematics] keys: rad, m, m, rad per joint
NEWTON_STEPS = 4          # at most: from the nominal solution (mm off) three reach rounding
WARM_START = 0.05         # rad: a nominal solution this close to the last one starts from its correction
STEP_TOL = 1e-12          # m / rad: this close to the pose, no further step
REACH_TOL = 1e-9          # m / rad: further from the pose than this after the steps: unreachable


def read_dh_errors(path: str, robot: str = "puma260") -> np.ndarray:
    """The ``[kinematics]`` errors (n, 4) of a calib parameter file; NaN (not identified) reads 0.
    BadRequest names the file and what is wrong."""
    try:
        with open(path, "rb") as f:
            data = tomllib.load(f)
    except OSError as exc:
        raise BadRequest(f"{path}: cannot read the calibration file: {exc.strerror}") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise BadRequest(f"{path}: not a TOML calibration file: {exc}") from None
    head = data.get("calib")
    if not isinstance(head, dict) or head.get("robot") != robot:
        raise BadRequest(f"{path}: not a calibration of robot {robot!r} ([calib] robot = "
                         f"{head.get('robot') if isinstance(head, dict) else None!r})")
    kin = data.get("kinematics")
    if not isinstance(kin, dict) or not any(k in kin for k in DH_ERRORS):
        raise BadRequest(f"{path}: no [kinematics] section: fit one with `calib fit kinematics LOG -p {path}`")
    cols = []
    for key in DH_ERRORS:
        v = kin.get(key, [0.0] * 6)
        if not isinstance(v, list) or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v):
            raise BadRequest(f"{path}: [kinematics] {key} is not a list of numbers")
        cols.append(v)
    if len({len(c) for c in cols}) != 1:
        raise BadRequest(f"{path}: [kinematics] lists differ in length")
    e = np.array(cols, dtype=float).T
    if np.isinf(e).any() or np.abs(np.nan_to_num(e)).max() > 0.1:
        raise BadRequest(f"{path}: [kinematics] errors must be finite and small (|e| <= 0.1 rad or m)")
    return np.nan_to_num(e, nan=0.0)


class CalibratedKinematics:
    """The kinematics contract of ``module`` (a generated rccl.kinematics module) for the arm
    whose DH table is the data file's plus ``errors`` (n, 4)."""

    def __init__(self, module, dh: np.ndarray, errors: np.ndarray) -> None:
        self.nominal = module
        self.errors = np.asarray(errors, dtype=float)
        dh = np.asarray(dh, dtype=float)
        if dh.shape != self.errors.shape or dh.shape[1] != 4:
            raise BadRequest(f"DH table {dh.shape} and errors {self.errors.shape} must both be (n, 4)")
        if any(k != "revolute" for k in module.JOINT_KINDS):
            raise BadRequest(f"{module.ROBOT}: calibrated kinematics are for revolute arms")
        true = dh + self.errors
        self.offset = [float(x) for x in true[:, 0]]         # theta_i = q_i + offset_i
        # the fixed part of each step, Tz(d) Tx(a) Rx(alpha) (3.3), its top 3x4 row-major
        self._fixed = [tuple(float(x) for x in _fixed(d, a, al)[:3].ravel()) for _, d, a, al in true]
        self.ROBOT = module.ROBOT
        self.JOINT_KINDS = module.JOINT_KINDS
        self.Config = module.Config
        self.config_of = module.config_of
        self.__name__ = f"{module.__name__} (calibrated)"
        # (last nominal solution, its correction): successive calls of a path are close, and
        # so are their corrections, so one Newton step usually finishes (replaced whole, so
        # a planning thread and the control thread sharing it only lose the warm start)
        self._last: tuple[np.ndarray, np.ndarray] | None = None

    def __getattr__(self, name: str) -> Any:
        # Jacobians, gravity, force computations, ranges: the nominal module's
        return getattr(self.nominal, name)

    def _chain(self, q) -> tuple[tuple[float, ...], list, list]:
        """T6's top 3x4 (row-major floats) and each joint's axis z_(i-1) and origin p_(i-1)
        in the base frame. Plain floats: for six 4x4 products they beat numpy's call overhead
        by a factor of ten (about 5 us)."""
        r00, r01, r02, px, r10, r11, r12, py, r20, r21, r22, pz = (1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0,
                                                                   0.0, 0.0, 1.0, 0.0)
        zs, ps = [], []
        for i in range(len(self._fixed)):
            zs.append((r02, r12, r22))
            ps.append((px, py, pz))
            th = q[i] + self.offset[i]
            c, s = math.cos(th), math.sin(th)
            f0, f1, f2, f3, f4, f5, f6, f7, a20, a21, a22, a23 = self._fixed[i]
            # A = Rz(th) F
            a00, a01, a02, a03 = c * f0 - s * f4, c * f1 - s * f5, c * f2 - s * f6, c * f3 - s * f7
            a10, a11, a12, a13 = s * f0 + c * f4, s * f1 + c * f5, s * f2 + c * f6, s * f3 + c * f7
            r00, r01, r02, px = (r00 * a00 + r01 * a10 + r02 * a20, r00 * a01 + r01 * a11 + r02 * a21,
                                 r00 * a02 + r01 * a12 + r02 * a22, r00 * a03 + r01 * a13 + r02 * a23 + px)
            r10, r11, r12, py = (r10 * a00 + r11 * a10 + r12 * a20, r10 * a01 + r11 * a11 + r12 * a21,
                                 r10 * a02 + r11 * a12 + r12 * a22, r10 * a03 + r11 * a13 + r12 * a23 + py)
            r20, r21, r22, pz = (r20 * a00 + r21 * a10 + r22 * a20, r20 * a01 + r21 * a11 + r22 * a21,
                                 r20 * a02 + r21 * a12 + r22 * a22, r20 * a03 + r21 * a13 + r22 * a23 + pz)
        return (r00, r01, r02, px, r10, r11, r12, py, r20, r21, r22, pz), zs, ps

    # -- forward kinematics -------------------------------------------------------------
    def fk(self, q, out=None) -> np.ndarray:
        """T6 (4, 4) of the calibrated arm; q (6,) or (N, 6) -> (N, 4, 4)."""
        q = np.asarray(q, dtype=float)
        if q.ndim == 1:
            T = self._fk_one(q)
        else:
            T = np.array([self._fk_one(x) for x in q])
        if out is not None:
            out[...] = T
            return out
        return T

    def _fk_one(self, q) -> np.ndarray:
        T = np.empty((4, 4))
        T[:3] = np.reshape(self._chain(q.tolist() if isinstance(q, np.ndarray) else q)[0], (3, 4))
        T[3] = (0.0, 0.0, 0.0, 1.0)
        return T

    # -- inverse kinematics ---------------------------------------------------------------
    def ik(self, T, config, q_ref=None) -> np.ndarray:
        """Joint angles of T6 = ``T`` in ``config``: the nominal closed form, then Newton steps
        on the calibrated arm (its own geometric Jacobian, so the steps converge
        quadratically: from the nominal solution's millimetres, two reach the pose to
        rounding). Unreachable (a ValueError, as the nominal module's) when the calibrated
        arm does not reach the pose."""
        T = np.asarray(T, dtype=float)
        q_nominal = np.array(self.nominal.ik(T, config, q_ref), dtype=float)
        q = q_nominal.copy()
        last = self._last
        if last is not None and float(np.abs(q_nominal - last[0]).max()) < WARM_START:
            q += last[1]
        t = T[:3].ravel().tolist()
        miss = math.inf
        for step in range(NEWTON_STEPS + 1):
            (r00, r01, r02, px, r10, r11, r12, py, r20, r21, r22, pz), zs, ps = self._chain(q.tolist())
            # the error in the base frame: position, and the small rotation R_T R^T (exact at zero)
            m01 = t[0] * r10 + t[1] * r11 + t[2] * r12
            m02 = t[0] * r20 + t[1] * r21 + t[2] * r22
            m10 = t[4] * r00 + t[5] * r01 + t[6] * r02
            m12 = t[4] * r20 + t[5] * r21 + t[6] * r22
            m20 = t[8] * r00 + t[9] * r01 + t[10] * r02
            m21 = t[8] * r10 + t[9] * r11 + t[10] * r12
            err = (t[3] - px, t[7] - py, t[11] - pz, 0.5 * (m21 - m12), 0.5 * (m02 - m20), 0.5 * (m10 - m01))
            miss = max(abs(x) for x in err)
            if miss < STEP_TOL or step == NEWTON_STEPS:
                break
            J = np.empty((6, 6))
            for i, ((zx, zy, zz), (ox, oy, oz)) in enumerate(zip(zs, ps)):
                dx, dy, dz = px - ox, py - oy, pz - oz
                J[:, i] = (zy * dz - zz * dy, zz * dx - zx * dz, zx * dy - zy * dx, zx, zy, zz)
            try:
                q += np.linalg.solve(J, err)
            except np.linalg.LinAlgError:
                q += np.linalg.lstsq(J, np.asarray(err), rcond=1e-9)[0]
        if not math.isfinite(miss) or miss > REACH_TOL:
            from rccl.kinematics.exceptions import Unreachable

            raise Unreachable(f"{self.ROBOT} (calibrated): the calibrated arm misses the pose by "
                              f"{miss:.2e} after {NEWTON_STEPS} Newton steps from the nominal solution")
        self._last = (q_nominal, q - q_nominal)
        return q

    def ik_all(self, T, q_ref=None) -> list:
        """Every configuration's solution (those the calibrated arm reaches)."""
        out = []
        for config, _ in self.nominal.ik_all(T, q_ref):
            try:
                out.append((config, self.ik(T, config, q_ref)))
            except ValueError:
                continue
        return out


def _fixed(d: float, a: float, alpha: float) -> np.ndarray:
    ca, sa = math.cos(alpha), math.sin(alpha)
    return np.array([[1.0, 0.0, 0.0, a], [0.0, ca, -sa, 0.0], [0.0, sa, ca, d], [0.0, 0.0, 0.0, 1.0]])


def load_calibrated(path: str, robot: str = "puma260") -> CalibratedKinematics:
    """The calibrated kinematics of ``robot`` from the ``[kinematics]`` section of ``path``."""
    from rcci.models import load_robot

    module = load(robot)
    dh = np.array([[j.theta, j.d, j.a, j.alpha] for j in load_robot(robot).joints])
    errors = read_dh_errors(path, robot)
    if errors.shape != dh.shape:
        raise BadRequest(f"{path}: [kinematics] has {errors.shape[0]} joints, {robot} has {dh.shape[0]}")
    return CalibratedKinematics(module, dh, errors)


def calibrated_kinematics(path: str, robot: str = "puma260"):
    """What ``rccl.open(url, kinematics=...)`` takes: the calibrated kinematics, wrapped for RCCL."""
    from .segments import Kinematics

    return Kinematics(load_calibrated(path, robot))
