"""The jerk-limited (Ruckig) trajectory mode against a real simula process, plus its bad-input errors.

Velocity, acceleration and jerk are measured from the commanded joint samples (finite
differences at the sample period), as a servo would see them.
"""
from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

import rccl
from rccl import EQ, T6, TL, Trsf, makeposition
from rccl.ending import MotionEnd
from rccl.exceptions import BadRequest, TrajectoryFault, UnreachableTarget
from rccl.jerk import JerkLimitedGenerator, JerkLimits
from rccl.limits import load_limits
from rccl.transform import rot, trsl

SimulaProcess = pytest.importorskip("rci.simula.process").SimulaProcess

START = np.radians([0.0, 80.0, -170.0, 10.0, -60.0, 0.0])   # well away from singularities
LIM = load_limits("puma260")
JERK = JerkLimits.from_limits(LIM)
RATE = 36
# finite differences of samples of a jerk-limited profile may exceed the continuous bound by rounding only
TOL = 1.0 + 1e-6


@pytest.fixture(scope="module")
def sim():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # Python kinematics when the C kernels are not built
        with SimulaProcess("-p", "--power-on", lockstep=True) as s:
            yield s


def open_arm(sim):
    return rccl.open(sim.url, robot="puma260", rate_hz=RATE, record=True, on_error="raise", timeout=2.0,
                     trajectory="ruckig")


def tour(base: np.ndarray) -> list:
    offsets = [trsl(0.05, 0.0, 0.0), trsl(0.05, 0.05, 0.02) @ rot("z", 0.2), trsl(0.0, 0.05, 0.0) @ rot("x", 0.1),
               trsl(0.0, 0.0, 0.0)]
    return [makeposition(f"p{i}", T6, EQ, Trsf(f"P{i}", o @ base), TL, T6) for i, o in enumerate(offsets)]


def go_start(arm) -> np.ndarray:
    arm.setmod("joint")
    arm.setvel(0.2, 2.0)
    start = makeposition("start", T6, EQ, Trsf("S", arm.kinematics.fk(START)), TL, T6)
    arm.move(start)
    arm.waitfor(start.end)
    return arm.t6


def derivatives(q: np.ndarray, dt: float):
    v = np.diff(q, axis=0) / dt
    a = np.diff(v, axis=0) / dt
    return v, a, np.diff(a, axis=0) / dt


@pytest.mark.parametrize("mode", ["joint", "cartesian"])
def test_tour_reaches_every_target_on_simula(sim, mode):
    with open_arm(sim) as arm:
        assert type(arm.gen) is JerkLimitedGenerator
        base = go_start(arm)
        arm.setmod(mode)
        arm.setvel(0.1, 1.0)
        n0 = len(arm.trace)
        reached = []
        for p in tour(base):
            arm.move(p)
            arm.waitfor(p.end)
            reached.append(np.abs(arm.t6 - p.solve(p.snapshot())).max())
        assert max(reached) < 1e-9, reached
        # simula followed: the measured joints end where the commanded ones did (encoder resolution)
        assert np.abs(arm.measured_q() - arm.q).max() < 1e-3
        q = np.array([x[1] for x in arm.trace[n0:]])
        assert len(q) > 20


def test_joint_mode_keeps_velocity_acceleration_and_jerk_within_the_limits(sim):
    with open_arm(sim) as arm:
        base = go_start(arm)
        arm.setmod("joint")
        arm.setvel(0.1, 10.0)           # the joint caps are the model's limits
        n0 = len(arm.trace)
        for p in tour(base):
            arm.move(p)
        arm.waitfor(p.end)
        q = np.array([x[1] for x in arm.trace[n0:]])
        v, a, j = derivatives(q, 1.0 / RATE)
        rv = np.abs(v).max(axis=0) / JERK.joint_velocity
        ra = np.abs(a).max(axis=0) / JERK.joint_acceleration
        rj = np.abs(j).max(axis=0) / JERK.joint_jerk
        assert rv.max() <= TOL and ra.max() <= TOL and rj.max() <= TOL, (rv, ra, rj)
        # the jerk limit binds (the tour is not so slow that the test would pass trivially)
        assert rj.max() > 0.9


