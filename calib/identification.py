"""Identification of the dynamics' base parameters from excitation logs: the regressor the fit
uses, the processing of a log into stacked rows, weighted least squares with 99.73 % intervals.

The model (joint level, SI, thesis 4.6 plus friction 4.27)::

    G^T sigma i = Y_b(q, qd, qdd) beta + sum_m J_m (G_m^T G_m - diag) qdd + friction(qd)

* ``Y_b beta``: the generated base regressor (rccl.kinematics, derive.dynamics_base), which
  holds a diagonal rotor inertia per joint (IA_j qdd_j, IA1 and IA2 grouped into ZZ1R, ZZ2R);
* what the generated regressor lacks, computed here: a motor that drives several joints (the
  PUMA's wrist motors 5 and 6, G rows with more than one entry) reflects its rotor inertia
  J_m as G_m^T G_m, whose diagonal the IA columns hold and whose off-diagonal part is one
  more column per such motor (parameter ``JM<m>``, kg m^2 at the motor);
* friction per joint and direction (the fields of eq. 4.27): ``FC<j>+``/``FC<j>-`` Coulomb
  (N m), ``FV<j>+``/``FV<j>-`` viscous (N m s/rad).

Processing of a log (:func:`rows_of_trace`): encoder angles through a zero-phase Butterworth
low-pass (``ORDER``, cut-off ``CUTOFF_HZ``, forward and backward: rcci.calib.filters), velocities and accelerations
by central differences of the filtered angles; the measured torque G^T sigma i from the ADC
(rcci.calib.drive); the model side passed through the current-sense filter of Appendix C (a
first-order lag of ``drive.FILTER_TAU`` that the ADC reading went through: the regressor rows
of each cycle's interval, averaged over its two ends, enter the same recursion), then both
sides through the same zero-phase low-pass, decimated to ``DECIMATE_HZ`` and trimmed by
``EDGE_S`` at both ends. Joint j's equation at an instant is left out when |qd_j| <
``STILL_SPEED`` (sticking, breakaway: friction there is not a function of qd) or when an ADC
channel of its motors is at its rail, and ``STILL_WINDOW_S`` either side of such an instant
(the low-pass spreads the stick over its neighbours).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rcci.calib.exceptions import CalibError, LogError
from rcci.calib.grouping import grouping
from rcci.calib.regressor import fitted_joints, full_regressor_columns, gear

ORDER = 4
CUTOFF_HZ = 4.0          # Hz: 8 x the excitation's highest harmonic (0.5 Hz)
NOISE_CUTOFF_HZ = 4.0    # Hz: what the measured torque holds above it is taken as its noise (current_noise)
DECIMATE_HZ = 20.0       # Hz: rows kept after the low-pass (5 x the cut-off)
EDGE_S = 1.0             # s trimmed at each end (the zero-phase filter's start-up)
STILL_SPEED = 0.1        # rad/s (m/s), or STILL_SHARE of the joint's velocity limit where smaller (slides)
STILL_SHARE = 0.035      # a tenth of the share of it the excitation uses (rcci.calib.excitation.SPEED_SHARE)
JACKKNIFE_BLOCKS = 10    # spans of time of the block jackknife (jackknife_error)
STILL_WINDOW_S = 0.15   # s either side of a slow instant also left out (the low-pass smears it)
MIN_SECONDS = 5.0        # a log shorter than this is refused


def still_speeds(robot: str) -> np.ndarray:
    """Per joint, the speed under which its equation is left out (module docstring)."""
    from rcci.models import load_robot

    return np.minimum(STILL_SPEED, STILL_SHARE * np.asarray(load_robot(robot).max_velocity, float))


def identifiable(robot: str) -> str | None:
    """None when random moving states separate every column of the fit (after the grouping of
    rcci.calib.grouping), else why not (:func:`inseparable`): checked before an arm's excitation
    is designed or recorded."""
    A = _random_rows(robot, seed=1)
    nrm = np.linalg.norm(A, axis=0)
    if np.all(nrm > 0) and np.linalg.cond(A / nrm) < 1e8:
        return None
    return inseparable(robot)


def inseparable(robot: str) -> str:
    """Which columns of the fit no motion separates (a null vector of the unit-column regressor
    on random states, moving joints only), in words."""
    A = _random_rows(robot, seed=0)
    nrm = np.linalg.norm(A, axis=0)
    names = column_names(robot)
    dead = [names[k] for k in np.flatnonzero(nrm == 0)]
    if dead:
        return f"no equation depends on {', '.join(dead)}"
    v = np.linalg.svd(A / nrm, full_matrices=False)[2][-1]
    big = [f"{v[k]:+.2f} {names[k]}" for k in np.argsort(-np.abs(v)) if abs(v[k]) > 0.05]
    return ("on every motion the columns combine to zero as " + " ".join(big)
            + " (friction and rotor columns alone: no rigid-body parameter to fold into them)")


def _random_rows(robot: str, seed: int) -> np.ndarray:
    """The fit's regressor stacked over rcci.calib.grouping.random_states."""
    from rcci.calib.grouping import random_states
    from rcci.models import load_robot

    m = load_robot(robot)
    q, qd, qdd = random_states(len(m.lower), np.asarray(m.lower, float), np.asarray(m.upper, float), seed=seed)
    return regressor_columns(robot, q, qd, qdd).reshape(-1, regressor_width(robot))


