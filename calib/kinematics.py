"""Kinematic error parameters of thesis 3.83-3.84 from measured end poses.

3.83 writes the true T6 as the product of (A_i + dA_i); to first order (3.84) it is the
ideal product plus M e, with M a pose-dependent matrix and e a constant vector of error
parameters.  Here e holds, for each joint, errors of its four DH parameters
(d theta, d d, d a, d alpha), and T6 is the thesis's A-matrix product (eq. 3.3) built in
CasADi, so that M = dT6/de comes exact from automatic differentiation.  The fit is
Gauss-Newton on the pose residuals (position in m, orientation as a rotation vector in
rad, weighted by ``orientation_scale``), each step solved by a truncated SVD: error
parameters the poses cannot tell apart (e.g. d d2 and d d3 of the PUMA's parallel
joints 2 and 3) are reported as combinations, not guessed.
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from calib.errors import FitError

PARAM_NAMES = ("dtheta", "dd", "da", "dalpha")


@dataclass(frozen=True)
class KinematicFit:
    """Error parameters e (24,) = per joint (d theta rad, d d m, d a m, d alpha rad),
    their standard deviations (NaN where not identifiable), which were identifiable,
    and the RMS pose residuals before and after (m, rad)."""

    e: np.ndarray
    std: np.ndarray
    identifiable: np.ndarray
    rank: int
    null_space: np.ndarray
    rms_position_before: float
    rms_position_after: float
    rms_orientation_before: float
    rms_orientation_after: float
    iterations: int


def _dh(theta, d, a, alpha):
    ct, st, c_a, s_a = ca.cos(theta), ca.sin(theta), ca.cos(alpha), ca.sin(alpha)
    return ca.vertcat(
        ca.horzcat(ct, -st * c_a, st * s_a, a * ct),
        ca.horzcat(st, ct * c_a, -ct * s_a, a * st),
        ca.horzcat(0, s_a, c_a, d),
        ca.horzcat(0, 0, 0, 1))


def fk_function(dh: np.ndarray) -> ca.Function:
    """CasADi T6(q, e) for a revolute arm with nominal DH rows (theta0, d, a, alpha)."""
    n = dh.shape[0]
    q = ca.SX.sym("q", n)
    e = ca.SX.sym("e", 4 * n)
    T = ca.SX.eye(4)
    for i in range(n):
        th0, d, a, al = dh[i]
        T = T @ _dh(th0 + q[i] + e[4 * i], d + e[4 * i + 1], a + e[4 * i + 2], al + e[4 * i + 3])
    return ca.Function("T6", [q, e], [T])


def _rotvec(R: np.ndarray) -> np.ndarray:
    """Rotation vector (rad) of a rotation matrix."""
    c = np.clip((np.trace(R) - 1) / 2, -1.0, 1.0)
    angle = np.arccos(c)
    w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    if angle < 1e-9:
        return 0.5 * w
    return angle / (2 * np.sin(angle)) * w


def _residuals(T6: ca.Function, Q: np.ndarray, poses: np.ndarray, e: np.ndarray,
               scale: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stacked residuals (6N,), and position / orientation parts (N,3) each."""
    dp, dr = [], []
    for q, Tm in zip(Q, poses):
        T = np.array(T6(q, e))
        dp.append(Tm[:3, 3] - T[:3, 3])
        dr.append(T[:3, :3] @ _rotvec(T[:3, :3].T @ Tm[:3, :3]))  # in the base frame
    dp, dr = np.array(dp), np.array(dr)
    return np.hstack([dp, scale * dr]).ravel(), dp, dr