@pytest.mark.parametrize("mode", ["joint", "cartesian"])
def test_queued_positions_blend_within_the_limits(sim, mode):
    """Issue 25: a queued position becomes Ruckig's target while the arm still moves: the tool does
    not stop at the corners, the tour is shorter than rest to rest, and the limits hold."""
    runs = {}
    for blend in (True, False):
        with open_arm(sim) as arm:
            base = go_start(arm)
            arm.gen.blend = blend
            arm.setmod(mode)
            arm.setvel(0.1, 1.0)
            n0 = len(arm.trace)
            ps = tour(base)
            for p in ps:
                arm.move(p)
            arm.waitfor(ps[-1].end)
            q = np.array([x[1] for x in arm.trace[n0:]])
            pts = np.array([arm.kinematics.fk(x)[:3, 3] for x in q])
            speed = np.linalg.norm(np.diff(pts, axis=0), axis=1) * RATE
            moving = np.nonzero(speed > 1e-5)[0]
            corner_speed = []
            for p in ps[:-1]:
                k = int(np.argmin(np.linalg.norm(pts - p.solve()[:3, 3], axis=1)))
                corner_speed.append(speed[max(k - 3, 0):k + 3].min())
            runs[blend] = dict(q=q, pts=pts, time=(moving[-1] + 1 - moving[0]) / RATE, corner=corner_speed,
                               blends=arm.gen.blends)
            assert np.abs(arm.t6 - ps[-1].solve()).max() < 1e-9
    b, r = runs[True], runs[False]
    assert b["blends"] == 3 and r["blends"] == 0
    assert min(b["corner"]) > 0.005 and max(r["corner"]) < 0.002, (b["corner"], r["corner"])   # m/s
    assert b["time"] < 0.97 * r["time"], (b["time"], r["time"])
    if mode == "joint":
        v, a, j = derivatives(b["q"], 1.0 / RATE)
        lim = (JERK.joint_velocity, JERK.joint_acceleration, JERK.joint_jerk)
        assert all((np.abs(x).max(axis=0) / m).max() <= TOL for x, m in zip((v, a, j), lim))
    else:
        v, a, j = derivatives(b["pts"], 1.0 / RATE)
        for x, m in zip((v, a, j), JERK.translational):
            assert np.linalg.norm(x, axis=1).max() <= m * TOL


def test_cartesian_mode_keeps_the_tool_within_its_limits_on_a_straight_line(sim):
    with open_arm(sim) as arm:
        base = go_start(arm)
        arm.setmod("cartesian")
        arm.setvel(0.5, 3.0)            # the Cartesian limits bind
        n0 = len(arm.trace)
        goal = makeposition("goal", T6, EQ, Trsf("G", trsl(0.06, -0.04, 0.03) @ base), TL, T6)
        arm.move(goal)
        arm.waitfor(goal.end)
        q = np.array([x[1] for x in arm.trace[n0:]])
        p = np.array([arm.kinematics.fk(qi)[:3, 3] for qi in q])
        v, a, j = derivatives(p, 1.0 / RATE)
        vt, at, jt = JERK.translational
        # the norms (each coordinate has limit / sqrt(3), rccl.jerk)
        assert np.linalg.norm(v, axis=1).max() <= vt * TOL
        assert np.linalg.norm(a, axis=1).max() <= at * TOL
        assert np.linalg.norm(j, axis=1).max() <= jt * TOL
        assert np.linalg.norm(j, axis=1).max() > 0.5 * jt          # the jerk limit binds (on one coordinate)
        # a straight line: every commanded point on the segment from start to goal
        d = p[-1] - p[0]
        off = np.cross(p - p[0], d / np.linalg.norm(d))
        assert np.linalg.norm(off, axis=1).max() < 1e-9


