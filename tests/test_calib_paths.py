"""rcci.calib.paths: a path kept within every joint's velocity limit (a move whose largest change
is in radians can drive a slide, in metres, past its limit: the Stanford arm's and the Microbo's
breakaway ramps stopped on R_REQVEL before Path.within)."""
from __future__ import annotations

import numpy as np

from rcci.calib.paths import Path, PathSegment


def _peak_speeds(path: Path, rate: float = 1000.0) -> np.ndarray:
    return np.max(np.abs(np.diff(path.sample(rate), axis=0)), axis=0) * rate


def test_within_caps_the_joint_nearest_its_limit_and_leaves_the_rest() -> None:
    start = np.array([0.0, 0.0, 0.3, 0.0])
    end = np.array([1.0, -0.5, 1.2, 0.0])              # joint 3 a slide: 0.9 m against 1 rad
    vmax = np.array([2.0, 2.0, 0.5, 2.0])
    raw = Path((PathSegment(start, end, 0.6, 1.5, 0.1),))
    assert _peak_speeds(raw)[2] > 0.5                       # 0.54 m/s: past the slide's limit
    capped = raw.within(vmax)
    peak = _peak_speeds(capped)
    assert np.all(peak <= 0.8 * vmax + 1e-6) and peak[2] >= 0.8 * 0.5 - 0.01
    np.testing.assert_allclose(capped.sample(1000.0)[-1], end)
    slow = Path((PathSegment(start, end, 0.3, 1.5, 0.1),))
    assert slow.within(vmax).segments == slow.segments       # already within: unchanged


def test_breakaway_moves_of_an_arm_with_a_slide_stay_within_its_limits() -> None:
    """Every step of the Stanford arm's joint-3 ramps (before the ramps themselves) within 0.8 x limits."""
    from rcci.calib.breakaway_program import _sweep
    from rcci.models import load_robot

    m = load_robot("stanford")
    vmax = np.asarray(m.max_velocity, float)
    q = 0.5 * (np.asarray(m.lower) + np.asarray(m.upper))
    sp = _sweep(q, 2, 0.1, 6.0, 500, vmax)
    assert np.max(np.abs(np.diff(sp[:, 2]))) * 500 <= 0.8 * vmax[2] + 1e-6


def test_breakaway_plans_fit_every_arms_ranges() -> None:
    """The thesis's poses where they fit (the PUMAs: unchanged), else the arm's own friction pose:
    every pose, ramp position and warm-up inside the ranges (the Stanford arm's slide in metres)."""
    from rcci.calib.breakaway_program import FRICTION_POSES, breakaway_plans
    from rcci.calib.experiments import DEG
    from rcci.calib.robot import robot_info
    from rcci.calib.unmeasured import unmeasured_joints

    for robot in ("puma260", "puma560", "stanford", "microbo"):
        info = robot_info(robot)
        joints = [j for j in range(1, 7) if j not in unmeasured_joints(robot)]
        lo, hi = np.asarray(info.lower), np.asarray(info.upper)
        for p in breakaway_plans(info.nominal["friction"]["static_pos"]["values"], info.drive.G, joints, info):
            assert np.all(p.pose >= lo) and np.all(p.pose <= hi), (robot, p.joint)
            k = p.joint - 1
            assert all(lo[k] + p.warm_half <= x <= hi[k] - p.warm_half for x in p.positions), (robot, p.joint)
            if robot.startswith("puma"):
                np.testing.assert_allclose(p.pose, np.array(FRICTION_POSES[p.joint][0]) * DEG)


def test_static_halts_keep_every_joint_within_its_limit() -> None:
    """Table 4.6's random halts: the Microbo's slides (0.2 m/s) and the Stanford boom within 0.8
    of their limits (the Microbo's campaign stopped on R_REQVEL, 0.224 m/s), the PUMAs' unchanged."""
    from rcci.calib.experiments import static_plan
    from rcci.models import load_robot

    for robot in ("puma260", "puma560", "stanford", "microbo"):
        m = load_robot(robot)
        lo, hi, v = (np.asarray(x, float) for x in (m.lower, m.upper, m.max_velocity))
        plan = static_plan(lo, hi, halts=30, vmax=v)
        for path in (plan.warmup, plan.path):
            assert np.all(_peak_speeds(path, 100.0) <= 0.8 * v + 1e-6), robot
        if robot.startswith("puma"):
            np.testing.assert_array_equal(plan.path.sample(100.0), static_plan(lo, hi, halts=30).path.sample(100.0))


def test_measurement_plans_pass_no_joint_past_95_percent_of_its_limit() -> None:
    """run_plan keeps every move under SPEED_SHARE_MAX of the joints' limits: the Stanford boom's
    sensitivity arc (planned in degrees per second) is slowed, the PUMAs' plans are unchanged."""
    from rcci.calib.plan import MeasurementPlan
    from rcci.calib.program import SPEED_SHARE_MAX
    from rcci.calib.regen import campaign_plans
    from rcci.calib.registry import RegenContext
    from rcci.calib.robot import robot_info
    from rcci.models import load_robot

    for robot in ("puma260", "stanford"):
        ctx = RegenContext("/nonexistent", "/nonexistent/.work", 1, None, robot_info(robot))
        kinds = ("sensitivity", "friction")
        plans, _ = campaign_plans(ctx, kinds, skip_refused=True)
        v = np.asarray(load_robot(robot).max_velocity, float)
        slowed = {p.name for _, p in plans if isinstance(p, MeasurementPlan)
                  and p.path.within(v, SPEED_SHARE_MAX).segments != p.path.segments}
        assert slowed == (set() if robot == "puma260" else {"sensitivity-j3-unloaded", "sensitivity-j3-loaded"})


def test_window_gravity_keeps_the_data_files_value_of_a_coefficient_simula_cannot_take() -> None:
    """The Stanford arm's fitted cm3 (a mass-type coefficient): calib report stopped on simula's
    ParamsError; the window's gravity now uses the data file's cm3 and says so."""
    from rcci.calib.robot import robot_info
    from rcci.calib.window_gravity import window_gravity

    info = robot_info("stanford")
    coeffs = {n: 1.05 * float(info.nominal["gravity_coeffs"][n]["value"]) for n in info.gravity_names}
    assert "cm3" in coeffs
    params = {"calib": {"schema": "rcci-calib-params/1", "robot": "stanford"}, "gravity_coeffs": coeffs}
    q = np.array([0.0, 0.0, 0.787, 1.571, 0.0, 0.0])
    g, sd, source = window_gravity("stanford", params, 2, q, (-0.3, 0.3), 0.1, loaded=True)
    assert np.isfinite(g) and np.isfinite(sd) and "cm3" in source
