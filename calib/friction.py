"""Coulomb and viscous friction from constant-speed runs (thesis 4.27, 4.5.4, Tables 4.2-4.4).

Each pass through a window with no change of potential energy does work against
friction only, so its mean friction is W / |d theta| at the pass's speed (taken with
smooth edges, rcci.calib.work.tapered_mean).  Per joint and
direction the points are fitted to 4.27, |f| = F_c + F_v |omega|, by least squares with
F_c, F_v >= 0 (CasADi QP).
The variation of Table 4.4 is read from the same passes: the friction along the path,
averaged over passes at each position, against its mean.

The uncertainty printed is a 99.73 % interval (rcci.calib.lsq.coverage_factor: 3 sd, Student's
t for the fit's few degrees of freedom). For F_v it is the fit's; for F_c the fit's
combined with three standard deviations of the position pattern's window mean: the friction
varies along the path (Table 4.4), the same on every pass, so each pass's mean carries
the pattern's mean over the window, which no fit of speeds can tell from F_c, the
joint's mean friction. Its standard deviation is estimated from the measured profile
(``pattern_sd``): the profile is resolved into sinusoids of the path, and each one's
window mean, averaged over where along the gear pattern the window may fall (a random
phase), is A^2 |H(k)|^2 / 2 in variance, H the window's weighting seen at wavenumber k.
A component longer than the window is indistinguishable from F_c and is not covered.
Passes with a reading at an ADC rail are left out (the current there is unknown).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from rcci.calib.drive import Drive
from rcci.calib.exceptions import FitError, LogError
from rcci.calib.logs import clipped_note, saturated_mask
from rcci.calib.lsq import PRINTED_SD, bounded_lsq, coverage_factor
from rcci.calib.trace import Trace
from rcci.calib.work import (Pass, find_passes, hann_edge_weights, tapered_mean, up_down_half_difference,
                         window_time)

PROFILE_BIN = 0.01  # rad: position bins of the Table 4.4 profile (finer than gear irregularities)
# rad: length of the Hann edges of each pass's weighting (rcci.calib.work.tapered_mean); long
# against the filter's smear at the top speeds (0.06 rad on joint 5), capped at a quarter
# of the window so that short windows keep a flat middle
TAPER = 0.3


@dataclass(frozen=True)
class FrictionPoint:
    """Mean friction (N m, positive) of one pass at one speed (rad/s, positive)."""

    joint: int
    direction: int
    speed: float
    friction: float
    path: str
    rate_hz: float = 36.0   # readings per second of the log the pass comes from


@dataclass(frozen=True)
class DirectionFit:
    """4.27 for one joint and direction: F_c (N m), F_v (N m s/rad); errors are 99.73 %
    intervals: ``factor`` times the fit's standard deviation (rcci.calib.lsq.coverage_factor),
    for F_c combined with 3 x the position pattern's (``coulomb_pattern_sd``, N m)."""

    coulomb: float
    coulomb_err: float
    viscous: float
    viscous_err: float
    points: int
    coulomb_fit_sd: float = float("nan")
    coulomb_pattern_sd: float = float("nan")
    factor: float = PRINTED_SD     # the fit's sds become the printed error by this (Student t)
    window_gravity: float = 0.0    # N m taken off every pass mean of this direction (gravity over the window)

    def with_pattern(self, relative_sd: float) -> "DirectionFit":
        """This fit with the pattern's window mean (relative sd) added to F_c's error."""
        sd = abs(self.coulomb) * relative_sd
        err = float(np.hypot(self.factor * self.coulomb_fit_sd, PRINTED_SD * sd))
        return replace(self, coulomb_err=err, coulomb_pattern_sd=sd)