def column_names(robot: str) -> tuple[str, ...]:
    """Names of the fit's columns: :func:`full_column_names` after the grouping
    (rcci.calib.grouping: e.g. the Microbo's M2 folded into IA2R, FC2+R, FC2-R)."""
    return grouping(robot).names


def regressor_width(robot: str) -> int:
    return len(column_names(robot))


def regressor_columns(robot: str, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
    """(N, n, p): joint torques = this @ the parameters of :func:`column_names`, at each row."""
    return grouping(robot).columns(full_regressor_columns(robot, q, qd, qdd))


@dataclass
class Rows:
    """Stacked equations of one or more logs: A x = y, row k is joint ``joint[k]``."""

    A: np.ndarray           # (m, p)
    y: np.ndarray           # (m,) N m (N)
    joint: np.ndarray       # (m,) 0-based
    noise: np.ndarray       # (n,) per-joint sd of the raw measured torque's noise (N m)
    seconds: float          # span of the logs used
    time: np.ndarray        # (m,) s of each row from the first log's first row used (logs end to end)
    period: float = 0.0     # s: the excitation's period, whose path the log repeats (0: not periodic)

    @staticmethod
    def stack(parts: "list[Rows]") -> "Rows":
        noise = np.sqrt(np.mean([p.noise ** 2 for p in parts], axis=0))
        start = np.concatenate([[0.0], np.cumsum([p.seconds for p in parts])[:-1]])
        periods = {p.period for p in parts}
        return Rows(np.vstack([p.A for p in parts]), np.concatenate([p.y for p in parts]),
                    np.concatenate([p.joint for p in parts]), noise, sum(p.seconds for p in parts),
                    np.concatenate([p.time + s for p, s in zip(parts, start)]),
                    periods.pop() if len(periods) == 1 else 0.0)


def lowpass(rate_hz: float):
    """The zero-phase Butterworth low-pass of the module docstring at ``rate_hz``, along axis 0
    (rcci.calib.filters)."""
    from rcci.calib.filters import zero_phase_lowpass

    if rate_hz <= 4 * max(CUTOFF_HZ, NOISE_CUTOFF_HZ):
        raise CalibError(f"a dynamics log needs a rate above {4 * max(CUTOFF_HZ, NOISE_CUTOFF_HZ):g} Hz, "
                         f"not {rate_hz:g} Hz")
    return lambda x: zero_phase_lowpass(x, ORDER, CUTOFF_HZ, rate_hz)


def current_filter(x: np.ndarray, rate_hz: float, tau: float) -> np.ndarray:
    """Model side of the current-sense filter: rows of each cycle's interval (mean of its two
    ends) through the first-order lag ``tau`` (s) sampled at ``rate_hz``; row 0 at rest."""
    from rcci.calib.filters import first_order_lag

    a = float(np.exp(-1.0 / (rate_hz * tau))) if tau > 0 else 0.0
    mid = 0.5 * (x[1:] + x[:-1])
    return np.concatenate([x[:1], first_order_lag(mid, a, x[0])])


def measurement(trace, drive) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t, q, measured joint torque) of a log, each row an instant; LogError when it is too
    short or not at a constant rate."""
    t = np.asarray(trace.t, float)
    if len(t) < 2 or t[-1] - t[0] < MIN_SECONDS:
        raise LogError(trace.path, None, f"only {t[-1] - t[0] if len(t) > 1 else 0:.2f} s of records: a "
                       f"dynamics fit needs at least {MIN_SECONDS:g} s of excitation")
    dt = np.diff(t)
    if np.ptp(dt) > 1e-6 * dt.mean():
        k = int(np.argmax(np.abs(dt - np.median(dt)) > 1e-6 * dt.mean())) + 1
        raise LogError(trace.path, trace.first_record + k, "the sample rate changes: a dynamics log is "
                       "recorded at one rate (its filters assume it)")
    return t, drive.joint_angles(trace.counts), drive.joint_torques(trace.adc)


def joint_motion(trace, drive, offset: np.ndarray | None = None):
    """One excitation log as the fit and the held-out check both read it: times t (s), the sample
    rate (Hz), the low-pass filter at that rate, the filtered joint angles q (rad, ``offset`` added:
    the fitted joint offsets), their rates qd and accelerations qdd (central differences), and the
    measured joint torques tau (N m, unfiltered)."""
    t, q_raw, tau = measurement(trace, drive)
    rate = 1.0 / float(np.mean(np.diff(t)))
    lp = lowpass(rate)
    q = lp(q_raw) + (0.0 if offset is None else np.asarray(offset, float))
    qd = np.gradient(q, t, axis=0)
    qdd = np.gradient(qd, t, axis=0)
    return t, rate, lp, q, qd, qdd, tau


def current_noise(t: np.ndarray, tau: np.ndarray, rate: float) -> np.ndarray:
    """Per joint, the sd (N m) of the measured torque's noise: what a zero-phase low-pass at
    ``NOISE_CUTOFF_HZ`` removes inside the log's edges, scaled up for the band it keeps."""
    from rcci.calib.filters import zero_phase_lowpass

    inner = (t >= t[0] + EDGE_S) & (t <= t[-1] - EDGE_S)
    high = tau - zero_phase_lowpass(tau, ORDER, NOISE_CUTOFF_HZ, rate)
    return np.std(high[inner], axis=0) * np.sqrt(rate / 2 / (rate / 2 - NOISE_CUTOFF_HZ))


