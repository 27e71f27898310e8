"""Kinematic error parameters of thesis 3.83-3.84 from touches of known faces (or measured end poses).

3.83 writes the true T6 as the product of (A_i + dA_i); to first order (3.84) it is the
ideal product plus M e, with M a pose-dependent matrix and e a constant vector of error
parameters.  Here e holds, for each joint, errors of its four DH parameters
(d theta, d d, d a, d alpha), and T6 is the thesis's A-matrix product (eq. 3.3) built in
CasADi, so that M = dT6/de comes exact from automatic differentiation.  The fit is
Gauss-Newton on the measurement residuals, each step solved by a truncated SVD: error
parameters the measurements cannot tell apart are reported as combinations, not guessed
(on the PUMA, d d2 and d d3 always: joints 2 and 3 are parallel, so both move the arm along
the same direction).

Two kinds of measurement:

* touches (``calib record kinematics``, rcci.calib.touch): the probe tip p(q, e) = T6(q, e) tip
  lies on a known face, n . p = h; one residual per touch, in metres.  A point measures no
  turn of link 6 about the line from the wrist centre to the tip, so that combination of
  the wrist's angle errors stays unseparated too;
* full end poses from an external instrument (a CSV of q, position, rotation vector):
  six residuals per pose, the rotation weighted by ``orientation_scale`` m/rad.

The error of each identifiable parameter is its standard deviation from the fit
(residual variance times the inverse normal matrix on the identified subspace).
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import casadi as ca
import numpy as np

from rcci.calib.exceptions import FitError, LogError
from rcci.calib.trace import Trace

PARAM_NAMES = ("dtheta", "dd", "da", "dalpha")
UNITS = ("rad", "m", "m", "rad")


@dataclass(frozen=True)
class KinematicFit:
    """Error parameters e (24,) = per joint (d theta rad, d d m, d a m, d alpha rad),
    their standard deviations (NaN where not identifiable alone), which were identifiable,
    the combinations that are not (``null_space`` rows), the covariance on the identified
    subspace, and the RMS residuals before and after (position m; orientation rad, NaN
    for touches)."""

    e: np.ndarray
    std: np.ndarray
    identifiable: np.ndarray
    rank: int
    null_space: np.ndarray
    cov: np.ndarray
    rms_position_before: float
    rms_position_after: float
    rms_orientation_before: float
    rms_orientation_after: float
    iterations: int
    measurements: int
    kind: str = "poses"

    @property
    def factor(self) -> float:
        """Standard deviations in the printed uncertainty: Student's t (99.73 %) for the
        residual's degrees of freedom (rcci.calib.lsq.coverage_factor)."""
        from rcci.calib.lsq import coverage_factor

        dof = self.measurements * (6 if self.kind == "poses" else 1) - self.rank
        return coverage_factor(dof)

    @property
    def names(self) -> list[str]:
        return param_names(len(self.e) // 4)

    def combinations(self) -> list[tuple[str, float, float, str, np.ndarray]]:
        """(name, value, std, unit, coefficients (24,)) of the identifiable combination of each group of parameters
        not identifiable alone (e.g. "dd2 + dd3"): the part of the group orthogonal to its
        null-space directions."""
        out = []
        names = self.names
        groups: list[set[int]] = []
        for v in self.null_space:
            support = set(np.flatnonzero((np.abs(v) > 0.05) & ~self.identifiable))
            for g in groups:
                if g & support:
                    g |= support
                    break
            else:
                groups.append(support)
        for g in groups:
            idx = sorted(g)
            N = self.null_space[:, idx]
            N = N[np.linalg.norm(N, axis=1) > 0.5]     # the null directions that live in this group
            # the identifiable directions inside the group: orthogonal to those
            _, s, vt = np.linalg.svd(N)
            for u in vt[int((s > 1e-3 * s.max()).sum()):]:
                lead = int(np.argmax(np.abs(u)))
                u = u / u[lead]
                full = np.zeros(len(self.e))
                full[idx] = u
                terms = " ".join(f"{'+' if c >= 0 else '-'} {abs(c):.2f} {names[i]}".replace(" 1.00 ", " ")
                                 for c, i in zip(u, idx) if abs(c) > 1e-6)
                unit = UNITS[idx[lead] % 4]
                out.append((terms.lstrip("+ "), float(full @ self.e), float(np.sqrt(full @ self.cov @ full)),
                            unit, full))
        return out


def param_names(n: int) -> list[str]:
    """'dtheta1', 'dd1', 'da1', 'dalpha1', 'dtheta2', ... for n joints."""
    return [f"{p}{j + 1}" for j in range(n) for p in PARAM_NAMES]


def _dh(theta, d, a, alpha):
    ct, st, c_a, s_a = ca.cos(theta), ca.sin(theta), ca.cos(alpha), ca.sin(alpha)
    return ca.vertcat(
        ca.horzcat(ct, -st * c_a, st * s_a, a * ct),
        ca.horzcat(st, ct * c_a, -ct * s_a, a * st),
        ca.horzcat(0, s_a, c_a, d),
        ca.horzcat(0, 0, 0, 1))


def fk_function(dh: np.ndarray, kinds: tuple[str, ...] | None = None) -> ca.Function:
    """CasADi T6(q, e) for an arm with nominal DH rows (theta0, d, a, alpha); ``kinds``
    ("revolute" or "prismatic" per joint, default all revolute) says which parameter the joint
    variable adds to (theta, or d for a slide: the Stanford arm's joint 3)."""
    n = dh.shape[0]
    kinds = kinds or ("revolute",) * n
    q = ca.SX.sym("q", n)
    e = ca.SX.sym("e", 4 * n)
    T = ca.SX.eye(4)
    for i in range(n):
        th0, d, a, al = dh[i]
        slide = kinds[i] == "prismatic"
        theta = th0 + e[4 * i] + (0 if slide else q[i])
        T = T @ _dh(theta, d + e[4 * i + 1] + (q[i] if slide else 0), a + e[4 * i + 2], al + e[4 * i + 3])
    return ca.Function("T6", [q, e], [T])


def nominal_dh(robot: str = "puma260") -> np.ndarray:
    """The data file's DH table, (n, 4) rows (theta offset rad, d m, a m, alpha rad)."""
    from rcci.models import load_robot

    return np.array([[j.theta, j.d, j.a, j.alpha] for j in load_robot(robot).joints])


def _rotvec(R: np.ndarray) -> np.ndarray:
    """Rotation vector (rad) of a rotation matrix."""
    from rcci.calib.touch import rotation_vector

    return rotation_vector(R)


def _gauss_newton(residual: Callable[[np.ndarray], np.ndarray], jacobian: Callable[[np.ndarray], np.ndarray],
                  n_params: int, n_meas: int, rcond: float, max_iter: int):
    """Gauss-Newton from e = 0 on residual(e) = model - measurement, with ``jacobian`` its
    derivative; steps by truncated SVD; returns (e, rank, Vt, s, keep, it)."""
    if n_meas < 2:
        raise FitError(f"{n_meas} measurement(s) cannot determine kinematic errors")
    e = np.zeros(n_params)
    r = residual(e)
    it = 0
    for it in range(1, max_iter + 1):
        M = jacobian(e)                                  # 3.84's M, stacked
        U, s, Vt = np.linalg.svd(M, full_matrices=False)
        keep = s > rcond * s[0]
        step = -Vt[keep].T @ ((U[:, keep].T @ r) / s[keep])
        e = e + step
        r = residual(e)
        if np.abs(step).max() < 1e-13:
            break
    M = jacobian(e)
    U, s, Vt = np.linalg.svd(M, full_matrices=False)
    keep = s > rcond * s[0]
    return e, int(keep.sum()), Vt, s, keep, it


def _result(e, rank, Vt, s, keep, it, r_after: np.ndarray, n_meas: int, kind: str,
            rms: tuple[float, float, float, float]) -> KinematicFit:
    dof = max(len(r_after) - rank, 1)
    s2 = float(r_after @ r_after) / dof
    cov = s2 * (Vt[keep].T / s[keep] ** 2) @ Vt[keep]
    # a parameter is identifiable alone when (almost) none of it lies in the null space
    proj = np.sum(Vt[keep] ** 2, axis=0)
    ident = proj > 0.99
    std = np.where(ident, np.sqrt(np.maximum(np.diag(cov), 0.0)), np.nan)
    return KinematicFit(e=e, std=std, identifiable=ident, rank=rank, null_space=Vt[~keep], cov=cov,
                        rms_position_before=rms[0], rms_position_after=rms[1],
                        rms_orientation_before=rms[2], rms_orientation_after=rms[3],
                        iterations=it, measurements=n_meas, kind=kind)


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
    q_s, e_s, e0 = ca.SX.sym("q", n), ca.SX.sym("e", 4 * n), ca.SX.sym("e0", 4 * n)
    T, T0 = T6(q_s, e_s), T6(q_s, e0)
    # linearised residual: position and small-angle rotation of T(e) relative to T(e0)
    Rrel = T0[:3, :3].T @ T[:3, :3]
    w = 0.5 * ca.vertcat(Rrel[2, 1] - Rrel[1, 2], Rrel[0, 2] - Rrel[2, 0], Rrel[1, 0] - Rrel[0, 1])
    J = ca.Function("J", [q_s, e_s, e0], [ca.jacobian(ca.vertcat(T[:3, 3], orientation_scale * (T0[:3, :3] @ w)), e_s)])

    def parts(e):
        dp, dr = [], []
        for q, Tm in zip(Q, poses):
            Tq = np.array(T6(q, e))
            dp.append(Tm[:3, 3] - Tq[:3, 3])
            dr.append(Tq[:3, :3] @ _rotvec(Tq[:3, :3].T @ Tm[:3, :3]))  # in the base frame
        return np.array(dp), np.array(dr)

    def residual(e):        # model - measurement
        dp, dr = parts(e)
        return -np.hstack([dp, orientation_scale * dr]).ravel()

    def jacobian(e):
        return np.vstack([np.array(J(q, e, e)) for q in Q])

    dp0, dr0 = parts(np.zeros(4 * n))
    e, rank, Vt, s, keep, it = _gauss_newton(residual, jacobian, 4 * n, len(Q), rcond, max_iter)
    dp1, dr1 = parts(e)
    rms = lambda a: float(np.sqrt(np.mean(np.sum(a ** 2, axis=1))))  # noqa: E731
    return _result(e, rank, Vt, s, keep, it, residual(e), len(Q), "poses",
                   (rms(dp0), rms(dp1), rms(dr0), rms(dr1)))


@dataclass(frozen=True)
class Touches:
    """Touches read from a log: contact joint angles (N,6) rad, face normals (N,3),
    face offsets (N,) m, the probe tip in link 6 (3,) m, and each touch's index in the plan."""

    q: np.ndarray
    normals: np.ndarray
    offsets: np.ndarray
    tip: np.ndarray
    index: np.ndarray


def fit_touches(dh: np.ndarray, touches: Touches, rcond: float = 1e-6, max_iter: int = 20,
                kinds: tuple[str, ...] | None = None) -> KinematicFit:
    """Error parameters from touches: residual n . (T6(q, e) tip) - h per touch (m); ``kinds``
    as fk_function's."""
    n = dh.shape[0]
    T6 = fk_function(dh, kinds)
    q_s, e_s = ca.SX.sym("q", n), ca.SX.sym("e", 4 * n)
    nrm, h = ca.SX.sym("n", 3), ca.SX.sym("h")
    tip = ca.DM([*touches.tip, 1.0])
    res = ca.dot(nrm, (T6(q_s, e_s) @ tip)[:3]) - h
    F = ca.Function("r", [q_s, e_s, nrm, h], [res, ca.jacobian(res, e_s)])
    Fmap = F.map(len(touches.q))
    args = (touches.q.T, None, touches.normals.T, touches.offsets[None, :])

    def run(e):
        r, J = Fmap(args[0], np.tile(e[:, None], (1, len(touches.q))), args[2], args[3])
        return np.array(r).ravel(), np.array(J).reshape(len(touches.q), 4 * n)

    e, rank, Vt, s, keep, it = _gauss_newton(lambda e: run(e)[0], lambda e: run(e)[1], 4 * n,
                                             len(touches.q), rcond, max_iter)
    r0, r1 = run(np.zeros(4 * n))[0], run(e)[0]
    rms = lambda a: float(np.sqrt(np.mean(a ** 2)))  # noqa: E731
    return _result(e, rank, Vt, s, keep, it, r1, len(touches.q), "touches",
                   (rms(r0), rms(r1), float("nan"), float("nan")))


def touches_from_trace(trace: Trace, drive) -> Touches:
    """The touches of a kinematics log (calib record kinematics): per touch, the joint
    angles halfway between the last reading with the probe open and the first with it
    closed (the arm stands on the commanded counts at each reading; the switch closed
    between them)."""
    fixture = trace.need("fixture", list)
    tip = np.asarray(trace.need("tip", list), dtype=float)
    bit = int(trace.need("probe_bit", int))
    faces = trace.need("touch_faces", list)
    if tip.shape != (3,):
        raise LogError(trace.path, None, f"metadata 'tip' = {tip.tolist()} is not 3 numbers (m)")
    try:
        normals = np.array([f["normal"] for f in fixture], dtype=float)
        offsets = np.array([f["offset"] for f in fixture], dtype=float)
    except (KeyError, TypeError, ValueError):
        raise LogError(trace.path, None, "metadata 'fixture' is not a list of {name, normal, offset}") from None
    index = trace.extra.get("touch")
    closed = trace.extra.get("inport1")
    if index is None or closed is None:
        raise LogError(trace.path, None, "records lack the touch index (u_touch) or inport1: "
                       "not a log of calib record kinematics")
    closed = (closed.astype(np.int64) >> bit) & 1
    theta = drive.joint_angles(trace.counts)
    Q, N, H, K = [], [], [], []
    for k in np.unique(index):
        rows = np.flatnonzero(index == k)
        hit = rows[closed[rows] == 1]
        if len(hit) == 0:
            raise LogError(trace.path, trace.first_record + int(rows[-1]),
                           f"touch {k + 1}: the probe never closed during the measuring approach")
        first = int(hit[0])
        if first == rows[0] or closed[first - 1]:
            raise LogError(trace.path, trace.first_record + first,
                           f"touch {k + 1}: the probe was closed when the measuring approach began")
        if not 0 <= k < len(faces) or not 0 <= int(faces[k]) < len(fixture):
            raise LogError(trace.path, None, f"touch {k + 1}: no face for it in metadata 'touch_faces'")
        f = int(faces[k])
        Q.append(0.5 * (theta[first - 1] + theta[first]))
        N.append(normals[f])
        H.append(offsets[f])
        K.append(int(k))
    if not Q:
        raise LogError(trace.path, None, "no touch in the log")
    return Touches(np.array(Q), np.array(N), np.array(H), tip, np.array(K))


def table(fit: KinematicFit, sigmas: float | None = None) -> str:
    """The error parameters per joint (mm, millidegrees), laid out like Table 3.1, with
    their printed uncertainty (``sigmas`` standard deviations; by default the fit's
    99.73 % factor, ``KinematicFit.factor``)."""
    sigmas = fit.factor if sigmas is None else sigmas
    what = "touches" if fit.kind == "touches" else "poses"
    out = [f"Kinematic error parameters (3.84) from {fit.measurements} {what}: e per joint, "
           f"+- {sigmas:.2f} sd, 99.73 % ('-' = not identifiable alone)",
           f"{'Joint':>5}  {'d theta (mdeg)':>18}  {'d d (mm)':>16}  {'d a (mm)':>16}  {'d alpha (mdeg)':>18}"]
    conv = (np.degrees(1) * 1e3, 1e3, 1e3, np.degrees(1) * 1e3)
    for j in range(len(fit.e) // 4):
        cells = []
        for k in range(4):
            i = 4 * j + k
            v = fit.e[i] * conv[k]
            cells.append(f"{v:8.3f} +- {sigmas * fit.std[i] * conv[k]:6.3f}" if fit.identifiable[i] else "-")
        out.append(f"{j + 1:>5}  {cells[0]:>18}  {cells[1]:>16}  {cells[2]:>16}  {cells[3]:>18}")
    for name, value, std, unit, _ in fit.combinations():
        out.append(f"not separable alone; identified as a combination: {name} = "
                   f"{_scaled(unit, value)} +- {_scaled(unit, sigmas * std)}")
    before, after = 1e3 * fit.rms_position_before, 1e3 * fit.rms_position_after
    line = f"rank {fit.rank} of {len(fit.e)}; RMS residual {before:.4f} -> {after:.4f} mm"
    if np.isfinite(fit.rms_orientation_before):
        line += (f", orientation {np.degrees(fit.rms_orientation_before) * 1e3:.2f} -> "
                 f"{np.degrees(fit.rms_orientation_after) * 1e3:.2f} mdeg")
    out.append(line + f" ({fit.iterations} iterations)")
    return "\n".join(out)


def _scaled(unit: str, value: float) -> str:
    """A value in mm (unit m) or mdeg (unit rad)."""
    return f"{np.degrees(value) * 1e3:.3f} mdeg" if unit == "rad" else f"{value * 1e3:.4f} mm"


def section(fit: KinematicFit, sigmas: float | None = None) -> dict:
    """The ``[kinematics]`` section of the parameter file: every error parameter (the
    minimum-norm values where the measurements leave a combination open, so that the
    corrected model reproduces what was measured), the printed uncertainty (NaN where not
    identifiable alone) and the combinations."""
    sigmas = fit.factor if sigmas is None else sigmas
    n = len(fit.e) // 4
    sec: dict = {}
    for k, name in enumerate(PARAM_NAMES):
        sec[name] = [float(fit.e[4 * j + k]) for j in range(n)]
        sec[f"{name}_std"] = [float(fit.std[4 * j + k]) for j in range(n)]
        sec[f"{name}_error"] = [float(sigmas * fit.std[4 * j + k]) for j in range(n)]
    sec["identifiable"] = [bool(x) for x in fit.identifiable]
    sec["combinations"] = [f"{nm} = {v!r} +- {sigmas * s!r} {u}" for nm, v, s, u, _ in fit.combinations()]
    sec["error_is"] = f"{sigmas:.3f} sd (99.73 %, {fit.measurements - fit.rank} degrees of freedom)"
    sec["measurements"] = int(fit.measurements)
    sec["rms_residual_before"] = fit.rms_position_before
    sec["rms_residual_after"] = fit.rms_position_after
    sec["unit"] = "rad (dtheta, dalpha), m (dd, da)"
    return sec


def read_poses(path: str) -> tuple[np.ndarray, np.ndarray]:
    """Measured end poses from a CSV file: q1..q6 (rad), x y z (m), rx ry rz (rotation
    vector, rad), one pose a line; '#' starts a comment.  LogError names the line."""
    Q, T = [], []
    try:
        with open(path, encoding="utf-8") as f:
            lines = f.readlines()
    except OSError as exc:
        raise LogError(path, None, f"cannot read: {exc.strerror}") from None
    except UnicodeDecodeError:
        raise LogError(path, None, "not a text CSV of measured poses (q1..q6, x, y, z, rx, ry, rz); "
                       "a recorder log of `calib record kinematics` ends in .rcilog[.xz|.gz]") from None
    for lineno, line in enumerate(lines, 1):
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        try:
            vals = np.array([float(x) for x in line.split(",")])
        except ValueError:
            raise LogError(path, lineno, f"not 12 comma-separated numbers: {line[:60]!r}") from None
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