@dataclass(frozen=True)
class FrictionResult:
    """Tables 4.2-4.4 for one joint; variation is a fraction (0.10 = 10 %)."""

    joint: int
    plus: DirectionFit
    minus: DirectionFit
    variation: float

    def with_window_gravity(self, g: float, sd: float) -> "FrictionResult":
        """F_c+ less and F_c- plus the window's mean gravity torque ``g`` (N m; each + pass
        carries +g, each - pass -g), its standard deviation ``sd`` added to the errors
        (x PRINTED_SD) (rcci.calib.window_gravity)."""
        def moved(f: DirectionFit, d: int) -> DirectionFit:
            return replace(f, coulomb=f.coulomb - d * g, coulomb_err=float(np.hypot(f.coulomb_err, PRINTED_SD * sd)),
                           window_gravity=d * g)
        return replace(self, plus=moved(self.plus, 1), minus=moved(self.minus, -1))

    def with_scale_error(self, relative: float) -> "FrictionResult":
        """The errors with a relative scale uncertainty (printed, 99.73 %) of the torques added:
        the fitted torque sensitivities' (every torque, so every coefficient, scales with them)."""
        def scaled(f: DirectionFit) -> DirectionFit:
            return replace(f, coulomb_err=float(np.hypot(f.coulomb_err, relative * f.coulomb)),
                           viscous_err=float(np.hypot(f.viscous_err, relative * f.viscous)))
        return replace(self, plus=scaled(self.plus), minus=scaled(self.minus))


def friction_points(trace: Trace, drive: Drive,
                    notes: list[str] | None = None) -> tuple[list[FrictionPoint], np.ndarray | None]:
    """Every pass of a friction log as a point, plus the log's relative friction profile.

    The profiles (2, bins) come from the log's two slowest speeds (where the current
    filter of Appendix C blurs the least distance): half the difference of the torque
    going up and coming down at each position, over its mean.  Gravity, the same both
    ways at one position, cancels, so this also holds for joints 2 and 3 whose paths
    cannot avoid gravity.  None when a speed lacks one of the directions.
    """
    i = trace.joint_index()
    w = trace.need("window", (list, tuple))
    if len(w) != 2 or not float(w[0]) < float(w[1]):
        raise LogError(trace.path, None, f"metadata 'window' = {w!r} is not [lo, hi] rad")
    lo, hi = float(w[0]), float(w[1])
    th = drive.current_angles(trace.t, trace.counts)[:, i]
    tau = drive.joint_torques(trace.adc)[:, i]
    points, passes = [], find_passes(th, lo, hi)
    clipped = saturated_mask(trace, [i], drive.G)
    if clipped.any():
        keep = [p for p in passes if not clipped[p.first - 1:p.last + 2].any()]
        if notes is not None and len(keep) < len(passes):
            notes.append(clipped_note(trace, "passes", len(passes) - len(keep), len(passes), [i], drive.G))
        passes = keep
    taper = min(TAPER, 0.25 * (hi - lo))
    rate = float(trace.rate_hz) if trace.rate_hz > 0 else 1.0 / float(np.median(np.diff(trace.t)))
    for p in passes:
        dt = window_time(th, trace.t, p, lo, hi)
        points.append(FrictionPoint(i + 1, p.direction, (hi - lo) / dt,
                                    tapered_mean(th, tau, p, lo, hi, taper), trace.path,
                                    rate))
    if not points:
        why = " with every reading off the ADC's rails" if clipped.any() else ""
        raise LogError(trace.path, None, f"no complete pass of joint {i + 1} through "
                       f"the window [{lo:.4f}, {hi:.4f}] rad{why}")
    speeds = sorted({round(pt.speed, 3) for pt in points})
    profiles = []
    for v in speeds[:2]:  # the two slowest speeds: two independent looks at one pattern
        sel = [(p, pt) for p, pt in zip(passes, points) if abs(pt.speed - v) < 0.2 * v]
        prof = _half_difference_profile(th, tau, [p for p, _ in sel], lo, hi)
        if prof is not None:
            profiles.append(prof)
    return points, (np.vstack(profiles) if len(profiles) == 2 else None)


def _half_difference_profile(th: np.ndarray, tau: np.ndarray, passes: list[Pass],
                             lo: float, hi: float) -> np.ndarray | None:
    """(tau going up - tau coming down) / 2 per position bin, over its mean, minus 1."""
    half = up_down_half_difference(th, tau, passes, lo, hi, max(int((hi - lo) / PROFILE_BIN), 4))
    both = np.isfinite(half)
    if both.sum() < 4:
        return None
    prof = np.full(len(half), np.nan)
    prof[both] = half[both] / half[both].mean() - 1.0
    return prof