def rows_of_trace(trace, drive, robot: str, offset: np.ndarray | None = None) -> Rows:
    """The stacked equations of one excitation log (module docstring); ``offset`` (rad, per
    joint) the fitted joint offsets (d theta of ``[kinematics]``) added to the encoder angles
    (the regressor is the arm's at its true angles, as the gravity fit's)."""
    from rcci.calib.drive import FILTER_TAU
    from rcci.calib.logs import ADC_RAIL

    t, rate, lp, q, qd, qdd, tau = joint_motion(trace, drive, offset)
    Y = regressor_columns(robot, q, qd, qdd)
    N, n, p = Y.shape
    Yf = lp(current_filter(Y.reshape(N, n * p), rate, FILTER_TAU)).reshape(N, n, p)
    tf = lp(tau)
    noise = current_noise(t, tau, rate)
    step = max(1, int(round(rate / DECIMATE_HZ)))
    keep = np.arange(0, N, step)
    keep = keep[(t[keep] >= t[0] + EDGE_S) & (t[keep] <= t[-1] - EDGE_S)]
    G = gear(robot)
    rail = np.abs(trace.adc) >= ADC_RAIL                       # (N, n) motors
    joint_rail = (rail.astype(float) @ (G != 0).astype(float)) > 0
    A, y, js, ts = [], [], [], []
    slow = _dilate(np.abs(qd) < still_speeds(robot), int(round(STILL_WINDOW_S * rate)))
    for j in fitted_joints(robot):
        ok = keep[~slow[keep, j] & ~joint_rail[keep, j]]
        A.append(Yf[ok, j, :])
        y.append(tf[ok, j])
        js.append(np.full(len(ok), j))
        ts.append(t[ok] - t[0] - EDGE_S)
    base_hz = float(trace.meta.get("excitation", {}).get("base_hz", 0.0) or 0.0)
    return Rows(np.vstack(A), np.concatenate(y), np.concatenate(js), noise, float(t[-1] - t[0] - 2 * EDGE_S),
                np.concatenate(ts), 1.0 / base_hz if base_hz > 0 else 0.0)


