"""RCCL on the Microbo Ecureuil (prismatic joints 2 and 3, wrist singular at theta5 = pi) against simula in lockstep.

Until now RCCL had only run the PUMA 260. Here a Cartesian and a joint-mode program run on
``simula --robot microbo`` through ``rccl.open(..., robot="microbo")``; the tool path is
measured on the world side with Pinocchio on the Microbo's URDF from the joint values simula
reports in ``how``. Error cases: a Cartesian line through the wrist singularity, a target
beyond a prismatic stroke, a PUMA-only configuration letter.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from rccl import EQ, T6, TL, Trsf, makeposition
from rccl.exceptions import BadRequest, SingularPath, UnreachableTarget
from rccl.limits import load_limits
from rccl.plots import line_deviation, pinocchio_fk
from rccl.transform import rot, trsl

from rccl_arm import go as shared_go, lockstep_simula, open_arm as shared_open_arm, tail

# joint 1 rad, joints 2-3 m (vertical and radial strokes), joints 4-6 rad: away from theta5 = pi
START = np.array([0.2, 0.20, 0.32, math.radians(-80.0), math.radians(100.0), 0.1])
LIM = load_limits("microbo")


@pytest.fixture(scope="module")
def sim():
    yield from lockstep_simula("microbo")


@pytest.fixture(scope="module")
def world():
    return pinocchio_fk("microbo")


def open_arm(sim, rate_hz: int = 36):
    return shared_open_arm(sim, "microbo", rate_hz)


def go(arm, q, name="start"):
    """Joint-mode move to joint values q; returns T6 there."""
    return shared_go(arm, q, name, rot_speed=1.5)


def test_world_model_agrees_with_the_generated_kinematics(world):
    from rccl.kinematics import microbo
    for q in (START, START + np.array([0.3, 0.05, -0.05, 0.4, 0.6, -0.5])):
        assert np.allclose(world(q), microbo.fk(q), atol=1e-9)


def test_cartesian_straight_line_and_arrival_on_the_microbo(sim, world):
    with open_arm(sim, 36) as arm:
        base = go(arm, START)
        goal = trsl(0.04, -0.03, 0.025) @ base @ rot("z", 0.3)
        p = makeposition("p", T6, EQ, Trsf("P", goal), TL, T6)
        arm.setmod("cartesian")
        arm.setvel(0.05, 0.5)
        n0 = len(arm.trace)
        arm.move(p)
        arm.waitfor(p.end)
        arm.rci.wait(0.3)
    qc, qm = tail(arm, n0)
    a, b = base[:3, 3], goal[:3, 3]
    # the prismatic joints really moved (the line is not a wrist-only motion)
    assert np.ptp(qc[:, 1]) > 0.01 and np.ptp(qc[:, 2]) > 0.01
    for q, what in ((qc, "commanded"), (qm, "measured")):
        pts = np.array([world(x)[:3, 3] for x in q])
        dev = line_deviation(pts, a, b)
        print(f"microbo {what}: max deviation from the line {dev.max() * 1e3:.4f} mm, end point "
              f"{np.linalg.norm(pts[-1] - b) * 1e3:.4f} mm from the goal, {len(q)} samples")
        assert dev.max() <= 1e-4, f"{what} path deviates {dev.max() * 1e3:.4f} mm from the line"
        assert np.linalg.norm(pts[-1] - b) <= 1e-4, f"{what} end point misses by {np.linalg.norm(pts[-1] - b) * 1e3} mm"
    # the tool turned about a fixed axis to the goal orientation
    r_end = world(qm[-1])[:3, :3]
    assert np.allclose(r_end, goal[:3, :3], atol=2e-3)
    assert len(qm) > 20


def test_joint_mode_on_the_microbo_interpolates_and_arrives(sim):
    with open_arm(sim, 36) as arm:
        go(arm, START)
        q_goal = START + np.array([-0.4, 0.06, 0.08, 0.5, 0.4, -0.6])   # rad, m, m, rad, rad, rad
        p = makeposition("pj", T6, EQ, Trsf("J", arm.kinematics.fk(q_goal)), TL, T6)
        arm.setmod("joint")
        arm.setvel(0.1, 1.0)
        n0 = len(arm.trace)
        arm.move(p)
        arm.move(arm.park)
        arm.waitfor(p.end)
        arm.waitfor(arm.park.end)
        arm.rci.wait(0.3)
    qc, qm = tail(arm, n0)
    # a straight line in joint space up to the transition into the move to park
    k = int(np.argmin(np.linalg.norm(qc - q_goal, axis=1)))
    d = q_goal - START
    r = qc[: max(k - 8, 1)] - START
    assert np.max(np.abs(r - np.outer(r @ d / (d @ d), d))) < 1e-9
    assert np.linalg.norm(qc[k] - q_goal) < 0.05          # passed near p (blended into the next move)
    assert np.all(np.abs(np.diff(qc, axis=0)) <= LIM.joint_velocity / 36 * 1.01)
    assert np.allclose(qm[-1], arm.park.joints, atol=3e-4)


def test_microbo_errors_are_refused_at_move(sim):
    with open_arm(sim, 36) as arm:
        base = go(arm, START)
        # beyond joint 2's stroke (0.35 m): 0.2 m straight up
        up = makeposition("up", T6, EQ, Trsf("U", trsl(0.0, 0.0, 0.2) @ base), TL, T6)
        for mode in ("cartesian", "joint"):
            arm.setmod(mode)
            with pytest.raises(UnreachableTarget, match="prismatic joint 2"):
                arm.move(up)
        with pytest.raises(BadRequest, match="no arm"):
            arm.setconf("l")          # the Microbo has only the wrist choice
        # a Cartesian line across theta5 = pi: joints 4 and 6 would have to turn half a turn at once
        q_a, q_b = START.copy(), START.copy()
        q_a[4], q_b[4] = math.pi - 0.25, math.pi + 0.25
        go(arm, q_a, "near")
        across = makeposition("across", T6, EQ, Trsf("X", arm.kinematics.fk(q_b)), TL, T6)
        arm.setmod("cartesian")
        with pytest.raises(SingularPath, match="singularity"):
            arm.move(across)
        assert len(arm.queue) == 0
        # joint mode goes there across theta5 = pi, asking for the other wrist configuration
        arm.setmod("joint")
        arm.setconf("flip")
        arm.move(across)
        arm.waitfor(across.end)
        arm.rci.wait(0.3)
        assert np.allclose(arm.measured_q(), q_b, atol=3e-4)