def fit_direction(points: list[FrictionPoint], what: str) -> DirectionFit:
    """Weighted least squares of |f| = F_c + F_v |omega|, both coefficients >= 0.

    A pass's mean friction averages the current noise over the readings it takes, so
    that part of its variance goes as 1 / (readings per pass), i.e. as speed / reading
    rate; what does not average away (what is left of the position pattern) is the same
    at any speed.  How much noise one reading carries depends on how the log was read
    (at 72 Hz each reading holds a tick's ripple, read at every servo tick the ripple
    cancels), so the variance is modelled per log: a x + b with x = |omega| / rate for a
    log with 6 passes or more, a constant for a smaller one, estimated from the
    residuals of a first fit weighted 1 / (x + median x) (two-step feasible generalised
    least squares); each point is then weighted by the inverse of its modelled variance.
    """
    speed = np.array([p.speed for p in points])
    f = np.array([p.friction for p in points])
    x = speed / np.array([p.rate_hz for p in points])
    A = np.c_[np.ones_like(speed), speed]
    w = 1.0 / np.sqrt(x + np.median(x))
    fit = bounded_lsq(A * w[:, None], f * w, lower=np.zeros(2), what=what)
    if len(points) >= 6:
        r2 = (f - A @ fit.x) ** 2
        logs = np.array([p.path for p in points])
        model = np.empty_like(r2)
        for log in set(logs):
            m = logs == log
            if m.sum() >= 6 and np.ptp(x[m]) > 0:
                # variance model from the squared residuals, a and b >= 0
                var = bounded_lsq(np.c_[x[m], np.ones(m.sum())], r2[m], lower=np.zeros(2),
                                  what=what + " (variance)").x
                model[m] = var[0] * x[m] + var[1]
            else:
                model[m] = r2[m].mean()
        # a floor of 1 % of the mean variance keeps one lucky point from taking all the weight
        model = np.maximum(model, 0.01 * r2.mean())
        if np.all(np.isfinite(model)) and model.max() > 0:
            w = 1.0 / np.sqrt(model)
            fit = bounded_lsq(A * w[:, None], f * w, lower=np.zeros(2), what=what)
    k = coverage_factor(fit.dof)
    return DirectionFit(coulomb=float(fit.x[0]), coulomb_err=k * float(fit.std[0]),
                        viscous=float(fit.x[1]), viscous_err=k * float(fit.std[1]),
                        points=len(points), coulomb_fit_sd=float(fit.std[0]), factor=k)


def profile_variation(profiles: list[np.ndarray]) -> float:
    """Table 4.4's variation (fraction) from pairs of position profiles of one joint.

    Each element of ``profiles`` is (2, bins): the relative friction along the path seen
    at the two slowest speeds.  Their mean S carries the repeatable, position-dependent
    part (gearing irregularities, 4.5.3) plus noise whose variance is var(A - B) / 4;
    the variation is reported as sqrt(2) times the noise-corrected RMS of S, i.e. the
    amplitude of a sinusoid of the same RMS (the peak of a noisy profile would grow with
    the noise and the number of bins).
    """
    est = []
    for pair in profiles:
        a, b = pair
        ok = np.isfinite(a) & np.isfinite(b)
        if ok.sum() < 8:
            continue
        signal = 0.5 * (a[ok] + b[ok])
        noise_var = np.var(a[ok] - b[ok]) / 4.0
        est.append(max(np.var(signal) - noise_var, 0.0))
    if not est:
        return float("nan")
    return float(np.sqrt(2.0 * np.mean(est)))


