"""Unit tests of simula's environment (rci.simula.environment): contact forces, joint torques, conveyor."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pinocchio as pin
import pytest

from rci.chg import POS, Chg
from rcci.models import load_robot
from rci.simula.environment import (CONVEYOR_CHANNEL, Box, Conveyor, Environment, EnvironmentArm,
                                    parse_environment, plane)
from rci.simula.params import truth_from_model

PUMA = load_robot("puma260")
DT = 1 / 36


def test_plane_pushes_out_along_its_normal_with_damping_never_pulling():
    fl = plane(0.1, stiffness=1e4, damping=50.0)
    assert np.all(fl.contact(np.array([0.2, 0, 0.11]), np.zeros(3)) == 0)
    np.testing.assert_allclose(fl.contact(np.array([0.2, 0, 0.099]), np.zeros(3)), [0, 0, 10.0], atol=1e-9)
    np.testing.assert_allclose(fl.contact(np.array([0.2, 0, 0.099]), np.array([0, 0, -0.1])), [0, 0, 15.0])
    # leaving fast: damping would pull; the force is clipped at zero
    np.testing.assert_allclose(fl.contact(np.array([0.2, 0, 0.099]), np.array([0, 0, 1.0])), 0.0)


def test_box_nearest_face_and_friction():
    b = Box(np.array([0.0, 0.0, 0.0]), np.array([0.2, 0.1, 0.1]), stiffness=1e4, damping=0.0, mu=0.3)
    f = b.contact(np.array([0.199, 0.05, 0.05]), np.zeros(3))       # just inside the +x face
    np.testing.assert_allclose(f, [10.0, 0, 0], atol=1e-9)
    f = b.contact(np.array([0.1, 0.05, 0.098]), np.array([0.05, 0, 0]))  # top face, sliding along +x
    np.testing.assert_allclose(f, [-0.3 * 20.0, 0, 20.0], atol=1e-9)
    with pytest.raises(ValueError, match="below"):
        Box(np.zeros(3), np.array([0.1, -0.1, 0.1]))


def test_joint_torques_are_j_transpose_f_by_virtual_work():
    env = Environment((plane(0.18),), None, np.array([0.0, 0.0, 0.05]))
    pm = pin.buildModelFromUrdf(str(PUMA.urdf_path))
    pd = pm.createData()
    q = np.array(PUMA.poses["ready"], float)
    tau, f = env.joint_torques(pm, pd, q, np.zeros(6))
    p, jp = env.tool_point(pm, pd, q)
    assert p[2] < 0.18 and f[2] > 0
    # virtual work: a small joint motion dq does work tau.dq = f.dp
    dq = np.random.default_rng(3).normal(size=6) * 1e-7
    p2, _ = env.tool_point(pm, pd, q + dq)
    assert tau @ dq == pytest.approx(f @ (p2 - p), rel=1e-4)


def test_conveyor_position_and_encoder_wraps():
    c = Conveyor(np.array([0.3, -0.2, 0.1]), np.array([0.0, 0.05, 0.0]))
    np.testing.assert_allclose(c.position(2.0), [0.3, -0.1, 0.1])
    assert c.encoder(0.0) == 0 and c.encoder(1.0) == 500          # 5 cm = 500 counts of 0.1 mm
    assert c.encoder(4.096 / 0.05 * 0.1 + 1e-9) == 0              # 0.4096 m: one wrap
    assert -2048 <= c.encoder(5.0) <= 2047


def test_parse_environment():
    env = parse_environment(["plane:z=0.12,k=3e4", "tool:z=0.05", "conveyor:x=0.3,vy=0.02"])
    assert env.boxes[0].hi[2] == 0.12 and env.boxes[0].stiffness == 3e4
    np.testing.assert_allclose(env.tool, [0, 0, 0.05])
    np.testing.assert_allclose(env.conveyor.velocity, [0, 0.02, 0])
    for bad, match in (["plane:h=1"], "needs z"), (["cube:x0=1"], "kind"), (["box:x0=1,q=2"], "unknown"), \
            (["plane:z=abc"], "key=number"):
        with pytest.raises(ValueError, match=match):
            parse_environment(bad)


def test_arm_pressed_onto_the_plane_by_its_servo_feels_the_reaction():
    truth = truth_from_model(PUMA)
    truth = replace(truth, disturbances=replace(truth.disturbances, start_warm=True))
    env = Environment((plane(0.1542),), Conveyor(np.zeros(3), np.array([0.1, 0, 0])), np.array([0.0, 0.0, 0.05]))
    arm = EnvironmentArm(PUMA, truth, start="ready", environment=env)
    c = Chg(nj=6)
    c.power_on.com = 1
    arm.apply(c, DT)
    counts0 = arm.counters()
    for _ in range(20):                                       # hold the ready pose: tool at z = 0.1532
        c = Chg(nj=6)
        for i in range(6):
            c.motion[i].issue(POS, int(counts0[i]))
        arm.apply(c, DT)
        arm.step(DT)
    assert arm.contact_force[2] == pytest.approx(2e4 * (0.1542 - 0.1532), rel=0.02)
    assert np.all(arm.ext == 0.0)                             # the user's external torque is untouched
    s = arm.sample()
    assert s.adcr[CONVEYOR_CHANNEL] == Conveyor(np.zeros(3), np.array([0.1, 0, 0])).encoder(arm.t)
    assert "contact_force" in arm.snapshot()
