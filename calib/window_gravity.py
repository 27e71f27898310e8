"""What gravity does over a friction window on the arm as calibrated (thesis 4.5.4's premise checked).

The friction windows are chosen with the nominal model so that gravity does no net work
over them (an axis vertical, or a window symmetric about the upright arm). On the real
arm the DH table is off by its errors (3.83): an axis meant to be vertical leans by a
few milliradians, the upright arm is a little off upright, and gravity's mean torque over
the window, g_w, is no longer zero. Each + pass's mean then carries +g_w and each - pass's
-g_w, which no fit of speeds separates from F_c+ and F_c-: on the PUMA 260 a lean of
3 mrad gives joint 5 about 0.004 N m, its whole Table 4.2 uncertainty.

``window_gravity`` computes g_w on the arm the parameter file describes: simula's own
gravity model (Pinocchio on the URDF with centres of mass moved to the fitted gravity
coefficients, rci.simula.arm) with the fitted ``[kinematics]`` errors applied, over the
window at the friction pose, weighted as each pass's mean weighs it. Its uncertainty
comes from the kinematic errors' (a Monte Carlo over their standard deviations). Without a
kinematic calibration the errors are taken as zero with an a priori spread
(``DH_TOLERANCE``) and the correction is only an uncertainty.

A gravity-loaded window (``loaded``: a joint no window frees of gravity's work, the PUMA 560's
joints 2 and 3, rcci.calib.friction_poses.loaded_friction_pose) has a g_w of its own whatever the
DH errors: it is always computed, and the fitted coefficients' errors enter its uncertainty. Gravity
is linear in them, g_w = m . c with m the window's mean regressor row, so their share is at most
sum |m_k| e_k whatever their correlations (the fit prints no covariance): that bound, taken as 3 sd
as the printed errors are, is added in quadrature to the DH spread. Without fitted coefficients the
data file's are used with GRAVITY_TOLERANCE each as their printed error.
"""
from __future__ import annotations

import numpy as np

from rcci.calib.work import hann_edge_weights

# a priori spread (1 sd) of DH errors when the parameter file has no kinematic calibration:
# lengths as Table 3.1's stated uncertainties (0.38-0.64 mm), angles estimated at 0.1 deg
# (estimate: what Table 3.1's length tolerances imply over the PUMA 260's 0.2 m links)
DH_TOLERANCE = (np.radians(0.1), 0.0005, 0.0005, np.radians(0.1))
# a priori error (99.73 %) of a data-file gravity coefficient when none is fitted: hidden truths
# move them 3-10 % (rcci.calib.hidden_truth); a real arm's data file is of that order (estimate)
GRAVITY_TOLERANCE = 0.10
SAMPLES = 24          # Monte Carlo draws of the kinematic errors for g_w's spread
POINTS = 121          # positions along the window