def test_abort_mid_motion_brakes_to_rest_and_next_move_runs(sim):
    with open_arm(sim) as arm:
        base = go_start(arm)
        arm.setmod("joint")
        arm.setvel(0.1, 10.0)
        far = makeposition("far", T6, EQ, Trsf("F", trsl(0.0, 0.0, -0.08) @ base), TL, T6)
        req = arm.move(far)
        n0 = len(arm.trace)
        arm.rci.wait(5.0, until=lambda: len(arm.trace) >= n0 + 8)
        moving = np.abs(arm.trace[-1][1] - arm.trace[-2][1]).max()
        assert moving > 1e-4                     # mid-motion
        arm.gen.abort(MotionEnd("test", "abort from the test"))
        arm.waitfor(req)
        assert req.ended.reason == "test"
        arm.rci.wait(5.0, until=lambda: not arm.gen.busy)
        n1 = len(arm.trace)
        arm.rci.wait(5.0, until=lambda: len(arm.trace) >= n1 + 3)   # a few samples of holding
        q = np.array([x[1] for x in arm.trace[n0:]])
        v, a, j = derivatives(q, 1.0 / RATE)
        assert np.abs(v[-1]).max() < 1e-9       # at rest
        assert (np.abs(a).max(axis=0) / JERK.joint_acceleration).max() <= TOL
        assert (np.abs(j).max(axis=0) / JERK.joint_jerk).max() <= TOL
        assert np.abs(arm.t6 - far.solve(far.snapshot())).max() > 1e-3   # it stopped short of the target
        # stop() (a second move to the same position, thesis 5.3.4) and a new move still work
        arm.move(far)
        held = arm.stop(0.3)
        arm.waitfor(held)
        assert np.abs(arm.t6 - far.solve(far.snapshot())).max() < 1e-9


def test_unreachable_pose_is_refused_before_moving(sim):
    with open_arm(sim) as arm:
        base = go_start(arm)
        away = makeposition("away", T6, EQ, Trsf("A", trsl(2.0, 0.0, 0.0) @ base), TL, T6)
        with pytest.raises(UnreachableTarget, match="away"):
            arm.move(away)
        q = arm.q
        ok = makeposition("ok", T6, EQ, Trsf("O", trsl(0.02, 0.0, 0.0) @ base), TL, T6)
        arm.move(ok)
        arm.waitfor(ok.end)
        assert np.abs(arm.q - q).max() > 0


@pytest.mark.parametrize("bad", [0.0, math.nan, -1.0, math.inf])
def test_bad_limits_are_named(bad):
    lim = LIM.__class__(LIM.lower, LIM.upper, np.where(np.arange(6) == 2, bad, LIM.joint_velocity),
                        LIM.joint_acceleration)
    with pytest.raises(BadRequest, match="joint 3 velocity limit"):
        JerkLimitedGenerator(rccl.session.load_kinematics("puma260"), lim, 1 / RATE, START)
    with pytest.raises(BadRequest, match="jerk ramp time"):
        JerkLimits.from_limits(LIM, ramp_s=bad)
    with pytest.raises(BadRequest, match="joint 3 velocity limit"):     # refused before any link is opened
        rccl.open("socket://127.0.0.1:1", limits=lim, trajectory="ruckig")


def test_moving_target_replans_every_sample():
    """A variable target moved while the arm runs: the generator re-plans and ends on the new target."""
    kin = rccl.session.load_kinematics("puma260")
    gen = JerkLimitedGenerator(kin, LIM, 1 / RATE, START)
    from rccl.planner import Planner
    arm = Planner(kin, LIM, gen)
    base = kin.fk(START)
    goal = Trsf("G", trsl(0.05, 0.0, 0.0) @ base, kind="variable")
    p = makeposition("goal", T6, EQ, goal, TL, T6)
    req = arm.move(p)
    for _ in range(10):
        gen.step()
    goal.p = tuple((trsl(0.0, 0.05, 0.0) @ base)[:3, 3])        # the target jumps mid-motion
    for _ in range(400):
        gen.step()
        if req.status == "done":
            break
    assert req.status == "done"
    gen.step()
    # done on the new target, at rest (and still following it: the queue is empty)
    assert np.abs(kin.fk(gen.q)[:3, 3] - (trsl(0.0, 0.05, 0.0) @ base)[:3, 3]).max() < 1e-9
    assert np.abs(gen.q - gen.q_prev).max() < 1e-12