def fit_kinematics(dh: np.ndarray, Q: np.ndarray, poses: np.ndarray,
                   orientation_scale: float = 0.2, rcond: float = 1e-3,
                   max_iter: int = 20) -> KinematicFit:
    """Error parameters from joint angles ``Q`` (N,6) rad and measured T6 ``poses`` (N,4,4).

    ``orientation_scale`` (m/rad) weighs a radian of orientation error like that many
    metres of position error (0.2 m: the PUMA 260's reach).
    """
    Q, poses = np.asarray(Q, float), np.asarray(poses, float)
    n = dh.shape[0]
    if len(Q) * 6 < 4 * n:
        raise FitError(f"{len(Q)} poses cannot determine {4 * n} error parameters")
    T6 = fk_function(dh)
    q_s = ca.SX.sym("q", n)
    e_s = ca.SX.sym("e", 4 * n)
    T = T6(q_s, e_s)
    # linearised residual: position and small-angle rotation of T(e) relative to T(e0)
    e0 = ca.SX.sym("e0", 4 * n)
    T0 = T6(q_s, e0)
    p = T[:3, 3]
    Rrel = T0[:3, :3].T @ T[:3, :3]
    w = 0.5 * ca.vertcat(Rrel[2, 1] - Rrel[1, 2], Rrel[0, 2] - Rrel[2, 0], Rrel[1, 0] - Rrel[0, 1])
    w_base = T0[:3, :3] @ w
    J = ca.Function("J", [q_s, e_s, e0],
                    [ca.jacobian(ca.vertcat(p, orientation_scale * w_base), e_s)])
    e = np.zeros(4 * n)
    r, dp0, dr0 = _residuals(T6, Q, poses, e, orientation_scale)
    rank, it = 0, 0
    for it in range(1, max_iter + 1):
        M = np.vstack([np.array(J(q, e, e)) for q in Q])       # 3.84's M, stacked
        U, s, Vt = np.linalg.svd(M, full_matrices=False)
        keep = s > rcond * s[0]
        rank = int(keep.sum())
        step = Vt[keep].T @ ((U[:, keep].T @ r) / s[keep])
        e = e + step
        r, _, _ = _residuals(T6, Q, poses, e, orientation_scale)
        if np.abs(step).max() < 1e-12:
            break
    r, dp1, dr1 = _residuals(T6, Q, poses, e, orientation_scale)
    dof = max(len(r) - rank, 1)
    s2 = float(r @ r) / dof
    cov = s2 * (Vt[keep].T / s[keep] ** 2) @ Vt[keep]
    # a parameter is identifiable alone when (almost) none of it lies in the null space
    proj = np.sum(Vt[keep] ** 2, axis=0)
    ident = proj > 0.99
    std = np.where(ident, np.sqrt(np.maximum(np.diag(cov), 0.0)), np.nan)
    rms = lambda a: float(np.sqrt(np.mean(np.sum(a ** 2, axis=1))))  # noqa: E731
    return KinematicFit(e=e, std=std, identifiable=ident, rank=rank, null_space=Vt[~keep],
                        rms_position_before=rms(dp0), rms_position_after=rms(dp1),
                        rms_orientation_before=rms(dr0), rms_orientation_after=rms(dr1),
                        iterations=it)


def table(fit: KinematicFit) -> str:
    """The error parameters per joint (mm, millidegrees), laid out like Table 3.1."""
    out = ["Kinematic error parameters (3.84): e per joint, +- 1 std ('-' = not identifiable alone)",
           f"{'Joint':>5}  {'d theta (mdeg)':>16}  {'d d (mm)':>14}  {'d a (mm)':>14}  {'d alpha (mdeg)':>16}"]
    conv = (np.degrees(1) * 1e3, 1e3, 1e3, np.degrees(1) * 1e3)
    for j in range(len(fit.e) // 4):
        cells = []
        for k in range(4):
            i = 4 * j + k
            v = fit.e[i] * conv[k]
            cells.append(f"{v:8.3f} +- {fit.std[i] * conv[k]:5.3f}" if fit.identifiable[i] else f"{'-':>14}")
        out.append(f"{j + 1:>5}  {cells[0]:>16}  {cells[1]:>14}  {cells[2]:>14}  {cells[3]:>16}")
    names = [f"{p}{j + 1}" for j in range(len(fit.e) // 4) for p in PARAM_NAMES]
    for v in fit.null_space:
        big = np.flatnonzero(np.abs(v) > 0.1)
        combo = " ".join(f"{v[i] / v[big[0]]:+.2f} {names[i]}" for i in big)
        out.append(f"not separable by these poses: {combo}")
    out.append(f"rank {fit.rank} of {len(fit.e)}; RMS position {1e3 * fit.rms_position_before:.3f} -> "
               f"{1e3 * fit.rms_position_after:.3f} mm, orientation "
               f"{np.degrees(fit.rms_orientation_before) * 1e3:.2f} -> "
               f"{np.degrees(fit.rms_orientation_after) * 1e3:.2f} mdeg ({fit.iterations} iterations)")
    return "\n".join(out)


def read_poses(path: str) -> tuple[np.ndarray, np.ndarray]:
    """Measured end poses from a CSV file: q1..q6 (rad), x y z (m), rx ry rz (rotation
    vector, rad), one pose a line; '#' starts a comment.  FitError names the line."""
    from calib.errors import LogError

    Q, T = [], []
    with open(path, encoding="utf-8") as f:
        for lineno, line in enumerate(f, 1):
            line = line.split("#", 1)[0].strip()
            if not line:
                continue
            try:
                vals = np.array([float(x) for x in line.split(",")])
            except ValueError:
                raise LogError(path, lineno, f"not 12 comma-separated numbers: {line!r}") from None
            if vals.size != 12 or not np.isfinite(vals).all():
                raise LogError(path, lineno, f"expected 12 finite numbers, got {vals.size}")
            Q.append(vals[:6])
            P = np.eye(4)
            P[:3, 3] = vals[6:9]
            P[:3, :3] = _rotmat(vals[9:12])
            T.append(P)
    if not Q:
        raise LogError(path, None, "no poses")
    return np.array(Q), np.array(T)


def _rotmat(w: np.ndarray) -> np.ndarray:
    """Rotation matrix of a rotation vector (Rodrigues)."""
    angle = float(np.linalg.norm(w))
    if angle < 1e-12:
        return np.eye(3)
    k = w / angle
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K
