"""The dynamics fit end to end: excitation logs -> weighted least squares of the base parameters
(rcci.calib.identification) -> the physically consistent variant (rcci.calib.consistent) -> the
held-out validation (measured against predicted torque on a log the fit did not see).

Held-out figures, per joint: the RMS of (measured - predicted) joint torque at the log's own
rate, the prediction passed through the same current-sense filter as the measurement (no
low-pass on either), over the instants where the joint moves (|qd| >= rcci.calib.identification.still_speeds) and over
all; set against the noise of the measured torque (rcci.calib.identification.Rows.noise: the sd of
the measurement minus its zero-phase low-pass, scaled to the whole band). The goal is RMS <= 2x
noise.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from rcci.calib.consistent import ConsistentResult, fit_consistent
from rcci.calib.exceptions import CalibError, LogError
from rcci.calib.identification import (Rows, WlsResult, column_names, current_filter, regressor_columns,
                                       rows_of_trace, wls)

GOAL_RMS_NOISE = 2.0


@dataclass
class Heldout:
    """Measured and predicted torque of one held-out log (N m), with its per-joint figures."""

    path: str
    t: np.ndarray
    measured: np.ndarray         # (N, n)
    predicted: np.ndarray        # (N, n), WLS values
    moving: np.ndarray           # (N, n) bool
    rms_moving: np.ndarray       # (n,)
    rms_all: np.ndarray          # (n,)
    noise: np.ndarray            # (n,)
    fitted: tuple[int, ...] = ()  # joints (0-based) whose equations were fitted (the others: nan RMS)

    def ratios(self) -> np.ndarray:
        """RMS (moving) / noise of the fitted joints, in joint order."""
        return np.array([self.rms_moving[j] / self.noise[j] for j in self.fitted])


@dataclass
class DynamicsResult:
    """The dynamics fit: WLS, the consistent variant, the held-out validation, timings."""

    robot: str
    names: tuple[str, ...]
    wls: WlsResult
    consistent: ConsistentResult | None
    heldout: list[Heldout]
    noise: np.ndarray            # per joint, of the fitted logs' measured torque
    seconds_fit: float           # wall time of reading the rows and both fits
    design_seconds: float        # the excitation designs' wall time (from the logs' metadata)
    cond_design: list[float]     # the designed excitations' condition numbers (unit columns)
    notes: list[str] = field(default_factory=list)


def _role(trace) -> str:
    role = trace.meta.get("role")
    if role not in ("fit", "heldout"):
        raise LogError(trace.path, None, f"metadata 'role' = {role!r}: a dynamics log is 'fit' or 'heldout'")
    return role


def heldout_figures(trace, drive, robot: str, x: np.ndarray, offset: np.ndarray | None = None) -> Heldout:
    """Measured against predicted torque on one log (module docstring)."""
    from rcci.calib.drive import FILTER_TAU
    from rcci.calib.identification import EDGE_S, current_noise, joint_motion, still_speeds
    from rcci.calib.regressor import fitted_joints

    t, rate, lp, q, qd, qdd, tau = joint_motion(trace, drive, offset)
    pred = current_filter(regressor_columns(robot, q, qd, qdd) @ x, rate, FILTER_TAU)
    inner = (t >= t[0] + EDGE_S) & (t <= t[-1] - EDGE_S)
    noise = current_noise(t, tau, rate)

    moving = (np.abs(qd) >= still_speeds(robot)) & inner[:, None]
    err = tau - pred
    rms_m = np.array([np.sqrt(np.mean(err[moving[:, j], j] ** 2)) if moving[:, j].any() else np.nan
                      for j in range(err.shape[1])])
    rms_a = np.sqrt(np.mean(err[inner] ** 2, axis=0))
    used = fitted_joints(robot)
    out = [j for j in range(err.shape[1]) if j not in used]     # no prediction there: the fit left them out
    rms_m[out], rms_a[out], pred[:, out] = np.nan, np.nan, np.nan
    return Heldout(trace.path, t, tau, pred, moving, rms_m, rms_a, noise, tuple(used))


def fit_dynamics(traces, drive, robot: str, consistent: bool = True,
                 offset: np.ndarray | None = None) -> DynamicsResult:
    """Fit the ``fit`` logs among ``traces``, validate on the ``heldout`` ones; ``offset`` the
    fitted joint offsets (rad) when the parameter file has a kinematic calibration. numpy's BLAS
    runs one thread meanwhile (rcci.calib.blas_threads: its workers stall on a busy machine)."""
    from rcci.calib.blas_threads import one_blas_thread

    with one_blas_thread():
        return _fit_dynamics(traces, drive, robot, consistent, offset)


def _fit_dynamics(traces, drive, robot: str, consistent: bool, offset: np.ndarray | None) -> DynamicsResult:
    """:func:`fit_dynamics`'s work."""
    t0 = time.monotonic()
    names = column_names(robot)
    fit_logs = [tr for tr in traces if _role(tr) == "fit"]
    held = [tr for tr in traces if _role(tr) == "heldout"]
    notes = []
    if not fit_logs:
        raise CalibError("calib fit dynamics: no log with role 'fit' among "
                         + ", ".join(tr.path for tr in traces) + " (the held-out log only validates)")
    if not held:
        notes.append("no held-out log (role 'heldout'): the fit is not validated on another trajectory")
    rows = Rows.stack([rows_of_trace(tr, drive, robot, offset) for tr in fit_logs])
    res = wls(rows, names)
    cons = None
    if consistent:
        w = 1.0 / np.where(res.joint_sd > 0, res.joint_sd, 1.0)[rows.joint]
        Aw = rows.A * w[:, None]
        r = (rows.y - rows.A @ res.value) * w
        cons = fit_consistent(robot, res.value, Aw.T @ Aw, float(r @ r))
        if cons.status not in ("Solve_Succeeded", "Solved_To_Acceptable_Level"):
            notes.append(f"the physically consistent fit ended with IPOPT status {cons.status}")
    heldout = [heldout_figures(tr, drive, robot, res.value, offset) for tr in held]
    seconds = time.monotonic() - t0
    design = sum(float(tr.meta.get("design_seconds", 0.0)) for tr in traces)
    conds = [float(tr.meta.get("excitation", {}).get("cond_scaled", np.nan)) for tr in traces]
    return DynamicsResult(robot, names, res, cons, heldout, rows.noise, seconds, design, conds, notes)


def truth_vector(traces, robot: str) -> np.ndarray | None:
    """The true parameters of the simula the logs were recorded against (None: a robot's logs)."""
    import tomllib

    from rcci.calib.dynamics_truth import truth_parameters
    from rcci.calib.truth import log_truth

    metas = [log_truth(tr) for tr in traces]
    if any(m["kind"] != "simula" for m in metas):
        return None
    texts = {m.get("params_toml") for m in metas}
    if len(texts) > 1:
        raise CalibError("the dynamics logs were recorded against simulas with different parameter files")
    text = texts.pop()
    return truth_parameters(robot, tomllib.loads(text) if text else None)


def coverage(res: DynamicsResult, truth: np.ndarray) -> tuple[int, int, np.ndarray]:
    """(inside, of, mask): base parameters (and the rest) whose truth is inside the printed interval."""
    inside = np.abs(res.wls.value - truth) <= res.wls.error
    return int(inside.sum()), len(inside), inside
