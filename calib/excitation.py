"""The excitation trajectory of the dynamics identification: a finite Fourier series per joint,
designed with CasADi and IPOPT to make the stacked identification regressor well conditioned.

Joint j follows (rad, s; w = 2 pi ``base_hz``, L harmonics)::

    q_j(t)   = q0_j + sum_l  a_jl / (w l) sin(w l t) - b_jl / (w l) cos(w l t)
    qd_j(t)  =        sum_l  a_jl cos(w l t) + b_jl sin(w l t)
    qdd_j(t) =        sum_l -a_jl w l sin(w l t) + b_jl w l cos(w l t)

a periodic motion that starts and ends at rest (sum_l a_jl = 0, sum_l l b_jl = 0). Every
limit is linear in (q0, a, b), so IPOPT gets them as linear constraints on a grid of
``LIMIT_POINTS`` instants per period: the joint ranges (less ``RANGE_MARGIN``), ``SPEED_SHARE``
of each joint's velocity limit and an acceleration limit (:func:`acceleration_limits`: the
data files give none). Between the grid's instants a limit may be passed a little: the
result is checked on ``CHECK_POINTS`` instants and, where needed, its oscillation (the a and b
coefficients) scaled down until it holds everywhere (the rest conditions are linear: they hold).

The objective is a smooth stand-in for the condition number: with the stacked regressor's
columns scaled to unit length (A D^-1, D the column norms, so that the result does not depend on
the units of the parameters), it minimises -log det((A D^-1)^T (A D^-1)) / p, which is zero
only when the scaled columns are orthogonal (condition number 1) and grows as the smallest
singular value falls, on ``DESIGN_POINTS`` instants per period. While the condition number
stays above ``COND_TARGET``, a second objective (``CRITERIA``) starts from the best design: the
log of the mean of 1 / eigenvalue of the same unit-column Gram matrix (log(tr(D G^-1 D) / p)),
which weighs the weakest direction far more than the log-det does (the Stanford arm's MY2 and
MZ3R columns differ only by a small inertial term: reports/identification-stanford-designs.md).
Each value and gradient comes from numpy through a CasADi callback (:func:`_objective`):
d(-log det C)/dA = -2 A (G^-1 - diag(G)^-1) / p and d tr(D G^-1 D)/dA = 2 A (diag(G^-1) -
G^-1 diag(G) G^-1) with G = A^T A, carried back to the coefficients by CasADi's reverse mode
through the generated regressor (a vector-Jacobian product, mapped over the instants). The
limits are a sparse matrix (each row holds one joint's coefficients), which keeps IPOPT's
steps cheap.

The regressor is the one the fit uses (rcci.calib.identification.regressor_columns): the generated
base regressor, the coupling of the wrist motors' rotor inertias and the per-direction friction
columns (Coulomb and viscous, for qd > 0 and qd < 0), here with (1 +- tanh(qd / ``SIGN_SPEED``)) / 2
standing for the direction. The two Coulomb columns of a joint add up to a constant, which a
gravity column nearly matches where a joint stays near one pose (the Stanford boom near
vertical): a sign-only column would hide that.
"""
from __future__ import annotations

import os
import time
from dataclasses import dataclass

import numpy as np

from rcci.calib.exceptions import CalibError

