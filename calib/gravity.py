"""Gravity loading coefficients from 180-degree sweeps (thesis 4.44-4.51, Tables 4.7-4.9).

A joint phi, the others fixed, is driven through [phi0, phi0 + 180 deg]; the gravity
torque on it is a pure sinusoid of phi, tau(phi0 + u) = a cos u + b sin u, so the work
of the two 90-degree segments gives its value at the start of the pass,

    tau0 = d (W1 - W2) / 2          (d = +1 moving up, -1 moving down),

plus the friction difference between the segments.  (Printed 4.47 reads
"tau0 = -2(Wg1 - Wg2)" and 4.44/4.46 lost their signs in the OCR; the form above is the
one the sinusoid gives, see docs/calib.md.)  The friction difference is removed as
4.49-4.51 do, by repeating the sweep over the same joint range with the arm reoriented
so that gravity does the same work in both segments: the difference of the two tau0
estimates is Y(q0) c - Y(q0') c, linear in the loading coefficients c, with Y the
gravity regressor of the robot model.  Every sweep (its two directions averaged: they
share their errors, ``sweep_observations``) is one observation of a least-squares fit for c.

Joint 2's sweep has no repeat (its axis is always horizontal, docs/calib.md). There the
friction's position pattern (Table 4.4) would stay in W1 - W2; it is taken out with the
sweep's own friction profile instead: going up and coming down, gravity is the same at a
position, so half the difference of the two torques is the friction along the path, and
its integrals over the two segments give the work difference to remove
(``segment_friction_difference``), scaled for the direction by the friction's asymmetry
measured on the same sweep once a first fit has given gravity.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from rcci.calib.drive import Drive
from rcci.calib.exceptions import FitError, LogError
from rcci.calib.logs import clipped_note, saturated_mask
from rcci.calib.lsq import bounded_lsq, coverage_factor
from rcci.calib.poses import unidentified
from rcci.calib.trace import Trace
from rcci.calib.work import Pass, find_passes, up_down_half_difference, window_work

Regressor = Callable[[np.ndarray], np.ndarray]  # q (6,) rad -> (6, k), tau_g = Y c


@dataclass(frozen=True)
class SweepPass:
    """tau0 (N m) of one pass: joint, direction, the start pose q0 (rad)."""

    position: str
    role: str
    joint: int
    direction: int
    q0: np.ndarray
    tau0: float
    path: str
    # N m rad: the sweep's mean friction profile integrated over the first 90 degrees less
    # over the second (``segment_friction_difference``); NaN when not measured
    friction_difference: float = float("nan")


@dataclass(frozen=True)
class GravityRow:
    """One line of Table 4.8: a start position, joint and direction, with its tau0.

    ``tau0`` is friction-compensated (4.51) when a repeat was measured; ``row`` is the
    regressor combination it equals; ``raw_tau0`` is the uncompensated value.
    """

    position: str
    joint: int
    direction: int
    tau0: float
    raw_tau0: float
    row: np.ndarray
    raw_row: np.ndarray
    passes: int


@dataclass(frozen=True)
class GravityResult:
    """Table 4.9: coefficients, their combined error and the friction error."""

    names: tuple[str, ...]
    value: np.ndarray
    error: np.ndarray
    fit_std: np.ndarray
    direction_diff: np.ndarray
    friction_error: np.ndarray
    rows: list[GravityRow]
    factor: float = 3.0          # the fit's sd times this in ``error`` (rcci.calib.lsq.coverage_factor)

    def with_scale_error(self, relative: float) -> "GravityResult":
        """The errors with a relative scale uncertainty of the torques added (the fitted
        torque sensitivities': every coefficient scales with them)."""
        from dataclasses import replace

        return replace(self, error=np.hypot(self.error, relative * np.abs(self.value)))


def sweep_passes(trace: Trace, drive: Drive, notes: list[str] | None = None) -> list[SweepPass]:
    """tau0 of every full pass of a gravity log (both directions); passes with a reading
    at an ADC rail are left out (noted in ``notes``)."""
    i = trace.joint_index()
    q_start = np.asarray(trace.need("q_start", (list, tuple)), dtype=float)
    n = len(drive.G)
    if q_start.shape != (n,):
        raise LogError(trace.path, None, f"metadata 'q_start' has {q_start.size} angles, not {n}")
    lo = float(trace.need("phi_low", (int, float)))
    hi = lo + np.pi
    position = str(trace.need("position", str))
    role = str(trace.meta.get("role", "main"))
    if role not in ("main", "repeat"):
        raise LogError(trace.path, None, f"metadata 'role' = {role!r} is not main or repeat")
    theta = drive.current_angles(trace.t, trace.counts)
    th, tau = theta[:, i], drive.joint_torques(trace.adc)[:, i]
    mid = lo + np.pi / 2
    out = []
    passes = find_passes(th, lo, hi)
    clipped = saturated_mask(trace, [i], drive.G)
    keep = [p for p in passes if not clipped[p.first - 1:p.last + 2].any()]
    if notes is not None and len(keep) < len(passes):
        notes.append(clipped_note(trace, "passes", len(passes) - len(keep), len(passes), [i], drive.G))
    diff = segment_friction_difference(th, tau, keep, lo, mid, hi)
    for p in keep:
        w_low = window_work(th, tau, p, lo, mid)
        w_high = window_work(th, tau, p, mid, hi)
        w1, w2 = (w_low, w_high) if p.direction > 0 else (w_high, w_low)
        q0 = q_start.copy()
        q0[i] = lo if p.direction > 0 else hi
        out.append(SweepPass(position, role, i + 1, p.direction, q0,
                             p.direction * (w1 - w2) / 2.0, trace.path, diff))
    if not out:
        why = " with every reading off the ADC's rails" if len(keep) < len(passes) else ""
        raise LogError(trace.path, None, f"no full pass of joint {i + 1} through "
                       f"[{lo:.4f}, {hi:.4f}] rad{why}")
    return out


PROFILE_BIN = 0.01  # rad


def segment_friction_difference(theta: np.ndarray, tau: np.ndarray, passes: Sequence[Pass],
                                lo: float, mid: float, hi: float) -> float:
    """D = the integral of the mean friction profile over [lo, mid] less over [mid, hi] (N m rad).

    At one position gravity is the same going up and coming down, so half the difference
    of the torques up and down, (tau_up - tau_down) / 2, is the friction there (the mean of
    the two directions'); the friction's position pattern (Table 4.4) makes its work
    differ between the segments by D (and by D (F_d / F_mean) in direction d), which W1 - W2
    keeps when no repeat (4.49-4.51) removes it. NaN without passes both ways."""
    n = max(int(round((hi - lo) / PROFILE_BIN)), 4)
    half = up_down_half_difference(theta, tau, list(passes), lo, hi, n)
    both = np.isfinite(half)
    if both.sum() < 0.8 * n:
        return float("nan")
    centres = lo + (np.arange(n) + 0.5) * (hi - lo) / n
    profile = np.interp(centres, centres[both], half[both])
    first = centres < mid
    return float((profile[first].sum() - profile[~first].sum()) * (hi - lo) / n)


def gravity_rows(passes: Sequence[SweepPass], regressor: Regressor,
                 asymmetry: dict[int, float] | None = None) -> list[GravityRow]:
    """Group passes by (position, joint, direction) and apply the repeat of 4.51.

    A sweep without a repeat has the friction pattern's segment difference removed instead:
    tau0 less D (1 + d a) / 2, with a = (F+ - F-) / (F+ + F-) of the joint from ``asymmetry``
    (0 when not known)."""
    keys = sorted({(p.position, p.joint, p.direction) for p in passes if p.role == "main"},
                  key=lambda k: (k[0], -k[1], -k[2]))
    rows = []
    for pos, j, d in keys:
        main = [p for p in passes if (p.position, p.joint, p.direction, p.role) == (pos, j, d, "main")]
        rep = [p for p in passes if (p.position, p.joint, p.direction, p.role) == (pos, j, d, "repeat")]
        raw_tau0 = float(np.mean([p.tau0 for p in main]))
        raw_row = np.asarray(regressor(main[0].q0))[j - 1]
        if rep:
            tau0 = raw_tau0 - float(np.mean([p.tau0 for p in rep]))
            row = raw_row - np.asarray(regressor(rep[0].q0))[j - 1]
        else:
            D = float(np.mean([p.friction_difference for p in main]))
            a = (asymmetry or {}).get(j, 0.0)
            tau0 = raw_tau0 - (D * (1 + d * a) / 2 if np.isfinite(D) else 0.0)
            row = raw_row
        rows.append(GravityRow(pos, j, d, tau0, raw_tau0, row, raw_row, len(main) + len(rep)))
    return rows


def sweep_observations(rows: Sequence[GravityRow], compensated: bool,
                       k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(A (m, k), y (m,) N m, joint (m,)): one observation per sweep.

    The + and - rows of a sweep measure one combination of the coefficients: the joint's
    own regressor row is a pure sinusoid of its angle, so the row at the far end is minus
    the row at the start, and both passes' tau0 carry the same slowly varying errors (a
    friction that drifts as the joint warms or cools, what the position pattern's removal
    leaves): on the PUMA 560, err(+) = -err(-) within 10-20 % on every sweep
    (docs/calib.md, "Gravity intervals"). Counted as two observations they halve the
    residual's apparent variance and double its degrees of freedom; so they are averaged
    into one, (row+ - row-) / 2 and (tau0+ - tau0-) / 2. A row without its opposite (one
    direction only, or rows that are not opposite) stays an observation of its own."""
    groups: dict[tuple[str, int], list[GravityRow]] = {}
    for r in rows:
        groups.setdefault((r.position, r.joint), []).append(r)
    A, y, joint = [], [], []
    for (_, j), rs in groups.items():
        rowf = [np.asarray(r.row if compensated else r.raw_row, float) for r in rs]
        tau = [r.tau0 if compensated else r.raw_tau0 for r in rs]
        dirs = [r.direction for r in rs]
        scale = max(float(np.abs(np.array(rowf)).max()), 1e-12)
        if sorted(dirs) == [-1, 1] and np.allclose(rowf[0], -rowf[1], rtol=0.0, atol=1e-9 * scale):
            A.append(sum(d * x for d, x in zip(dirs, rowf)) / 2)
            y.append(sum(d * t for d, t in zip(dirs, tau)) / 2)
            joint.append(j)
        else:
            A += rowf
            y += tau
            joint += [j] * len(rs)
    return np.array(A).reshape(-1, k), np.array(y), np.array(joint)


def _solve(rows: Sequence[GravityRow], compensated: bool, k: int, what: str,
           noise: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, int]:
    """(coefficients, their sd from the residuals, number of observations), one
    observation per sweep (``sweep_observations``), weighted by 1 / noise[joint]; the sd is
    ``robust_sd``'s."""
    A, y, joint = sweep_observations(rows, compensated, k)
    w = np.ones(len(y)) if noise is None else 1.0 / noise[joint - 1]
    fit = bounded_lsq(A * w[:, None], y * w, what=what)
    return fit.x, robust_sd(A * w[:, None], y * w, fit.x), len(y)


def robust_sd(A: np.ndarray, y: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Standard deviations of the least-squares ``x`` of y ~ A x from each observation's own
    residual (the heteroscedasticity-consistent "HC3" sandwich: residual r_i / (1 - h_i), h_i
    the observation's leverage), not from one variance pooled over all.

    The weights (each joint's friction) say only roughly how much error a joint's sweeps carry:
    on the PUMA 560 the residuals per unit of friction differ between joints by 2-4x from
    seed to seed (joint 4's twice joint 2's on hidden truth 1), so a pooled variance gives the
    coefficients that joint 4's sweeps alone measure (cz4) an interval 2-3x too narrow. An
    observation that alone fixes a combination (h_i = 1) makes that combination's sd infinite."""
    H_inv = np.linalg.inv(A.T @ A)
    lev = np.einsum("ij,jk,ik->i", A, H_inv, A)
    r = (y - A @ x) / np.maximum(1.0 - lev, 1e-12)
    meat = (A * r[:, None]).T @ (A * r[:, None])
    return np.sqrt(np.diag(H_inv @ meat @ H_inv))


def sweep_friction(passes: Sequence[SweepPass], traces: list[Trace], drive: Drive) -> np.ndarray:
    """Each swept joint's friction (N m, (n,), NaN where not swept), from the sweeps
    themselves: over the same 180 degrees gravity's work cancels between a pass up and a
    pass down, so (W_up + W_down) / (2 pi) is the mean friction."""
    out = np.full(len(drive.G), np.nan)
    per: dict[int, list[float]] = {}
    for tr in traces:
        i = tr.joint_index()
        lo = float(tr.need("phi_low", (int, float)))
        theta = drive.current_angles(tr.t, tr.counts)[:, i]
        tau = drive.joint_torques(tr.adc)[:, i]
        ps = find_passes(theta, lo, lo + np.pi)
        up = [window_work(theta, tau, p, lo, lo + np.pi) for p in ps if p.direction > 0]
        dn = [window_work(theta, tau, p, lo, lo + np.pi) for p in ps if p.direction < 0]
        if up and dn:
            per.setdefault(i, []).append((np.mean(up) + np.mean(dn)) / (2 * np.pi))
    for i, v in per.items():
        out[i] = abs(float(np.mean(v)))
    return out


def fit_gravity(traces: list[Trace], drive: Drive, regressor: Regressor,
                names: tuple[str, ...], noise: np.ndarray | None = None,
                notes: list[str] | None = None) -> GravityResult:
    """Table 4.9 from gravity logs.

    ``noise`` (6,) is the expected scatter of a joint's tau0 in relative terms: what
    remains of friction in W1 - W2 grows with the joint's friction, so rows are weighted
    by 1 / noise[joint]^2; by default each swept joint's friction as the sweeps
    themselves measure it (``sweep_friction``), so no other fit's values are needed.
    error = sqrt((t sd of the fit)^2 + (half the difference between the fits of the two
    directions)^2): the thesis's combination of measurement uncertainty and direction, with
    the fit's part a 99.73 % interval as everywhere in calib (t = rcci.calib.lsq.coverage_factor
    of the fit's degrees of freedom, sweeps less coefficients: a sweep's two directions are one
    observation, ``sweep_observations``; the sd from each observation's own residual,
    ``robust_sd``; the thesis printed 2 sd); friction_error = how much the
    result moves without the repeat (4.49). FitError naming them when the sweeps leave
    coefficients open (rcci.calib.poses.unidentified).
    """
    passes = [p for tr in traces for p in sweep_passes(tr, drive, notes)]
    if noise is None:
        noise = sweep_friction(passes, traces, drive)
        if not np.isfinite(noise[[p.joint - 1 for p in passes]]).all():
            noise = None          # a joint swept one way only: equal weights
    rows = gravity_rows(passes, regressor)
    k = len(names)
    open_ = unidentified(np.array([r.row for r in rows]).reshape(-1, k), names)
    if open_:
        raise FitError(f"the gravity logs do not identify {', '.join(open_)}: no sweep among them "
                       "(its joint's regressor row at its start pose) separates them; record the sweeps "
                       "`calib record gravity --robot ROBOT` chooses for the arm")
    value, std, n_obs = _solve(rows, True, k, "gravity loading", noise)
    lone = {p.joint for p in passes if p.role == "main"} - {p.joint for p in passes if p.role == "repeat"}
    if lone:        # sweeps without a repeat: once more with their directions' friction asymmetry
        asym = friction_asymmetry(traces, drive, regressor, value, lone)
        rows = gravity_rows(passes, regressor, asym)
        value, std, n_obs = _solve(rows, True, k, "gravity loading", noise)
    raw, _, _ = _solve(rows, False, k, "gravity loading without the friction repeat", noise)
    by_dir = []
    for d in (1, -1):
        sel = [r for r in rows if r.direction == d]
        try:
            by_dir.append(_solve(sel, True, k, "gravity loading, one direction", noise)[0])
        except FitError:
            by_dir.append(None)
    if by_dir[0] is not None and by_dir[1] is not None:
        ddiff = np.abs(by_dir[0] - by_dir[1])
    else:
        ddiff = np.zeros(k)
    factor = coverage_factor(n_obs - k)
    if n_obs <= k:          # as many sweeps as coefficients: nothing left to measure the scatter
        if notes is not None:
            notes.append(f"gravity: {n_obs} sweeps for {k} coefficients leave no residual to estimate "
                         "the scatter from; the errors are infinite (record the plan's extra sweeps)")
        error = np.full(k, np.inf)
    else:
        error = np.sqrt((factor * std) ** 2 + (ddiff / 2) ** 2)
    return GravityResult(names=names, value=value, error=error, fit_std=std,
                         direction_diff=ddiff, friction_error=np.abs(value - raw), rows=rows, factor=factor)


def friction_asymmetry(traces: list[Trace], drive: Drive, regressor: Regressor, coeffs: np.ndarray,
                       joints: set[int]) -> dict[int, float]:
    """(F+ - F-) / (F+ + F-) of each joint in ``joints`` (1-based) over its sweeps, with the
    gravity of ``coeffs`` taken off: F+ the mean of tau - tau_g moving up, F- of tau_g - tau
    moving down."""
    out: dict[int, list[tuple[float, float]]] = {}
    for tr in traces:
        i = tr.joint_index()
        if i + 1 not in joints:
            continue
        lo = float(tr.need("phi_low", (int, float)))
        q_start = np.asarray(tr.need("q_start", (list, tuple)), dtype=float)
        theta = drive.current_angles(tr.t, tr.counts)[:, i]
        tau = drive.joint_torques(tr.adc)[:, i]
        for p in find_passes(theta, lo, lo + np.pi):
            seg = slice(p.first, p.last + 1)
            q = np.tile(q_start, (p.last + 1 - p.first, 1))
            q[:, i] = theta[seg]
            tg = np.array([np.asarray(regressor(x))[i] @ coeffs for x in q])
            out.setdefault(i + 1, []).append((p.direction, float(np.mean(p.direction * (tau[seg] - tg)))))
    asym = {}
    for j, v in out.items():
        up = [f for d, f in v if d > 0]
        dn = [f for d, f in v if d < 0]
        if up and dn:
            fp, fm = float(np.mean(up)), float(np.mean(dn))
            asym[j] = (fp - fm) / (fp + fm) if fp + fm > 0 else 0.0
    return asym


def row_result(row: GravityRow, result: GravityResult) -> tuple[str, float]:
    """Table 4.8's last column: the row solved for its leading coefficient, the others
    taken from the overall fit."""
    lead = int(np.argmax(np.abs(row.row)))
    others = row.row @ result.value - row.row[lead] * result.value[lead]
    return result.names[lead], float((row.tau0 - others) / row.row[lead])
