"""The physically consistent variant of the dynamics fit: link inertials in log-Cholesky form,
fitted with CasADi + IPOPT, mapped back to base parameters.

Each link k (in its DH frame) is ten numbers theta = (alpha, d1, d2, d3, s12, s23, s13, t1, t2,
t3) giving the upper-triangular

    U = e^alpha [[e^d1, s12, s13, t1], [0, e^d2, s23, t2], [0, 0, e^d3, t3], [0, 0, 0, 1]]

and the pseudo-inertia J = U U^T = [[S, h], [h^T, m]] (S = tr(I_o)/2 1 - I_o, h = m c): any
theta gives a positive mass and an inertia about the centre of mass whose principal moments
satisfy the triangle inequalities (J positive definite), and every such link has a theta. The
motors' rotor inertias are e^r_m (six numbers: positive), reflected through G as simula and a
real drive train do (G^T diag(J_m) G: its diagonal the generated IA columns, its off-diagonal
rcci.calib.identification's JM columns). Friction coefficients are bounded at zero.

The cost is the weighted least squares cost of the unconstrained fit, written with its normal
matrix: (x(theta) - x_wls)^T A_w^T A_w (x(theta) - x_wls), x(theta) the base parameters of the
generated ``base_parameters`` (CasADi) with the rotor and friction columns, grouped as the fit's
columns are (rcci.calib.grouping). It starts from the data file's inertials.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from rcci.calib.exceptions import CalibError

EPS_INERTIA = 1e-6     # kg m^2 added to each principal axis of the start (a data-file link may be flat)


@dataclass
class ConsistentResult:
    """The consistent fit: its parameters (the WLS's columns), links, cost and time."""

    value: np.ndarray
    masses: np.ndarray            # (n,) kg
    com: np.ndarray               # (n, 3) m
    inertia: np.ndarray           # (n, 6) about the centre of mass: xx yy zz xy xz yz
    rotor: np.ndarray             # (n,) kg m^2 per motor
    cost_ratio: float             # weighted residual sum of squares / the unconstrained fit's (>= 1)
    status: str
    seconds: float


def _pseudo(m: float, c: np.ndarray, ic: np.ndarray) -> np.ndarray:
    io = ic + m * (c @ c * np.eye(3) - np.outer(c, c))
    J = np.zeros((4, 4))
    J[:3, :3] = 0.5 * np.trace(io) * np.eye(3) - io
    J[:3, 3] = J[3, :3] = m * c
    J[3, 3] = m
    return J


def _theta_of(J: np.ndarray) -> np.ndarray:
    """log-Cholesky numbers of a positive definite pseudo-inertia."""
    P = np.eye(4)[::-1]
    U = P @ np.linalg.cholesky(P @ J @ P) @ P
    e = U[3, 3]
    V = U / e
    return np.array([np.log(e), np.log(V[0, 0]), np.log(V[1, 1]), np.log(V[2, 2]),
                     V[0, 1], V[1, 2], V[0, 2], V[0, 3], V[1, 3], V[2, 3]])


def _links_of(th):
    """CasADi: (m, c (3,), I about c (3x3)) of one link's ten numbers."""
    import casadi as ca

    a, d1, d2, d3, s12, s23, s13, t1, t2, t3 = (th[i] for i in range(10))
    U = ca.exp(a) * ca.vertcat(ca.horzcat(ca.exp(d1), s12, s13, t1), ca.horzcat(0, ca.exp(d2), s23, t2),
                               ca.horzcat(0, 0, ca.exp(d3), t3), ca.horzcat(0, 0, 0, 1))
    J = ca.mtimes(U, U.T)
    m = J[3, 3]
    h = J[0:3, 3]
    S = J[0:3, 0:3]
    io = ca.trace(S) * ca.DM.eye(3) - S
    c = h / m
    ic = io - m * (ca.dot(c, c) * ca.DM.eye(3) - ca.mtimes(c, c.T))
    return m, c, ic


def fit_consistent(robot: str, x_wls: np.ndarray, H: np.ndarray, rss: float,
                   max_iter: int = 300) -> ConsistentResult:
    """The consistent fit (module docstring); ``H`` the weighted normal matrix A_w^T A_w, ``rss``
    the unconstrained fit's weighted residual sum of squares."""
    import casadi as ca

    from rcci.calib.excitation import casadi_kernel
    from rcci.calib.grouping import grouping
    from rcci.calib.regressor import rotor_coupling_motors
    from rcci.calib.robot import robot_info
    from rcci.models import load_robot

    t0 = time.monotonic()
    model = load_robot(robot)
    n = model.n_joints
    G = np.asarray(robot_info(robot).drive.G, float)
    coupled = rotor_coupling_motors(G)
    th = ca.SX.sym("theta", 10 * n)
    r = ca.SX.sym("r", n)                     # log rotor inertias per motor
    fr = ca.SX.sym("f", 4 * n)
    ms, coms, rows = [], [], []
    for k in range(n):
        m, c, ic = _links_of(th[10 * k:10 * k + 10])
        ms.append(m)
        coms.append(c.T)
        rows.append(ca.horzcat(ic[0, 0], ic[1, 1], ic[2, 2], ic[0, 1], ic[0, 2], ic[1, 2]))
    jr = ca.exp(r)
    rotor_diag = ca.mtimes(ca.DM(G.T ** 2), jr)       # sum_m J_m G_mj^2
    beta = casadi_kernel(robot, "base_parameters")(ca.vertcat(*ms), ca.vertcat(*coms), ca.vertcat(*rows),
                                                    rotor_diag)
    x = ca.mtimes(ca.DM(grouping(robot).K), ca.vertcat(beta, *[jr[m] for m in coupled], fr))
    e = x - ca.DM(x_wls)
    cost = ca.mtimes([e.T, ca.DM(H), e])
    z = ca.vertcat(th, r, fr)
    start = []
    for li in model.links:
        ic = np.asarray(li.inertia, float) + EPS_INERTIA * np.eye(3)
        start.append(_theta_of(_pseudo(float(li.mass), np.asarray(li.com, float), ic)))
    jr0 = np.where(np.arange(n) < 3, 2e-5, 5e-6)
    f0 = np.maximum(np.asarray(x_wls[-4 * n:], float), 0.0)
    z0 = np.concatenate([np.concatenate(start), np.log(jr0), f0])
    lbx = np.concatenate([np.full(10 * n + n, -np.inf), np.zeros(4 * n)])
    scale = float(np.trace(H)) / len(x_wls) or 1.0
    solver = ca.nlpsol("consistent", "ipopt", {"x": z, "f": cost / scale},
                       {"ipopt.print_level": 0, "print_time": False, "ipopt.max_iter": max_iter,
                        "ipopt.tol": 1e-10})
    sol = solver(x0=z0, lbx=lbx)
    zs = np.asarray(sol["x"]).ravel()
    fx = ca.Function("x", [z], [x, ca.vertcat(*ms), ca.vertcat(*coms), ca.vertcat(*rows), jr])
    xv, mv, cv, iv, rv = (np.asarray(v) for v in fx(zs))
    xv = xv.ravel()
    if not np.all(np.isfinite(xv)):
        raise CalibError(f"robot {robot}: the consistent fit did not converge ({solver.stats()['return_status']})")
    extra = float((xv - x_wls) @ H @ (xv - x_wls))
    return ConsistentResult(xv, mv.ravel(), cv.reshape(n, 3), iv.reshape(n, 6), rv.ravel(),
                            (rss + extra) / rss if rss > 0 else float("inf"), solver.stats()["return_status"],
                            time.monotonic() - t0)