def test_a_fault_freezes_the_arm_with_a_named_error():
    kin = rccl.session.load_kinematics("puma260")
    gen = JerkLimitedGenerator(kin, LIM, 1 / RATE, START)
    from rccl.planner import Planner
    arm = Planner(kin, LIM, gen)
    base = kin.fk(START)
    goal = Trsf("G", trsl(0.05, 0.0, 0.0) @ base, kind="variable")
    arm.setmod("cartesian")
    req = arm.move(makeposition("goal", T6, EQ, goal, TL, T6))
    for _ in range(5):
        gen.step()
    goal.p = (3.0, 0.0, 0.0)                                        # out of reach mid-motion
    q = None
    for _ in range(36 * 30):          # it heads for the target and faults where the reach ends
        q = gen.step()
        if gen.faulted is not None:
            break
    q = gen.step()                    # frozen: the same command again
    assert gen.faulted is not None and req.status == "failed"
    assert "goal" in str(gen.faulted)
    with pytest.raises(TrajectoryFault):
        arm.check()
    assert np.array_equal(q, gen.q)


def test_one_arm_has_the_adaptive_primitives_whatever_its_generator():
    from rci.exceptions import DeviceError
    """Issue 25, defect 3: rccl.adaptive.open is rccl.open; one Arm class, both generators."""
    import rccl.adaptive
    from rccl.adaptive.session import AdaptiveArm
    from rccl.session import Arm
    assert AdaptiveArm is Arm
    for kind in ("quartic", "ruckig"):
        arm = Arm("socket://127.0.0.1:1", trajectory=kind)     # not opened: nothing is connected
        for name in ("limit", "evalfn", "add_check", "comply", "lock", "cond", "move", "setvel"):
            assert callable(getattr(arm, name)), (kind, name)
    with pytest.raises(DeviceError, match="cannot open robot link"):    # the same open, the same error
        rccl.adaptive.open("socket://127.0.0.1:1", trajectory="ruckig", timeout=0.5)


def test_unknown_trajectory_is_named():
    with pytest.raises(ValueError, match="'bezier' is not 'quartic'"):
        rccl.open("socket://127.0.0.1:1", trajectory="bezier")


def test_bad_jerk_record_is_named():
    with pytest.raises(BadRequest, match="joint 2 jerk limit"):
        JerkLimits(JERK.joint_velocity, JERK.joint_acceleration, np.array([1.0, math.nan, 1, 1, 1, 1]),
                   JERK.translational, JERK.rotational)
    with pytest.raises(BadRequest, match="rotational jerk limit"):
        JerkLimits(JERK.joint_velocity, JERK.joint_acceleration, JERK.joint_jerk, JERK.translational, (1.0, 1.0, 0.0))


def test_a_ruckig_refusal_freezes_the_arm_with_the_move_named():
    """Ruckig's own input check (a NaN in the target) becomes a named fault; the arm holds."""
    kin = rccl.session.load_kinematics("puma260")
    gen = JerkLimitedGenerator(kin, LIM, 1 / RATE, START)
    from rccl.planner import Planner
    arm = Planner(kin, LIM, gen)
    req = arm.move(makeposition("goal", T6, EQ, Trsf("G", trsl(0.03, 0.0, 0.0) @ kin.fk(START)), TL, T6))
    for _ in range(3):
        gen.step()
    gen._inp.target_position = [math.nan] * 6       # what a broken target would hand Ruckig
    q = gen.q.copy()
    assert np.array_equal(gen.step(), q)
    assert req.status == "failed" and "move(goal): Ruckig refused the input" in str(gen.faulted)