def _dilate(mask: np.ndarray, k: int) -> np.ndarray:
    """``mask`` (N, n) widened by ``k`` rows either side, per column."""
    if k <= 0:
        return mask
    c = np.cumsum(np.vstack([np.zeros((1, mask.shape[1])), mask.astype(float)]), axis=0)
    N = len(mask)
    lo = np.clip(np.arange(N) - k, 0, N)
    hi = np.clip(np.arange(N) + k + 1, 0, N)
    return (c[hi] - c[lo]) > 0


@dataclass
class WlsResult:
    """Weighted least squares of the dynamics: values, 99.73 % half-widths, the figures behind."""

    names: tuple[str, ...]
    value: np.ndarray
    error: np.ndarray            # 99.73 % half-widths
    sd: np.ndarray               # standard deviations (after the correlation inflation)
    cov: np.ndarray              # covariance of value (the same inflation)
    joint_sd: np.ndarray         # (n,) residual sd per joint (the weights' 1/sqrt)
    inflation: np.ndarray        # (n,) per joint, 1 + 2 sum of the residuals' autocorrelations
    dof: int
    factor: float                # coverage factor (Student's t, 99.73 %)
    rows: int
    cond_scaled: float           # condition number of the weighted, unit-column regressor
    jackknife: np.ndarray        # the block jackknife's 99.73 % half-widths (``error`` is the larger)


def _inflation(r: np.ndarray, lags: int = 20) -> float:
    """1 + 2 sum_k rho_k of a residual sequence, summed while rho_k > 0 (at least 1)."""
    r = r - r.mean()
    v = float(r @ r)
    if v == 0 or len(r) < 3:
        return 1.0
    s = 0.0
    for k in range(1, min(lags, len(r) - 1) + 1):
        rho = float(r[:-k] @ r[k:]) / v
        if rho <= 0:
            break
        s += rho
    return max(1.0, 1.0 + 2.0 * s)


def _repeat(r: np.ndarray, t: np.ndarray, period: float, seconds: float) -> float:
    """1 + (K - 1) rho_P: how much a residual that repeats with the excitation's path inflates the
    variance, K = ``seconds`` / ``period`` periods in the rows, rho_P (>= 0) the correlation of
    the residuals ``r`` at times ``t`` with those one period later (1 when there are no such pairs)."""
    if period <= 0 or seconds <= period:
        return 1.0
    k = np.searchsorted(t, t + period - 1e-6)
    ok = k < len(t)
    ok[ok] &= np.abs(t[k[ok]] - t[ok] - period) < 1e-6
    if np.count_nonzero(ok) < 10:
        return 1.0
    a, b = r[ok] - r[ok].mean(), r[k[ok]] - r[k[ok]].mean()
    den = float(np.sqrt((a @ a) * (b @ b)))
    rho = max(0.0, float(a @ b) / den) if den > 0 else 0.0
    return 1.0 + (seconds / period - 1.0) * rho