def pattern_sd(profiles: list[np.ndarray], lo: float, hi: float, lines: int = 6) -> float:
    """Standard deviation (relative to the friction) of the position pattern's mean over
    the window [lo, hi] rad, as each pass's tapered mean weighs it; NaN without a profile.

    The mean of each profile pair (the repeatable part, rcci.calib.friction.profile_variation)
    is resolved greedily into ``lines`` sinusoids of the path (the strongest wavenumber of
    what is left, then its least-squares amplitude); each contributes A^2 |H(k)|^2 / 2,
    the variance of its weighted window mean over a uniformly random phase. Checked by
    simulation over 200 seeded patterns per joint window (docs/calib.md): the estimate's
    RMS is within 10 % of the true RMS window mean, and 3 sd covers 98.5-100 %.
    """
    taper = min(TAPER, 0.25 * (hi - lo))
    est = []
    for pair in profiles:
        ok = np.isfinite(pair)
        signal = np.where(ok.any(axis=0), np.where(ok, pair, 0.0).sum(axis=0) / np.maximum(ok.sum(axis=0), 1), np.nan)
        centres = np.linspace(lo, hi, len(signal) + 1)
        centres = 0.5 * (centres[1:] + centres[:-1])
        ok = np.isfinite(signal)
        if ok.sum() < 8:
            continue
        th, x = centres[ok], signal[ok] - signal[ok].mean()
        w = hann_edge_weights(th, lo, hi, taper)
        ks = np.linspace(np.pi / (hi - lo), 0.5 * np.pi / PROFILE_BIN, 2000)
        C, S = np.cos(np.outer(ks, th)), np.sin(np.outer(ks, th))
        var = 0.0
        for _ in range(lines):
            k = ks[int(np.argmax((C @ x) ** 2 + (S @ x) ** 2))]
            A = np.c_[np.cos(k * th), np.sin(k * th), np.ones_like(th)]
            c, *_ = np.linalg.lstsq(A, x, rcond=None)
            x = x - A @ c
            H = abs(np.sum(w * np.exp(1j * k * th)) / np.sum(w))
            var += 0.5 * (c[0] ** 2 + c[1] ** 2) * H ** 2
        est.append(var)
    return float(np.sqrt(np.mean(est))) if est else float("nan")


def fit_friction(traces: list[Trace], drive: Drive,
                 notes: list[str] | None = None) -> tuple[list[FrictionResult], list[FrictionPoint]]:
    """Tables 4.2-4.4 for every joint that has friction logs; also returns the points.
    Warnings (passes left out, a log of a set missing) are appended to ``notes``."""
    by_joint: dict[int, list[FrictionPoint]] = {}
    prof_by_joint: dict[int, list[tuple[float, np.ndarray]]] = {}
    window: dict[int, tuple[float, float]] = {}
    for tr in traces:
        pts, prof = friction_points(tr, drive, notes)
        by_joint.setdefault(pts[0].joint, []).extend(pts)
        prof_by_joint.setdefault(pts[0].joint, [])
        window[pts[0].joint] = tuple(float(x) for x in tr.meta["window"])
        if prof is not None:
            prof_by_joint[pts[0].joint].append((min(p.speed for p in pts), prof))
    results = []
    for j in sorted(by_joint):
        pts = by_joint[j]
        fits = {}
        for d, name in ((1, "+"), (-1, "-")):
            sel = [p for p in pts if p.direction == d]
            if len(sel) < 2:
                raise FitError(f"joint {j}: {len(sel)} pass(es) in the {name} direction; "
                               "the fit needs passes at two speeds at least")
            fits[d] = fit_direction(sel, f"joint {j} friction, {name} direction")
        # Table 4.4 from the logs with the slowest passes: the filter blurs the pattern
        # less there (a joint's fast passes may come in a log of their own)
        profs = prof_by_joint[j]
        slowest = min((v for v, _ in profs), default=0.0)
        keep = [pr for v, pr in profs if v <= 1.5 * slowest]
        rel = pattern_sd(keep, *window[j])
        if not np.isfinite(rel):
            rel = 0.0
            if notes is not None:
                notes.append(f"joint {j}: no position profile (passes in both directions at two slow "
                             "speeds): F_c's error leaves out the pattern's window mean")
        results.append(FrictionResult(joint=j, plus=fits[1].with_pattern(rel), minus=fits[-1].with_pattern(rel),
                                      variation=profile_variation(keep)))
    if not results:
        raise FitError("no friction log among the inputs")
    return results, [p for j in sorted(by_joint) for p in by_joint[j]]