LIMIT_POINTS = 40           # instants per period where IPOPT sees the limits
CHECK_POINTS = 2000         # instants per period where the result is checked (and scaled into them)
DESIGN_POINTS = 40          # instants per period in the stacked regressor of the objective
RANGE_MARGIN = 0.1          # rad (m) kept from each end of a joint's range, at most RANGE_SHARE of it
RANGE_SHARE = 0.1
SPEED_SHARE = 0.35          # of each joint's velocity limit
ACCEL_S = 0.4               # s: the acceleration limit is the speed limit reached in this time
SIGN_SPEED = 0.05           # rad/s, the tanh's width standing for sign(qd) in the design
BASE_HZ = 0.1               # Hz: a 10 s period
HARMONICS = 5
ROUND_ITER = 40             # IPOPT iterations per round of the design
ROUNDS = 5                  # at most, while the condition number is above COND_TARGET
COND_TARGET = 50.0          # unit columns: half the goal of 100
#: the design's objectives, in the order the rounds use them (the next only while above COND_TARGET):
#: -log det of the unit-column Gram matrix / p, then log of the mean of its inverse's diagonal
CRITERIA = ("logdet", "trace")
RANK_COND = 1e8             # above: a column is a combination of others on every motion


def casadi_kernel(robot: str, name: str):
    """The generated CasADi function ``name`` of ``robot`` (rccl/kinematics/casadi/ROBOT/NAME.casadi)."""
    import casadi as ca

    import rccl.kinematics as kin

    path = os.path.join(os.path.dirname(os.path.abspath(kin.__file__)), "casadi", robot, f"{name}.casadi")
    if not os.path.exists(path):
        raise CalibError(f"robot {robot}: no generated CasADi kernel {name} ({path}); run `make derive`")
    return ca.Function.load(path)


def range_limits(robot: str) -> tuple[np.ndarray, np.ndarray]:
    """(lower, upper) per joint the excitation keeps within: the range less RANGE_MARGIN at each
    end, or less RANGE_SHARE of it where that is smaller (a short slide)."""
    from rcci.models import load_robot

    m = load_robot(robot)
    lo, hi = np.asarray(m.lower, float), np.asarray(m.upper, float)
    margin = np.minimum(RANGE_MARGIN, RANGE_SHARE * (hi - lo))
    return lo + margin, hi - margin


def acceleration_limits(robot: str) -> np.ndarray:
    """Per joint (rad/s^2 or m/s^2): the velocity limit reached in ACCEL_S, times SPEED_SHARE;
    an estimate of this project (the data files hold no acceleration limit), checked after the
    design against the current limits (:func:`torque_share`)."""
    from rcci.models import load_robot

    return SPEED_SHARE * np.asarray(load_robot(robot).max_velocity, float) / ACCEL_S


