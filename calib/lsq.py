"""Least squares with bounds (CasADi QP) and the parameter covariance of a linear fit."""
from __future__ import annotations

import functools
from dataclasses import dataclass

import casadi as ca
import numpy as np

from rcci.calib.exceptions import FitError

# The uncertainty calib prints beside a fitted value (Tables 4.2, 4.3, the kinematic errors)
# is a 99.73 % interval: three standard deviations when the standard deviation is known,
# Student's t quantile for the fit's degrees of freedom when it is estimated from the
# residuals of few points (coverage_factor). The thesis printed two standard deviations
# (4.5.4), under which one value in twenty lies outside by chance alone; this makes "the
# truth lies within the printed uncertainty" a claim that holds for every value of a
# calibration (docs/calib.md).
PRINTED_SD = 3.0
COVERAGE = 0.9973      # two-sided, the normal distribution's +-3 sd


@functools.lru_cache(maxsize=None)
def coverage_factor(dof: int) -> float:
    """Half-width of the two-sided COVERAGE interval in standard deviations estimated with
    ``dof`` degrees of freedom: Student's t quantile (3.0 as dof grows; 4.0 at 8, 19 at 2).
    Computed by integrating the t density (no SciPy dependency)."""
    if dof <= 0:
        return float("inf")
    if dof > 2000:
        return PRINTED_SD
    import math

    nu = float(dof)
    log_c = math.lgamma((nu + 1) / 2) - math.lgamma(nu / 2) - 0.5 * math.log(nu * math.pi)
    x = np.linspace(0.0, 400.0, 400001)
    pdf = np.exp(log_c - (nu + 1) / 2 * np.log1p(x * x / nu))
    cdf = 0.5 + np.concatenate([[0.0], np.cumsum(0.5 * (pdf[1:] + pdf[:-1]) * np.diff(x))])
    return float(np.interp(0.5 + COVERAGE / 2, cdf, x))


@dataclass(frozen=True)
class LinearFit:
    """Result of fitting y ~ A x.

    ``std`` is each parameter's standard deviation from the fit (residual variance
    times (A^T A)^-1); a parameter held on a bound gets the standard deviation it would
    have with the others free, so the error never reads as zero.
    """

    x: np.ndarray
    std: np.ndarray
    residual_std: float
    n: int
    active: np.ndarray

    @property
    def dof(self) -> int:
        """Degrees of freedom of the residual variance: observations less free parameters."""
        return max(self.n - len(self.x) + int(self.active.sum()), 1)


def bounded_lsq(A: np.ndarray, y: np.ndarray, lower: np.ndarray | None = None,
                what: str = "fit") -> LinearFit:
    """Minimise ||A x - y||^2 subject to x >= lower (CasADi's active-set QP, qrqp).

    Raises FitError when there are fewer observations than parameters or A has
    dependent columns (the data do not determine the parameters).
    """
    A = np.atleast_2d(np.asarray(A, dtype=float))
    y = np.asarray(y, dtype=float).ravel()
    n, p = A.shape
    if n < p:
        raise FitError(f"{what}: {n} observations cannot determine {p} parameters")
    if np.linalg.matrix_rank(A) < p:
        raise FitError(f"{what}: the observations do not separate the {p} parameters "
                       "(e.g. every run at the same speed)")
    H = A.T @ A
    g = -A.T @ y
    lb = np.full(p, -np.inf) if lower is None else np.asarray(lower, dtype=float)
    x_free = np.linalg.solve(H, -g)
    if np.all(x_free >= lb):
        x = x_free
    else:
        qp = {"h": ca.Sparsity.dense(p, p)}
        solver = ca.conic("bounded_lsq", "qrqp", qp,
                          {"print_iter": False, "print_header": False, "print_info": False,
                           "error_on_fail": True})
        sol = solver(h=ca.DM(H), g=ca.DM(g), lbx=ca.DM(lb), ubx=ca.DM(np.full(p, np.inf)))
        # the active-set solver may land a hair outside a bound (-1e-19): put it on it,
        # since a consumer checks "friction >= 0" literally
        x = np.maximum(np.array(sol["x"]).ravel(), lb)
    active = np.isclose(x, lb) & (x_free < lb)
    resid = A @ x - y
    dof = max(n - p, 1)
    s2 = float(resid @ resid) / dof
    cov = s2 * np.linalg.inv(H)
    return LinearFit(x=x, std=np.sqrt(np.diag(cov)), residual_std=float(np.sqrt(s2)),
                     n=n, active=active)
