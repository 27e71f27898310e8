"""The measurement plans: paths that do what the thesis's experiments need."""
from __future__ import annotations

import numpy as np
import pytest

from calib.experiments import (FRICTION_POSES, friction_plans, gravity_plans,
                               sensitivity_plans, static_plan)
from calib.robot import robot_info
from calib.work import find_passes

INFO = robot_info("puma260")


@pytest.mark.parametrize("joint", sorted(FRICTION_POSES))
def test_friction_window_has_no_potential_energy_change(joint):
    (plan,) = friction_plans([joint])
    lo, hi = plan.meta["window"]
    q = np.array(plan.meta["pose"])
    # gravity work over the window must vanish whatever the coefficients: every
    # regressor column integrates to zero
    th = np.linspace(lo, hi, 401)
    rows = []
    for x in th:
        qq = q.copy()
        qq[joint - 1] = x
        rows.append(INFO.regressor(qq)[joint - 1])
    integral = np.trapezoid(np.array(rows), th, axis=0)
    assert np.abs(integral).max() < 1e-9


def test_friction_path_cruises_through_the_window_at_each_speed():
    (plan,) = friction_plans([2])
    lo, hi = plan.meta["window"]
    s = plan.path.sample(36.0)
    assert INFO.lower[1] <= s[:, 1].min() and s[:, 1].max() <= INFO.upper[1]
    passes = find_passes(s[:, 1], lo, hi)
    assert len(passes) == 2 * len(plan.meta["speeds"])
    for p, v in zip(passes[::2], plan.meta["speeds"]):
        speed = np.abs(np.diff(s[p.first:p.last + 1, 1])) * 36.0
        assert speed == pytest.approx(v, rel=1e-6)


def test_every_plan_stays_within_the_joint_ranges():
    plans = (friction_plans() + sensitivity_plans(2.0, 0.05)
             + gravity_plans(INFO.regressor, INFO.lower, INFO.upper)
             + [static_plan(INFO.lower, INFO.upper)])
    for plan in plans:
        s = plan.path.sample(36.0)
        assert (s >= INFO.lower - 1e-9).all() and (s <= INFO.upper + 1e-9).all(), plan.name


def test_gravity_repeats_do_equal_gravity_work_in_both_segments():
    plans = gravity_plans(INFO.regressor, INFO.lower, INFO.upper)
    repeats = [p for p in plans if p.meta["role"] == "repeat"]
    assert {p.meta["position"] for p in repeats} == {"j5", "j4", "j3A", "j3B"}
    for p in repeats:
        q0 = np.array(p.meta["q_start"])
        j = p.meta["joint"] - 1
        q0[j] = p.meta["phi_low"]
        assert np.abs(INFO.regressor(q0)[j]).max() < 1e-9, p.name


def test_static_plan_has_275_halts():
    plan = static_plan(INFO.lower, INFO.upper)
    dwells = [s for s in plan.path.segments if s.dwell > 0]
    assert len(dwells) == 275
