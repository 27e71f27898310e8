"""Work done by a joint along a path (thesis 4.4-4.5), and the passes a path is cut into.

The thesis sums i_a * d(theta_s) / sigma over the samples (4.5).  Here the same sum is
taken in joint space, W = integral of tau_j d(theta), with the joint torque
tau_j = G^T K_adc v_adc (4.36) and the joint angle from the encoders (4.30): when only
joint i moves, the motors' total work t_s . d(theta_s) equals tau_j,i d(theta_i)
because theta_s = G theta and tau_j = G^T t_s.  The integral is a trapezoid sum in
theta, cut exactly at the ends of the observation window by linear interpolation, so a
window need not fall on samples.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Pass:
    """One monotonic crossing of an observation window [lo, hi] (radians).

    ``first``/``last`` index the samples strictly inside the window; the samples just
    outside (``first - 1`` and ``last + 1``) exist and lie beyond opposite ends.
    ``direction`` is +1 when the joint angle increases through the window, else -1.
    """

    first: int
    last: int
    direction: int


def find_passes(theta: np.ndarray, lo: float, hi: float,
                reversal_tol: float = 0.0) -> list[Pass]:
    """Every crossing of [lo, hi] by the joint angle ``theta`` (N,) (radians).

    A crossing enters at one end and leaves at the other; runs that enter and leave by
    the same end (a turn inside the window) are not passes.  A crossing during which
    theta goes back by more than ``reversal_tol`` radians is not monotonic and is
    skipped too, since its work would count part of the path twice.
    """
    if not lo < hi:
        raise ValueError(f"observation window [{lo}, {hi}] is empty")
    theta = np.asarray(theta, dtype=float)
    side = np.where(theta < lo, -1, np.where(theta > hi, 1, 0))
    passes: list[Pass] = []
    n = len(theta)
    k = 0
    while k < n:
        if side[k] != 0:
            k += 1
            continue
        first = k
        while k < n and side[k] == 0:
            k += 1
        last = k - 1
        if first == 0 or k >= n:
            continue            # starts or ends inside the window: incomplete
        before, after = side[first - 1], side[k]
        if before == after:
            continue            # turned round inside the window
        direction = int(after)  # leaving above hi means theta increased
        seg = theta[first - 1:last + 2] * direction
        back = np.maximum.accumulate(seg) - seg
        if back.max() > reversal_tol:
            continue
        passes.append(Pass(first, last, direction))
    return passes


def window_work(theta: np.ndarray, tau: np.ndarray, p: Pass, lo: float, hi: float) -> float:
    """Work (J) done by the joint torque ``tau`` (N m) while ``theta`` crosses [lo, hi].

    Positive when the torque pushes the way the joint moves, so a pass against
    friction alone gives positive work in either direction.
    """
    k = np.arange(p.first - 1, p.last + 2)
    th, tq = np.asarray(theta, float)[k], np.asarray(tau, float)[k]
    return _clipped_trapezoid(th, tq, lo, hi)


def window_time(theta: np.ndarray, t: np.ndarray, p: Pass, lo: float, hi: float) -> float:
    """Seconds the pass spends between lo and hi (interpolated at both ends)."""
    k = np.arange(p.first - 1, p.last + 2)
    th, tt = np.asarray(theta, float)[k], np.asarray(t, float)[k]
    x = th * p.direction
    order = np.argsort(x, kind="stable")
    t_lo, t_hi = np.interp([lo * p.direction, hi * p.direction], x[order], tt[order])
    return float(abs(t_hi - t_lo))


def _clipped_trapezoid(th: np.ndarray, tq: np.ndarray, lo: float, hi: float) -> float:
    """Trapezoid integral of tq d(th) over the part of each interval inside [lo, hi]."""
    a, b = th[:-1], th[1:]
    ta, tb = tq[:-1], tq[1:]
    ca, cb = np.clip(a, lo, hi), np.clip(b, lo, hi)
    span = b - a
    safe = np.where(span == 0.0, 1.0, span)
    slope = np.where(span == 0.0, 0.0, (tb - ta) / safe)
    tca = ta + slope * (ca - a)
    tcb = ta + slope * (cb - a)
    return float(np.sum(0.5 * (tca + tcb) * (cb - ca)))


def hann_edge_weights(theta: np.ndarray, lo: float, hi: float, taper: float) -> np.ndarray:
    """Weights along [lo, hi] (rad) that rise from 0 to 1 over ``taper`` rad at each end
    as half a cosine (a Hann edge), 1 in between, 0 outside."""
    if taper <= 0.0:
        return ((theta >= lo) & (theta <= hi)).astype(float)
    a = np.clip((theta - lo) / taper, 0.0, 1.0)
    b = np.clip((hi - theta) / taper, 0.0, 1.0)
    return (0.5 - 0.5 * np.cos(np.pi * a)) * (0.5 - 0.5 * np.cos(np.pi * b))


def tapered_mean(theta: np.ndarray, tau: np.ndarray, p: Pass, lo: float, hi: float,
                 taper: float) -> float:
    """Mean torque (N m) over a pass, weighted along the path by Hann edges of ``taper`` rad.

    The plain window mean (work / distance, 4.5) has sharp ends, so any torque that
    varies with position near them (the gear pattern of Table 4.4) enters through end
    terms that the current filter of Appendix C changes with speed: at 4 rad/s the
    15 ms filter smears the torque over 0.06 rad of travel, which moves a pass's mean
    on joint 5 by up to 0.1 %, as much as its viscous term adds per rad/s.
    With weights that fall smoothly to zero, those end terms vanish and the same smear
    changes the weighted mean of a position-dependent torque only at second order.
    Positive when the torque pushes the way the joint moves (as ``window_work``).
    """
    if taper <= 0.0:
        return p.direction * window_work(theta, tau, p, lo, hi) / (hi - lo)
    k = np.arange(p.first - 1, p.last + 2)
    th, tq = np.asarray(theta, float)[k], np.asarray(tau, float)[k]
    w = hann_edge_weights(th, lo, hi, taper)
    # trapezoid in theta; zero weight at the ends, so the samples beyond them add nothing
    wt, ww = w * tq, w
    dth = np.abs(np.diff(th))
    num = float(np.sum(0.5 * (wt[1:] + wt[:-1]) * dth))
    den = float(np.sum(0.5 * (ww[1:] + ww[:-1]) * dth))
    return p.direction * num / den


def up_down_half_difference(theta: np.ndarray, tau: np.ndarray, passes: list[Pass], lo: float,
                            hi: float, bins: int) -> np.ndarray:
    """(tau going up - tau coming down) / 2 (N m) in ``bins`` equal bins of [lo, hi] (rad),
    NaN where a bin lacks a direction: at one position gravity is the same both ways, so
    this is the mean of the two directions' friction there."""
    edges = np.linspace(lo, hi, bins + 1)
    sums = {1: np.zeros(bins), -1: np.zeros(bins)}
    counts = {1: np.zeros(bins), -1: np.zeros(bins)}
    for p in passes:
        seg = slice(p.first, p.last + 1)
        idx = np.clip(np.digitize(theta[seg], edges) - 1, 0, bins - 1)
        sums[p.direction] += np.bincount(idx, weights=tau[seg], minlength=bins)
        counts[p.direction] += np.bincount(idx, minlength=bins)
    both = (counts[1] > 0) & (counts[-1] > 0)
    out = np.full(bins, np.nan)
    out[both] = 0.5 * (sums[1][both] / counts[1][both] - sums[-1][both] / counts[-1][both])
    return out