def window_gravity(robot: str, params: dict, joint: int, pose: np.ndarray, window: tuple[float, float],
                   taper: float, seed: int = 0, loaded: bool = False) -> tuple[float, float, str]:
    """(g_w N m, its standard deviation N m, where the model came from) for ``joint``
    (1-based) swept over ``window`` (rad) at ``pose`` (rad), tapered as the pass means are;
    ``loaded``: a window gravity works on by design (g_w computed even without kinematics)."""
    from rcci.models import load_robot
    from rci.simula.arm import SimulatedArm

    model = load_robot(robot)
    n = model.n_joints
    head = {"calib": params.get("calib", {"schema": "rcci-calib-params/1", "robot": robot})}
    grav = {k: v for k, v in params.get("gravity_coeffs", {}).items()
            if not k.endswith(("_error", "unit")) and np.isfinite(float(v))} if "gravity_coeffs" in params else {}
    kin = params.get("kinematics", {})
    have_kin = all(k in kin for k in ("dtheta", "dd", "da", "dalpha"))
    base, dropped = _tuned(model, robot, head, grav)
    if dropped:
        grav = {k: v for k, v in grav.items() if k not in dropped}
    if have_kin:
        e = np.nan_to_num(np.array([kin[k] for k in ("dtheta", "dd", "da", "dalpha")], dtype=float).T)
        sd = np.array([kin.get(f"{k}_std", [np.nan] * n) for k in ("dtheta", "dd", "da", "dalpha")], dtype=float).T
        sd = np.nan_to_num(sd)
        source = "the fitted kinematics" + ("" if grav else " and the data file's gravity coefficients")
    else:
        e = np.zeros((n, 4))
        sd = np.tile(DH_TOLERANCE, (n, 1))
        source = ("no kinematic calibration: an a priori DH spread (0.1 deg, 0.5 mm)"
                  + ("" if grav else " and the data file's gravity coefficients"))
    if dropped:
        source += f" (the data file's {', '.join(dropped)}: simula fixes link masses, not that coefficient)"
    revolute = np.array([[k == "revolute"] for k in model.kinds])
    if have_kin and np.any(e * ~revolute):
        source += " (a slide's fitted DH errors left out: simula's arm models none)"
    e, sd = e * revolute, sd * revolute                  # simula has no DH errors for a slide
    th = np.linspace(window[0], window[1], POINTS)
    w = hann_edge_weights(th, window[0], window[1], taper)
    q = np.tile(np.asarray(pose, dtype=float), (POINTS, 1))
    q[:, joint - 1] = th

    def mean_gravity(errors: np.ndarray) -> float:
        from dataclasses import replace

        arm = SimulatedArm(model, replace(base, dh_errors=errors), seed=0, start="ready")
        tau = np.array([arm.gravity(x)[joint - 1] for x in q])
        return float(np.sum(w * tau) / np.sum(w))

    g = mean_gravity(e) if have_kin or loaded else 0.0    # other windows are gravity-free by design
    rng = np.random.default_rng(seed)
    draws = [mean_gravity(e + sd * rng.standard_normal(e.shape)) for _ in range(SAMPLES)]
    dh_sd = float(np.std(draws, ddof=1))
    if not loaded:
        return g, dh_sd, source
    coeff_sd, how = coefficient_sd(robot, params, joint, pose, window, taper)
    return g, float(np.hypot(dh_sd, coeff_sd)), source + "; " + how


def coefficient_sd(robot: str, params: dict, joint: int, pose: np.ndarray, window: tuple[float, float],
                   taper: float) -> tuple[float, str]:
    """(1 sd N m of g_w from the gravity coefficients' errors, where they came from): the bound
    sum |m_k| e_k / 3 with m the window's mean regressor row (tapered as the passes) and e_k each
    coefficient's printed (99.73 %) error, fitted (``[gravity_coeffs] NAME_error``) or
    GRAVITY_TOLERANCE of the data file's value."""
    from rcci.calib.friction_poses import mean_gravity_row
    from rcci.calib.robot import robot_info

    info = robot_info(robot)
    m = mean_gravity_row(info, joint, window[0], window[1], np.asarray(pose, dtype=float), POINTS, taper)
    fitted = params.get("gravity_coeffs", {})
    errs, fallback = [], []
    for name in info.gravity_names:
        e = fitted.get(f"{name}_error")
        if e is None or not np.isfinite(float(e)):
            fallback.append(name)
            e = GRAVITY_TOLERANCE * abs(float(info.nominal["gravity_coeffs"][name]["value"]))
        errs.append(float(e))
    bound = float(np.abs(m) @ np.array(errs))
    how = ("the gravity coefficients' fitted errors" if not fallback else
           f"{100 * GRAVITY_TOLERANCE:.0f} % of the data file's {', '.join(fallback)} as their error")
    return bound / 3.0, how


def _tuned(model, robot: str, head: dict, grav: dict):
    """simula's truth with the fitted gravity coefficients ``grav`` where simula can take them
    (rci.simula.arm.gravity_moves: those a centre of mass carries); the others (a mass-type
    coefficient such as the Stanford arm's cm3) keep the data file's value and are returned."""
    from rci.simula.arm import gravity_moves
    from rci.simula.params import apply_params, truth_from_model

    movable = gravity_moves(model)
    dropped = [k for k, v in grav.items()
               if k not in movable and abs(float(v) - model.gravity_coeffs[k].value) >= 1e-15]
    keep = {k: v for k, v in grav.items() if k not in dropped}
    base = truth_from_model(model)
    if keep:
        base = apply_params({**head, "gravity_coeffs": keep}, "the parameter file", robot, base)
    return base, dropped