def wls(rows: Rows, names: tuple[str, ...]) -> WlsResult:
    """Two-pass weighted least squares: ordinary LS for each joint's residual sd, then rows
    weighted by 1/sd_j^2. Covariance s^2 (A^T W A)^-1 with each joint's rows' share of it
    inflated by that joint's residual autocorrelation (``_inflation``: the rows of a filtered,
    decimated signal are not independent) and by its repetition from one period of the
    excitation to the next (``_repeat``: the residual is mostly a function of the path, the
    position-dependent friction of Table 4.4 and what else the model lacks, so the periods of
    one path are not independent samples of it; measured on the PUMA 260's hidden truth, the
    residuals one period apart correlate at 0.89-1.0); half-widths: the larger of Student's t (99.73 %, dof
    = effective rows - parameters) x sd and the block jackknife's (``jackknife_error``)."""
    from rcci.calib.lsq import coverage_factor

    A, y, js = rows.A, rows.y, rows.joint
    m, p = A.shape
    if m <= p:
        raise CalibError(f"the dynamics fit has {m} equations for {p} parameters: record longer excitations")
    n = int(js.max()) + 1
    x0, *_ = np.linalg.lstsq(A, y, rcond=None)
    r0 = y - A @ x0
    sd_j = np.array([np.std(r0[js == j]) if np.any(js == j) else 1.0 for j in range(n)])
    sd_j = np.where(sd_j > 0, sd_j, 1.0)
    w = 1.0 / sd_j[js]
    Aw, yw = A * w[:, None], y * w
    scale = np.linalg.norm(Aw, axis=0)
    if np.any(scale == 0):
        dead = [names[k] for k in np.flatnonzero(scale == 0)]
        raise CalibError(f"the excitation logs do not excite {', '.join(dead)}: no equation depends on them")
    As = Aw / scale
    U, s, Vt = np.linalg.svd(As, full_matrices=False)
    cond = float(s[0] / s[-1])
    if cond > 1e8:
        v = Vt[-1]
        big = " ".join(f"{v[k]:+.2f} {names[k]}" for k in np.argsort(-np.abs(v)) if abs(v[k]) > 0.05)
        raise CalibError(f"the dynamics logs do not separate the columns {big} (condition number {cond:.1e}): "
                         "record an excitation that moves every joint both ways")
    xs = Vt.T @ ((U.T @ yw) / s)
    x = xs / scale
    res = yw - Aw @ x
    s2 = float(res @ res) / (m - p)
    infl = np.array([_inflation(res[js == j]) * _repeat(res[js == j], rows.time[js == j], rows.period, rows.seconds)
                     if np.any(js == j) else 1.0 for j in range(n)])      # a joint left out has no rows
    Ainv = (Vt.T / s) @ U.T / scale[:, None]                 # x = Ainv @ yw
    cov = s2 * (Ainv * infl[js][None, :]) @ Ainv.T
    sd = np.sqrt(np.diag(cov))
    eff = int(max(p + 1, round(sum(np.sum(js == j) / infl[j] for j in range(n)))))
    factor = coverage_factor(eff - p)
    resid_sd = np.array([np.std((y - A @ x)[js == j]) if np.any(js == j) else np.nan for j in range(n)])
    jk = jackknife_error(rows, sd_j)
    return WlsResult(names, x, np.maximum(factor * sd, jk), sd, cov, resid_sd, infl, eff - p, factor, m, cond, jk)


def jackknife_error(rows: Rows, joint_sd: np.ndarray, blocks: int = JACKKNIFE_BLOCKS) -> np.ndarray:
    """99.73 % half-widths from the delete-one-block jackknife over ``blocks`` equal spans of
    time (Student's t with blocks - 1 degrees of freedom): what changes from one stretch of the
    trajectory to another (friction that varies with position, sticking) widens it. When the
    rows repeat a periodic path (``rows.period``), the spans are of its phase, each taken out of
    every period at once."""
    from rcci.calib.lsq import coverage_factor

    if rows.period > 0 and rows.seconds > rows.period:
        # the rows repeat one path: a block is a span of its phase, in every period (else the
        # same stretch of path stays in the fit through its other copies)
        k = np.minimum((np.mod(rows.time, rows.period) / rows.period * blocks).astype(int), blocks - 1)
    else:
        k = np.minimum((rows.time / max(rows.seconds, 1e-9) * blocks).astype(int), blocks - 1)
    w = 1.0 / joint_sd[rows.joint]
    est = []
    for b in range(blocks):
        m = k != b
        if np.count_nonzero(m) <= rows.A.shape[1]:
            return np.zeros(rows.A.shape[1])
        x, *_ = np.linalg.lstsq(rows.A[m] * w[m, None], rows.y[m] * w[m], rcond=None)
        est.append(x)
    est = np.array(est)
    sd = np.sqrt((blocks - 1) / blocks * ((est - est.mean(axis=0)) ** 2).sum(axis=0))
    return coverage_factor(blocks - 1) * sd
