"""Redundancy in RCCL on ``simula --robot panda`` in lockstep: a Cartesian straight line with each
free-parameter rule (q7 held, a function of time, far from limits and singularities) and a
self-motion, with both generators; the controller's kinematics are the generated
rccl.kinematics.panda (closed-form IK with q7 given).

Tolerances: the commanded tool point (the generated fk of the commanded joints) stays on the
line to 1e-9 m with the quartic generator (every sample is the IK of a pose on the line; the
IK reproduces its pose to rounding, 1e-12) and to 1e-7 m with Ruckig (its phase-synchronised
profile keeps the 6-vector on a line to its own arithmetic); the measured joints stay within
their ranges; the measured flange during a self-motion stays within 1 mm of where it started
(the servo's tracking lag on simula at these joint speeds, under 1 rad/s: the measured
joints trail the commanded ones by a fraction of a sample's step).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import rccl
from rccl import EQ, T6, TL, Trsf, makeposition
from rccl import redundancy
from rccl.exceptions import SingularPath, UnreachableTarget
from rccl.limits import load_limits
from rccl.plots import pinocchio_fk
from rcci.models import load_robot

from rccl.position import joint_position
from rccl_arm import lockstep_simula, tail

ROBOT = "panda"
LINE_TOL = {"quartic": 1e-9, "ruckig": 1e-7}
OFFSET = np.array([0.08, 0.04, -0.04])       # m, base frame
SELF_TOL = 1e-3                              # m, the measured flange during a self-motion


@pytest.fixture(scope="module")
def sim():
    yield from lockstep_simula(ROBOT)


@pytest.fixture(scope="module")
def world():
    return pinocchio_fk(ROBOT)


@pytest.fixture(scope="module")
def ready():
    return np.array(load_robot(ROBOT).poses["ready"], dtype=float)


def arm_on(sim, generator: str):
    """An RCCL Panda on ``sim`` driven by ``generator``, recording its trace."""
    return rccl.open(sim.url, robot=ROBOT, rate_hz=36, record=True, on_error="raise", timeout=2.0,
                     trajectory=generator)


def go(arm, q: np.ndarray) -> np.ndarray:
    """Joint-mode move to the joints ``q`` (rad; a joint-defined position: q7 too, whatever the
    rule); returns T6 there."""
    arm.setmod("joint")
    arm.setvel(0.1, 1.0)
    p = joint_position("ready", arm.kinematics, q)
    arm.move(p)
    arm.waitfor(p.end)
    return arm.t6


def distance_to_line(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    u = (b - a) / np.linalg.norm(b - a)
    rel = points - a
    return np.linalg.norm(rel - np.outer(rel @ u, u), axis=1)


def line_with(arm, ready, rule: str):
    """From the ready pose, a Cartesian line under ``rule``: (commanded q, measured q, start, goal, f)."""
    t0 = go(arm, ready)
    goal = t0.copy()
    goal[:3, 3] += OFFSET
    arm.setmod("cartesian")
    arm.setvel(0.05, 0.3)
    q70 = float(arm.q[6])
    f = None
    if rule == "time":
        def f(t: float) -> float:
            return q70 + 0.2 * math.sin(1.5 * t)
        arm.setfree(q7=f)
    elif rule == "far":
        arm.setfree("far")
    else:
        arm.setfree("hold")
    p = makeposition("goal", T6, EQ, Trsf("GOAL", goal), TL, T6)
    n0 = len(arm.trace)
    arm.move(p)
    arm.waitfor(p.end)
    arm.rci.wait(0.3)
    arm.setfree()
    qc, qm = tail(arm, n0)
    return qc, qm, t0, goal, f


@pytest.mark.parametrize("generator", ["quartic", "ruckig"])
@pytest.mark.parametrize("rule", ["hold", "time", "far"])
def test_cartesian_line_with_each_rule(sim, world, ready, generator, rule):
    kin_limits = load_limits(ROBOT)
    with arm_on(sim, generator) as arm:
        qc, qm, t0, goal, f = line_with(arm, ready, rule)
        kin = arm.kinematics
        pts = np.array([kin.fk(q)[:3, 3] for q in qc])
        assert np.max(distance_to_line(pts, t0[:3, 3], goal[:3, 3])) < LINE_TOL[generator]
        assert np.linalg.norm(kin.fk(qm[-1])[:3, 3] - goal[:3, 3]) < 1e-3      # the encoders: reached
        for q in np.vstack([qc, qm]):
            assert kin_limits.out_of_range(q) is None, q
        q7 = qc[:, 6]
        moving = np.nonzero(np.abs(q7 - q7[0]) > 0)[0]
        if rule == "hold":
            assert moving.size == 0                       # the same float every sample
        elif rule == "time":
            first = moving[0] - 1
            k = np.arange(first, first + 20)
            assert np.allclose(q7[k], [f((i - first) / 36.0) for i in k], atol=1e-12)
        else:
            steps = np.abs(np.diff(q7))
            assert 0 < np.max(steps) <= redundancy.FAR_STEP + 1e-12


@pytest.mark.parametrize("generator", ["quartic", "ruckig"])
def test_selfmove_keeps_the_flange_still(sim, world, ready, generator):
    with arm_on(sim, generator) as arm:
        t0 = go(arm, ready)
        target = float(ready[6]) - 0.4
        n0 = len(arm.trace)
        req = arm.selfmove(q7=target, duration=2.0)
        arm.waitfor(req)
        arm.rci.wait(0.3)
        qc, qm = tail(arm, n0)
        kin = arm.kinematics
        assert max(float(np.abs(kin.fk(q) - t0).max()) for q in qc) < 1e-9     # commanded: still
        drift = max(float(np.linalg.norm(world(q)[:3, 3] - t0[:3, 3])) for q in qm)
        assert drift < SELF_TOL                                                  # measured: within the lag
        assert qc[-1, 6] == pytest.approx(target, abs=1e-12)
        assert abs(qm[-1, 6] - target) < 1e-3
        assert np.ptp(qc[:, 3]) > 0.01 or np.ptp(qc[:, 0]) > 0.01               # the elbow swung


def test_selfmove_out_of_range_is_refused_on_the_arm(sim, ready):
    with arm_on(sim, "quartic") as arm:
        go(arm, ready)
        with pytest.raises((UnreachableTarget, SingularPath), match="% of the self-motion"):
            arm.selfmove(q7=-2.8, duration=3.0)
        assert not arm.gen.busy
