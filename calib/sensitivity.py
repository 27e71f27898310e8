"""Motor torque sensitivity from pulley-and-mass runs (thesis 4.39-4.43, Table 4.1).

A joint swings at constant speed through an arc, raising and lowering a known mass on a
pulley; the same is done without the mass.  Only motor i carries the pulley's torque
when joint i moves (G is lower triangular, so the load on joint i maps to motors
1..i while only motors i..6 turn), so the work of motor i in ampere-radians,
A = integral i_i d(theta_s,i) = G_ii integral i_i d(theta_i), gives by 4.43

    sigma_i (A+ - A'+ - A- + A'-) = 2 W_mass,

friction cancelling between the loaded and unloaded runs.  Each loaded round trip
(one + pass, one - pass) is one trial, against the mean of the unloaded passes.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rcci.calib.drive import Drive
from rcci.calib.exceptions import FitError, LogError
from rcci.calib.logs import ADC_RAIL, clipped_note, saturated_mask
from rcci.calib.trace import Trace
from rcci.calib.work import find_passes, window_work

GRAVITY = 9.80665  # m/s^2, standard gravity: the mass's weight

# Relative uncertainties of the inputs of 4.43 when a log does not state its own
# (estimate: a mass weighed to 0.2 %, a pulley radius known to 1 %, the current scale
# V_g / R_i known to 2 % since R_i is printed to three digits and V_g to three).
DEFAULT_REL_UNCERTAINTY = {"mass": 0.002, "radius": 0.01, "current_scale": 0.02}


@dataclass(frozen=True)
class SensitivityResult:
    """Table 4.1 for one joint (N m / A): trials, mean, spread, independent error."""

    joint: int
    trials: int
    mean: float
    std: float
    independent_error: float
    values: np.ndarray


@dataclass(frozen=True)
class _PassWork:
    plus: np.ndarray   # ampere-radians of motor i on each + pass
    minus: np.ndarray  # ... on each - pass


def _ampere_radians(trace: Trace, drive: Drive,
                    notes: list[str] | None = None) -> tuple[int, tuple[float, float], _PassWork]:
    i = trace.joint_index()
    lo, hi = _window(trace)
    theta = drive.current_angles(trace.t, trace.counts)[:, i]
    current = drive.motor_currents(trace.adc)[:, i] * drive.G[i, i]
    clipped = saturated_mask(trace, [i], np.eye(len(drive.G)))     # only motor i's current enters 4.43
    plus, minus = [], []
    passes = find_passes(theta, lo, hi)
    keep = [p for p in passes if not clipped[p.first - 1:p.last + 2].any()]
    if notes is not None and len(keep) < len(passes):
        notes.append(clipped_note(trace, "passes", len(passes) - len(keep), len(passes), [i], np.eye(len(drive.G))))
    for p in keep:
        (plus if p.direction > 0 else minus).append(window_work(theta, current, p, lo, hi))
    if not plus or not minus:
        rail = (f" with motor {i + 1}'s ADC channel off its rails (+-{ADC_RAIL}): {len(passes) - len(keep)} "
                f"of {len(passes)} passes read at the rail, where the current is unknown (a smaller mass "
                "or a larger current scale)" if len(keep) < len(passes) else "")
        raise LogError(trace.path, None, f"no complete pass in both directions through "
                       f"the window [{lo:.4f}, {hi:.4f}] rad of joint {i + 1}{rail}")
    return i, (lo, hi), _PassWork(np.array(plus), np.array(minus))


def _window(trace: Trace) -> tuple[float, float]:
    w = trace.need("window", (list, tuple))
    if len(w) != 2 or not float(w[0]) < float(w[1]):
        raise LogError(trace.path, None, f"metadata 'window' = {w!r} is not [lo, hi] rad")
    return float(w[0]), float(w[1])


def mass_work(trace: Trace, lo: float, hi: float) -> float:
    """Potential energy (J) the pulley's mass gains while the joint moves lo -> hi.

    Metadata 'load' = {mass_kg, radius_m, sign}: the string winds on a drum of radius
    radius_m on the joint axis, and sign = +1 when the mass rises as the joint angle
    increases.
    """
    load = trace.need("load", dict)
    try:
        mass, radius, sign = float(load["mass_kg"]), float(load["radius_m"]), float(load["sign"])
    except (KeyError, TypeError, ValueError) as exc:
        raise LogError(trace.path, None, f"metadata 'load' = {load!r} lacks mass_kg, "
                       f"radius_m or sign ({exc})") from None
    return sign * mass * GRAVITY * radius * (hi - lo)


def fit_sensitivity(traces: list[Trace], drive: Drive, notes: list[str] | None = None) -> list[SensitivityResult]:
    """Table 4.1 from sensitivity logs: each joint needs loaded and unloaded logs.
    Passes with motor i's reading at an ADC rail are left out (noted in ``notes``)."""
    loaded: dict[int, list[tuple[Trace, tuple[float, float], _PassWork]]] = {}
    unloaded: dict[int, list[tuple[Trace, tuple[float, float], _PassWork]]] = {}
    for tr in traces:
        i, window, work = _ampere_radians(tr, drive, notes)
        mass = float(tr.need("load", dict).get("mass_kg", 0.0))
        (loaded if mass > 0 else unloaded).setdefault(i, []).append((tr, window, work))
    results = []
    for i in sorted(loaded):
        refs = unloaded.get(i, [])
        values, rel2 = [], []
        for tr, window, work in loaded[i]:
            same = [w for _, win, w in refs if np.allclose(win, window, atol=1e-3)]
            if not same:
                raise FitError(f"{tr.path}: no unloaded log of joint {i + 1} over the same "
                               f"window {window} to cancel friction (4.41-4.42)")
            ref_plus = np.mean(np.concatenate([w.plus for w in same]))
            ref_minus = np.mean(np.concatenate([w.minus for w in same]))
            w_mass = mass_work(tr, *window)
            trips = min(len(work.plus), len(work.minus))
            for k in range(trips):
                denom = work.plus[k] - ref_plus - work.minus[k] + ref_minus
                if denom * w_mass <= 0:
                    raise LogError(tr.path, None, f"round trip {k + 1}: the loaded work "
                                   f"difference has the wrong sign for the pulley's "
                                   f"metadata 'load' sign (mass work {w_mass:.3f} J)")
                values.append(2.0 * w_mass / denom)
            rel = dict(DEFAULT_REL_UNCERTAINTY)
            rel.update(tr.meta.get("rel_uncertainty", {}))
            rel2.append(sum(float(v) ** 2 for v in rel.values()))
        vals = np.array(values)
        if len(vals) < 2 and notes is not None:
            notes.append(f"joint {i + 1}: {len(vals)} trial (round trip with both passes complete): its "
                         "spread, so its std and the error it passes on to later fits, is unknown (NaN); "
                         "record more round trips")
        mean = float(vals.mean())
        std = float(vals.std(ddof=1)) if len(vals) > 1 else float("nan")
        results.append(SensitivityResult(joint=i + 1, trials=len(vals), mean=mean, std=std,
                                         independent_error=mean * float(np.sqrt(max(rel2))),
                                         values=vals))
    if not results:
        raise FitError("no loaded sensitivity log (metadata load.mass_kg > 0) among the inputs")
    return results