@dataclass(frozen=True)
class Excitation:
    """A designed excitation: Fourier coefficients and what the design achieved."""

    robot: str
    base_hz: float
    offset: np.ndarray            # (n,) q0, rad (m)
    a: np.ndarray                 # (n, L) rad/s
    b: np.ndarray                 # (n, L) rad/s
    seed: int
    cond_scaled: float            # condition number, columns scaled to unit length
    cond_raw: float               # the same, columns as they come (SI units)
    iterations: int
    seconds: float                # wall time of the design

    @property
    def period(self) -> float:
        return 1.0 / self.base_hz

    def state(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q, qd, qdd), each (N, n), at times ``t`` (s)."""
        return fourier_state(np.asarray(t, float), self.base_hz, self.offset, self.a, self.b)

    def as_meta(self) -> dict:
        """JSON-friendly coefficients (a log's metadata carries them)."""
        return {"robot": self.robot, "base_hz": self.base_hz, "offset": [float(x) for x in self.offset],
                "a": self.a.tolist(), "b": self.b.tolist(), "seed": self.seed,
                "cond_scaled": self.cond_scaled, "cond_raw": self.cond_raw}


def retimed(exc: Excitation, factor: float) -> Excitation:
    """The same path played ``factor`` times slower (speeds / factor, accelerations / factor^2):
    a second trajectory without a second design (its limits still hold for factor >= 1)."""
    if factor < 1:
        raise CalibError(f"retimed: factor {factor} < 1 would pass the speed limits")
    return Excitation(exc.robot, exc.base_hz / factor, exc.offset, exc.a / factor, exc.b / factor, exc.seed,
                      exc.cond_scaled, exc.cond_raw, exc.iterations, exc.seconds)


def fourier_state(t: np.ndarray, base_hz: float, offset: np.ndarray, a: np.ndarray, b: np.ndarray):
    """(q, qd, qdd) of the series at times ``t`` (numpy or CasADi coefficients)."""
    w = 2 * np.pi * base_hz
    L = a.shape[1]
    ell = np.arange(1, L + 1)
    s, c = np.sin(np.outer(t, ell) * w), np.cos(np.outer(t, ell) * w)      # (N, L)
    q = offset[None, :] + (s / (w * ell)) @ a.T - (c / (w * ell)) @ b.T
    qd = c @ a.T + s @ b.T
    qdd = (-s * w * ell) @ a.T + (c * w * ell) @ b.T
    return q, qd, qdd


def _basis(t: np.ndarray, base_hz: float, n: int, L: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Matrices P, V, Acc (N n, nx) with q, qd, qdd at ``t`` (row-major (N, n)) = M @ x for the
    decision vector x = [q0 (n), a (n L, row-major), b (n L)]."""
    N = len(t)
    w = 2 * np.pi * base_hz
    ell = np.arange(1, L + 1)
    s, c = np.sin(np.outer(t, ell) * w), np.cos(np.outer(t, ell) * w)
    nx = n + 2 * n * L
    P, V, A = (np.zeros((N * n, nx)) for _ in range(3))
    for j in range(n):
        rows = np.arange(N) * n + j
        ia, ib = n + j * L + np.arange(L), n + n * L + j * L + np.arange(L)
        P[rows, j] = 1.0
        P[np.ix_(rows, ia)], P[np.ix_(rows, ib)] = s / (w * ell), -c / (w * ell)
        V[np.ix_(rows, ia)], V[np.ix_(rows, ib)] = c, s
        A[np.ix_(rows, ia)], A[np.ix_(rows, ib)] = -s * w * ell, c * w * ell
    return P, V, A


def design_rows(robot: str):
    """A CasADi function (q, qd, qdd) -> (n, p) of one instant: the design regressor (SX)."""
    import casadi as ca

    from rcci.calib.grouping import grouping
    from rcci.calib.regressor import rotor_coupling_motors
    from rcci.calib.robot import robot_info

    f = casadi_kernel(robot, "base_regressor")
    G = np.asarray(robot_info(robot).drive.G, float)
    n = G.shape[0]
    q, qd, qdd = (ca.SX.sym(s, n) for s in ("q", "qd", "qdd"))
    cols = [f(q, qd, qdd)]
    for m in rotor_coupling_motors(G):
        full = np.outer(G[m], G[m])
        cols.append(ca.mtimes(ca.DM(full - np.diag(np.diag(full))), qdd))
    pos = 0.5 * (1 + ca.tanh(qd / SIGN_SPEED))        # the fit's per-direction friction columns
    neg = 1 - pos
    fric = ca.horzcat(ca.diag(pos), -ca.diag(neg), ca.diag(qd * pos), ca.diag(qd * neg))
    cols.append(fric[:, [t * n + j for j in range(n) for t in range(4)]])    # the fit's order: per joint
    g = grouping(robot)                        # the fit's columns (rcci.calib.grouping)
    rows = ca.times(ca.horzcat(*cols), ca.DM(g.mask))[:, list(g.keep)]
    return ca.Function("design_rows", [q, qd, qdd], [rows])


class _Problem:
    """The objective's numerical parts: A(x) and vector-Jacobian products from CasADi (reverse
    mode through the generated regressor, mapped over the design instants), the rest numpy."""

    def __init__(self, robot: str, base_hz: float, n: int, L: int, criterion: str = "logdet") -> None:
        import casadi as ca

        if criterion not in CRITERIA:
            raise CalibError(f"excitation design: unknown criterion {criterion!r} (known: {', '.join(CRITERIA)})")
        self.criterion = criterion

        M = DESIGN_POINTS
        t = np.arange(M) / (M * base_hz)
        P, V, Acc = _basis(t, base_hz, n, L)
        x = ca.MX.sym("x", P.shape[1])
        # (n, M) matrices: column k is the instant k (P's rows are instant-major)
        q, qd, qdd = (ca.reshape(ca.mtimes(ca.DM(B), x), n, M) for B in (P, V, Acc))
        rows = design_rows(robot)
        out = rows.map(M)(q, qd, qdd)                     # (n, M p): instant k's block at k p
        self.n, self.M = n, M
        self.p = rows.size2_out(0)
        adj = ca.MX.sym("adj", out.shape[0], out.shape[1])
        self.afun = ca.Function("A", [x], [out])
        self.vjp = ca.Function("vjp", [x, adj], [ca.jtimes(out, x, adj, True)])

    def matrix(self, x: np.ndarray) -> np.ndarray:
        out = np.asarray(self.afun(x))                  # (n, M p)
        return out.reshape(self.n, self.M, self.p).transpose(1, 0, 2).reshape(self.M * self.n, self.p)

    def value_grad(self, x: np.ndarray, grad: bool) -> tuple[float, np.ndarray | None]:
        A = self.matrix(x)
        G = A.T @ A
        d = np.diag(G).copy()
        sign, logdet = np.linalg.slogdet(G)
        p = G.shape[0]
        if sign <= 0 or not np.isfinite(logdet):
            return 1e3, (np.zeros_like(x) if grad else None)
        Gi = np.linalg.inv(G)
        if self.criterion == "logdet":
            f = float(-(logdet - np.log(d).sum()) / p)
        else:                       # log of the mean of 1 / eigenvalue of the unit-column Gram matrix
            h = np.diag(Gi)
            tr = float(d @ h)
            f = float(np.log(tr / p))
        if not grad:
            return f, None
        if self.criterion == "logdet":
            S = -(Gi - np.diag(1.0 / d)) / p
        else:                       # d tr(D Gi D) = tr((diag(h) - Gi diag(d) Gi) dG), dG = dA^T A + A^T dA
            S = (np.diag(h) - Gi @ np.diag(d) @ Gi) / tr
        dA = (2 * A @ S).reshape(self.M, self.n, self.p).transpose(1, 0, 2).reshape(self.n, self.M * self.p)
        return f, np.asarray(self.vjp(x, dA)).ravel()


def _objective(problem: _Problem, nx: int):
    """The CasADi callback of the objective, with its Jacobian (a second callback)."""
    import casadi as ca

    class Grad(ca.Callback):
        def __init__(self, name, opts=None):
            ca.Callback.__init__(self)
            self.construct(name, opts or {})

        def get_n_in(self): return 2
        def get_n_out(self): return 1

        def get_sparsity_in(self, i):
            return ca.Sparsity.dense(nx, 1) if i == 0 else ca.Sparsity.dense(1, 1)

        def get_sparsity_out(self, i): return ca.Sparsity.dense(1, nx)

        def eval(self, arg):
            return [problem.value_grad(np.asarray(arg[0]).ravel(), True)[1].reshape(1, -1)]

    class Objective(ca.Callback):
        def __init__(self, name, opts=None):
            ca.Callback.__init__(self)
            self.construct(name, opts or {})

        def get_n_in(self): return 1
        def get_n_out(self): return 1
        def get_sparsity_in(self, i): return ca.Sparsity.dense(nx, 1)
        def get_sparsity_out(self, i): return ca.Sparsity.dense(1, 1)

        def eval(self, arg):
            return [problem.value_grad(np.asarray(arg[0]).ravel(), False)[0]]

        def has_jacobian(self): return True

        def get_jacobian(self, name, inames, onames, opts):
            self._grad = Grad(name, opts)
            return self._grad

    return Objective("excitation_objective")


def _limits(robot: str, base_hz: float, L: int):
    """Linear constraints (matrix, lower, upper) of the limits and the rest at t = 0."""
    from rcci.models import load_robot

    m = load_robot(robot)
    n = m.n_joints
    t = np.arange(LIMIT_POINTS) / (LIMIT_POINTS * base_hz)
    P, V, Acc = _basis(t, base_hz, n, L)
    low, high = range_limits(robot)
    lo, hi = np.tile(low, len(t)), np.tile(high, len(t))
    vmax = np.tile(SPEED_SHARE * np.asarray(m.max_velocity, float), len(t))
    amax = np.tile(acceleration_limits(robot), len(t))
    P0, V0, A0 = _basis(np.zeros(1), base_hz, n, L)
    rows = [P, V, Acc, V0, A0]
    lower = [lo, -vmax, -amax, np.zeros(n), np.zeros(n)]
    upper = [hi, vmax, amax, np.zeros(n), np.zeros(n)]
    return np.vstack(rows), np.concatenate(lower), np.concatenate(upper)


def _start(robot: str, seed: int, n: int, L: int, base_hz: float, spread: float = 0.0) -> np.ndarray:
    """A feasible random start: small coefficients around the middle of the ranges, the middle
    moved by up to ``spread`` x half of each range (less the margins) when ``spread`` > 0."""
    from rcci.models import load_robot

    m = load_robot(robot)
    rng = np.random.default_rng(seed)
    mid = 0.5 * (np.asarray(m.lower, float) + np.asarray(m.upper, float))
    if spread > 0:
        lo, hi = range_limits(robot)
        mid = 0.5 * (lo + hi) + spread * np.random.default_rng([seed, 99]).uniform(-1, 1, n) * 0.5 * (hi - lo)
    a = rng.uniform(-1, 1, (n, L))
    b = rng.uniform(-1, 1, (n, L))
    a -= a.mean(axis=1, keepdims=True)                         # sum_l a = 0
    ell = np.arange(1, L + 1)
    b -= np.outer(b @ ell / (ell @ ell), ell)                 # sum_l l b = 0
    x = np.concatenate([mid, a.ravel(), b.ravel()])
    C, lo, hi = _limits(robot, base_hz, L)
    for _ in range(60):                                        # shrink into the limits
        y = C @ x
        if np.all(y >= lo - 1e-9) and np.all(y <= hi + 1e-9):
            return x
        x[n:] *= 0.7
    return x


def design(robot: str = "puma260", seed: int = 0, base_hz: float = BASE_HZ, harmonics: int = HARMONICS,
           max_iter: int = ROUND_ITER, rounds: int = ROUNDS, spread: float = 0.0,
           criteria: tuple[str, ...] = CRITERIA) -> Excitation:
    """Design the excitation of ``robot`` (deterministic for ``seed``), CasADi + IPOPT: for each
    of ``criteria`` in turn (the next from the best design so far), rounds of ``max_iter``
    iterations, each from the last, until the condition number (unit columns) is at most
    COND_TARGET or ``rounds`` are done; ``spread``: the start's offsets (``_start``). numpy's
    BLAS runs one thread meanwhile (rcci.calib.blas_threads: its workers stall on a busy machine)."""
    from rcci.calib.blas_threads import one_blas_thread

    with one_blas_thread():
        return _design(robot, seed, base_hz, harmonics, max_iter, rounds, spread, criteria)


def _design(robot: str, seed: int, base_hz: float, harmonics: int, max_iter: int, rounds: int, spread: float,
            criteria: tuple[str, ...]) -> Excitation:
    """:func:`design`'s rounds."""
    from rcci.models import load_robot

    t0 = time.monotonic()
    n, L = load_robot(robot).n_joints, harmonics
    C, lo, hi = _limits(robot, base_hz, L)
    xs, iters, best = _start(robot, seed, n, L, base_hz, spread), 0, None
    for criterion in criteria:
        solver, _callback = _solver(robot, base_hz, n, L, C, max_iter, criterion)
        for _ in range(rounds):
            sol = solver(x0=xs, lbg=lo, ubg=hi)
            xs = np.asarray(sol["x"]).ravel()
            iters += int(solver.stats()["iter_count"])
            q0, a, b = xs[:n], xs[n:n + n * L].reshape(n, L), xs[n + n * L:].reshape(n, L)
            shrink = _shrink(robot, base_hz, q0, a, b)
            trial = Excitation(robot, base_hz, q0, a * shrink, b * shrink, seed, 0.0, 0.0, iters, 0.0)
            c = condition_numbers(trial)
            if best is None or c[0] < best[1][0]:      # the surrogate is not the condition number:
                best = (trial, c)                      # keep the round that did best
            if c[0] <= COND_TARGET or solver.stats()["return_status"] == "Solve_Succeeded":
                break
        if best[1][0] <= COND_TARGET:
            break
        xs = np.concatenate([best[0].offset, best[0].a.ravel(), best[0].b.ravel()])
    exc, (cs, cr) = best
    if cs > RANK_COND:
        from rcci.calib.identification import inseparable

        raise CalibError(f"robot {robot}: no excitation identifies every column of the fit (condition number "
                         f"{cs:.1e}): {inseparable(robot)}")
    return Excitation(exc.robot, base_hz, exc.offset, exc.a, exc.b, seed, cs, cr, iters,
                      time.monotonic() - t0)


def _solver(robot: str, base_hz: float, n: int, L: int, C: np.ndarray, max_iter: int, criterion: str):
    """The CasADi IPOPT solver of one design criterion over the limits ``C`` (``_limits``) and its
    objective's callback (the caller keeps it alive while the solver runs)."""
    import casadi as ca

    nx = n + 2 * n * L
    obj = _objective(_Problem(robot, base_hz, n, L, criterion), nx)
    x = ca.MX.sym("x", nx)
    # sparse: each limit row involves one joint's coefficients only (IPOPT's KKT stays sparse)
    c, r = np.nonzero(C.T)                  # column-major, the order of CasADi's nonzeros
    Cs = ca.DM(ca.Sparsity.triplet(C.shape[0], C.shape[1], r.tolist(), c.tolist()), C[r, c])
    if not np.array_equal(np.asarray(Cs.full()), C):
        raise CalibError("excitation design: the sparse limit matrix differs from the dense one")
    nlp = {"x": x, "f": obj(x), "g": ca.mtimes(Cs, x)}
    opts = {"ipopt.hessian_approximation": "limited-memory", "ipopt.max_iter": max_iter,
            "ipopt.print_level": 0, "print_time": False, "ipopt.tol": 1e-6,
            "ipopt.acceptable_tol": 1e-4, "ipopt.acceptable_iter": 5,
            "ipopt.jac_c_constant": "yes", "ipopt.jac_d_constant": "yes", "ipopt.mu_strategy": "adaptive"}
    return ca.nlpsol(f"excitation_{criterion}", "ipopt", nlp, opts), obj


def _shrink(robot: str, base_hz: float, q0: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """The largest factor <= 1 on (a, b) that keeps the motion inside every limit at CHECK_POINTS
    instants; CalibError when the offset itself is outside the range."""
    from rcci.models import load_robot

    m = load_robot(robot)
    lo, hi = range_limits(robot)
    if np.any(q0 < lo) or np.any(q0 > hi):
        raise CalibError(f"robot {robot}: the excitation's mean pose {np.round(q0, 3).tolist()} is outside the "
                         "joint ranges less their margin")
    t = np.arange(CHECK_POINTS) / (CHECK_POINTS * base_hz)
    q, qd, qdd = fourier_state(t, base_hz, q0, a, b)
    osc = q - q0
    with np.errstate(divide="ignore", invalid="ignore"):
        pos = np.where(osc > 0, (hi - q0) / osc, np.where(osc < 0, (lo - q0) / osc, np.inf))
        vel = SPEED_SHARE * np.asarray(m.max_velocity, float) / np.abs(qd)
        acc = acceleration_limits(robot) / np.abs(qdd)
    # 0.1 % below the tightest: between the check instants a peak can rise by ~(pi L / CHECK_POINTS)^2 / 2
    return float(min(1.0, np.nanmin(pos), np.nanmin(vel), np.nanmin(acc)) * (1 - 1e-3))


def condition_numbers(exc: Excitation, points: int = 400) -> tuple[float, float]:
    """Condition numbers of the fit's stacked regressor (rcci.calib.identification, per-direction
    friction columns) over one period at ``points`` instants, with the rows the fit uses (a
    joint's equation where it moves faster than its still speed): columns scaled to unit
    length, and as they come."""
    from rcci.calib.identification import regressor_columns, regressor_width, still_speeds

    t = np.arange(points) * exc.period / points
    q, qd, qdd = exc.state(t)
    Y = regressor_columns(exc.robot, q, qd, qdd)
    A = Y[np.abs(qd) >= still_speeds(exc.robot)].reshape(-1, regressor_width(exc.robot))
    norms = np.linalg.norm(A, axis=0)
    if np.any(norms == 0):
        return float("inf"), float("inf")
    return float(np.linalg.cond(A / norms)), float(np.linalg.cond(A))


def weakest_directions(exc: Excitation, k: int = 2, points: int = 400) -> list[tuple[float, str]]:
    """The ``k`` smallest singular values of the fit's unit-column regressor over one period (as
    :func:`condition_numbers`) with their singular vectors in words (entries above 0.1)."""
    from rcci.calib.identification import column_names, regressor_columns, regressor_width, still_speeds

    t = np.arange(points) * exc.period / points
    q, qd, qdd = exc.state(t)
    Y = regressor_columns(exc.robot, q, qd, qdd)
    A = Y[np.abs(qd) >= still_speeds(exc.robot)].reshape(-1, regressor_width(exc.robot))
    A = A / np.linalg.norm(A, axis=0)
    _, s, vt = np.linalg.svd(A, full_matrices=False)
    names = column_names(exc.robot)
    return [(float(s[-i] / s[0]), " ".join(f"{vt[-i][j]:+.2f} {names[j]}" for j in np.argsort(-np.abs(vt[-i]))
                                           if abs(vt[-i][j]) > 0.1)) for i in range(1, k + 1)]


def torque_share(exc: Excitation, points: int = 400) -> np.ndarray:
    """Per motor, the largest share of its current limit the data-file model (inverse dynamics
    plus Coulomb and viscous friction) needs along the excitation."""
    import rccl.kinematics as kin
    from rcci.calib.robot import robot_info
    from rcci.models import load_robot

    mod = kin.load(exc.robot)
    info = robot_info(exc.robot)
    m = load_robot(exc.robot)
    t = np.arange(points) * exc.period / points
    q, qd, qdd = exc.state(t)
    fr = info.nominal["friction"]
    fc = 0.5 * (np.asarray(fr["coulomb_pos"]["values"], float) + np.asarray(fr["coulomb_neg"]["values"], float))
    fv = 0.5 * (np.asarray(fr["viscous_pos"]["values"], float) + np.asarray(fr["viscous_neg"]["values"], float))
    tau = np.array([mod.inverse_dynamics(q[k], qd[k], qdd[k]) for k in range(points)])
    tau += fc * np.sign(qd) + fv * qd
    G = np.asarray(info.drive.G, float)
    ts = np.linalg.solve(G.T, tau.T).T
    lim = np.asarray(m.max_current, float) * np.asarray(info.drive.sigma, float)
    return np.abs(ts).max(axis=0) / lim
