"""The RCCL trajectory generator, stepped sample by sample on the kinematics stand-in (pure math).

Checks: straight lines (Cartesian and joint), continuity of velocity and acceleration
across Paul's quartic transitions, velocity limits, queue semantics (holding, stopping by
moving twice, stop(time), order), waitfor/end events, moving targets, and error cases.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import test_rccl_standin as K
from rccl.exceptions import BadRequest, ConfigurationChange, SingularPath, TrajectoryFault, UnreachableTarget
from rccl.limits import load_limits
from rccl.planner import Planner
from rccl.position import EQ, TL, makeposition
from rccl.trajectory import Kinematics, TrajectoryGenerator
from rccl.transform import T6, Trsf, rot, trsl

Q0 = np.radians([0.0, 80.0, -170.0, 10.0, -60.0, 0.0])
KIN = Kinematics(K)
LIM = load_limits("puma260")


def make(rate: float = 36.0, q0=Q0):
    gen = TrajectoryGenerator(KIN, LIM, 1.0 / rate, np.array(q0, dtype=float))
    return gen, Planner(KIN, LIM, gen)


def at(offset: np.ndarray, name: str, kind: str = "const", base=None):
    """A position at FK(Q0) moved by ``offset`` (4x4, in the base frame)."""
    t = Trsf(name.upper(), offset @ (K.fk(Q0) if base is None else base), kind)
    return makeposition(name, T6, EQ, t, TL, T6), t


def run(gen, seconds: float) -> np.ndarray:
    return np.array([gen.step() for _ in range(int(round(seconds / gen.dt)))])


def run_until(gen, cond, limit_s: float = 30.0) -> np.ndarray:
    out = []
    for _ in range(int(limit_s / gen.dt)):
        out.append(gen.step())
        if cond():
            break
    else:
        raise AssertionError("condition not reached")
    return np.array(out)


def positions(q: np.ndarray) -> np.ndarray:
    return np.array([K.fk(x)[:3, 3] for x in q])


def line_deviation(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    u = (b - a) / np.linalg.norm(b - a)
    r = p - a
    return float(np.max(np.linalg.norm(r - np.outer(r @ u, u), axis=1)))


# ------------------------------------------------------------------------------------------
def test_cartesian_mode_tool_moves_on_a_straight_line_and_turns_about_a_fixed_axis():
    gen, arm = make(36.0)
    start = K.fk(Q0)
    pa, _ = at(trsl(-0.06, 0.05, 0.03) @ rot([0.2, 0.3, 1.0], 0.0), "pa")
    dest = trsl(-0.06, 0.05, 0.03) @ start
    dest[:3, :3] = rot([0.2, 0.3, 1.0], 0.4)[:3, :3] @ start[:3, :3]
    target = Trsf("TGT", dest)
    p = makeposition("p", T6, EQ, target, TL, T6)
    arm.setmod("cartesian")
    arm.setvel(0.05, 0.5)
    req = arm.move(p)
    q = run_until(gen, lambda: req.status == "done")
    pts = positions(q)
    dev = line_deviation(pts, start[:3, 3], dest[:3, 3])
    assert dev < 1e-4 * 0.01, f"deviation {dev * 1e3:.6f} mm"  # far below the 0.1 mm target
    assert np.allclose(K.fk(q[-1]), dest, atol=1e-9)
    # rotation about one fixed axis: R(t) R_start^T has the same axis all along
    axes = []
    for x in q[5:-5:5]:
        from rccl.transform import axis_angle
        k, a = axis_angle(K.fk(x)[:3, :3] @ start[:3, :3].T)
        if a > 1e-3:
            axes.append(k)
    assert len(axes) > 3 and np.allclose(axes, axes[0], atol=1e-6)


def test_tool_frame_moves_straight_when_a_tool_is_given():
    gen, arm = make(36.0)
    tool = Trsf("TOOL", trsl(0.0, 0.0, 0.08))
    base_tool = K.fk(Q0) @ tool.matrix
    goal = Trsf("G", trsl(0.04, -0.03, 0.02) @ base_tool @ rot("x", 0.3))
    p = makeposition("p", T6, tool, EQ, goal, TL, tool)
    arm.setmod("c")
    req = arm.move(p)
    q = run_until(gen, lambda: req.status == "done")
    tips = np.array([(K.fk(x) @ tool.matrix)[:3, 3] for x in q])
    assert line_deviation(tips, base_tool[:3, 3], goal.p) < 1e-7
    assert np.allclose(K.fk(q[-1]) @ tool.matrix, goal.matrix, atol=1e-9)


def test_joint_mode_is_a_straight_line_in_joint_space():
    gen, arm = make(36.0)
    q_goal = Q0 + np.radians([20.0, -10.0, 15.0, -30.0, 20.0, 45.0])
    p = makeposition("p", T6, EQ, Trsf("G", K.fk(q_goal)), TL, T6)
    arm.setmod("joint")
    req = arm.move(p)
    q = run_until(gen, lambda: req.status == "done")
    d = q_goal - Q0
    r = q - Q0
    resid = r - np.outer(r @ d / (d @ d), d)
    assert np.max(np.abs(resid)) < 1e-9
    assert np.allclose(q[-1], q_goal, atol=1e-9)
    s = r @ d / (d @ d)
    assert np.all(np.diff(s) >= -1e-12)  # monotone progress, no overshoot


def _fd(q: np.ndarray, dt: float):
    v = np.diff(q, axis=0) / dt
    a = np.diff(v, axis=0) / dt
    return v, a


@pytest.mark.parametrize("mode", ["joint", "cartesian"])
@pytest.mark.parametrize("rate", [36.0, 250.0])
def test_velocity_and_acceleration_continuous_across_transitions(mode, rate):
    gen, arm = make(rate)
    arm.setmod(mode)
    arm.setvel(0.15, 1.5)
    arm.settime(0.3, 0.6)
    arm.setvel(0.15, 1.5)  # back to velocity-defined travel, keeping the 0.3 s transition
    offsets = [trsl(-0.05, 0.05, 0.02), trsl(0.0, 0.08, -0.03) @ rot("z", 0.3), trsl(0.05, 0.0, 0.0)]
    reqs = [arm.move(at(o, f"p{i}")[0]) for i, o in enumerate(offsets)]
    q = run_until(gen, lambda: reqs[-1].status == "done")
    q = np.concatenate([q, run(gen, 0.5)])
    v, a = _fd(q, gen.dt)
    amax = LIM.joint_acceleration
    # no velocity step larger than one sample's worth of the acceleration limit
    assert np.all(np.abs(np.diff(v, axis=0)) <= amax * gen.dt * 1.05 + 1e-9), np.max(np.abs(a) / amax)
    assert np.all(np.abs(v) <= LIM.joint_velocity * 1.001)
    # acceleration has no jumps: its change per sample stays a small fraction of the limit
    jump = np.max(np.abs(np.diff(a, axis=0)) / amax)
    assert jump < (0.7 if rate < 100 else 0.1), jump
    # and the arm comes to rest at the last position
    assert np.allclose(q[-1], q[-2], atol=1e-12)
    assert np.allclose(K.fk(q[-1]), K.fk(Q0) @ np.eye(4) if False else at(offsets[-1], "x")[0].solve(), atol=1e-9)


def test_transition_does_not_pass_through_the_corner_but_stopping_does():
    gen, arm = make(100.0)
    arm.setmod("c")
    arm.setvel(0.1, 1.0)
    pa, ta = at(trsl(-0.06, 0.0, 0.0), "pa")
    pb, tb = at(trsl(-0.06, 0.06, 0.0), "pb")
    arm.move(pa)
    r = arm.move(pb)
    pts = positions(run_until(gen, lambda: r.status == "done"))
    miss = np.min(np.linalg.norm(pts - ta.p, axis=1))
    assert miss > 1e-3  # the corner is cut by the quartic (Figure 5.2)
    gen, arm = make(100.0)
    arm.setmod("c")
    arm.setvel(0.1, 1.0)
    arm.move(pa)
    arm.move(pa)  # stop at pa: move to the same point twice
    r = arm.move(pb)
    pts = positions(run_until(gen, lambda: r.status == "done"))
    assert np.min(np.linalg.norm(pts - ta.p, axis=1)) < 1e-9


def test_transition_listeners_see_every_transition_with_its_window_and_positions():
    gen, arm = make(100.0)
    arm.setmod("c")
    arm.setvel(0.1, 1.0)
    pa, _ = at(trsl(-0.06, 0.0, 0.0), "pa")
    pb, _ = at(trsl(-0.06, 0.06, 0.0), "pb")
    calls, events = [], []
    gen.before_transition.append(lambda: calls.append(gen.t))
    gen.on_transition.append(events.append)
    arm.move(pa)
    r = arm.move(pb)
    run_until(gen, lambda: r.status == "done")
    run(gen, 0.5)
    moving = [(e.from_position, e.to_position) for e in events if e.moving]
    # into pa, the corner pa -> pb, and pb's stop (into its hold); then only holds, which move nothing
    assert moving == [("here", "pa"), ("pa", "pb"), ("pb", "pb")]
    assert all(not e.moving for e in events[3:]) and len(events) > 3
    assert len(calls) == len(events)               # one before-call per transition
    for e in events:                               # 5.5.1: a window of 2 tau at 100 Hz (0.1 s each side)
        assert math.isclose(e.t_end - e.t_start, 0.2, abs_tol=1e-9)
    assert events[1].t_start < r.finished_t and events[2].t_end == pytest.approx(r.finished_t)


def test_empty_queue_holds_and_stop_time_dwells():
    gen, arm = make(36.0)
    arm.setmod("joint")
    p, t = at(trsl(0.03, 0.03, 0.0), "p")
    r1 = arm.move(p)
    r2 = arm.stop(1.0)
    q = run_until(gen, lambda: r2.status == "done")
    still = np.all(np.abs(np.diff(q, axis=0)) < 1e-12, axis=1)
    # the arm stands still at p for about 1 s (the stop's travel time, minus the transitions)
    longest = max(len(s) for s in "".join("1" if x else "0" for x in still).split("0"))
    assert 0.7 <= longest * gen.dt <= 1.2, longest * gen.dt
    assert r1.status == "done"
    q_hold = run(gen, 2.0)
    assert np.allclose(q_hold, q_hold[0], atol=1e-12)          # empty queue: holds
    assert np.allclose(K.fk(q_hold[0]), p.solve(), atol=1e-9)


def test_requests_complete_in_order_and_end_events_count():
    gen, arm = make(36.0)
    pa, _ = at(trsl(0.03, 0.0, 0.0), "pa")
    pb, _ = at(trsl(0.0, 0.03, 0.0), "pb")
    reqs = [arm.move(pa), arm.move(pb), arm.move(pa)]
    order = []
    for _ in range(int(20 / gen.dt)):
        gen.step()
        for r in reqs:
            if r.status == "done" and r not in order:
                order.append(r)
        if len(order) == 3:
            break
    assert order == reqs
    assert pa.end.count == -2 and pb.end.count == -1
    arm.waitfor(pb.end)   # already completed: returns at once (count back to 0)
    assert pb.end.count == 0


def test_speed_and_travel_time():
    gen, arm = make(100.0)
    arm.setmod("c")
    arm.setvel(0.05, 5.0)
    p, _ = at(trsl(0.1, 0.0, 0.0), "p")
    r = arm.move(p)
    q = run_until(gen, lambda: r.status == "done")
    v = np.linalg.norm(np.diff(positions(q), axis=0), axis=1) / gen.dt
    assert abs(np.max(v) - 0.05) < 0.05 * 0.02   # cruises at the requested speed
    gen, arm = make(100.0)
    arm.settime(0.2, 3.0)
    r = arm.move(p)
    q = run_until(gen, lambda: r.status == "done")
    moving = np.nonzero(np.any(np.abs(np.diff(q, axis=0)) > 1e-12, axis=1))[0]
    span = (moving[-1] - moving[0]) * gen.dt
    assert 2.9 <= span <= 3.3, span   # travel 3 s plus the halves of the two 0.2 s transitions


def test_velocity_limits_are_respected_when_asking_for_too_much():
    gen, arm = make(100.0)
    arm.setmod("joint")
    arm.settime(0.1, 0.05)  # far too fast for a 90 degree waist turn
    q_goal = Q0 + np.radians([90.0, 0, 0, 0, 0, 0])
    r = arm.move(makeposition("p", T6, EQ, Trsf("G", K.fk(q_goal)), TL, T6))
    q = run_until(gen, lambda: r.status == "done")
    v, _ = _fd(q, gen.dt)
    assert np.all(np.abs(v) <= LIM.joint_velocity * 1.001)
    assert np.max(np.abs(v[:, 0])) > 0.8 * LIM.joint_velocity[0]


def test_moving_target_is_followed_while_holding():
    gen, arm = make(36.0)
    arm.setmod("c")
    p, t = at(trsl(0.0, 0.0, 0.0), "p", kind="variable")
    centre = t.p.copy()
    n = [0]

    def circle(tr):  # 5.4.4: one degree per sample on a 1 cm circle
        n[0] += 1
        a = math.radians(n[0])
        tr.p = centre + 0.01 * np.array([math.cos(a) - 1.0, math.sin(a), 0.0])

    t.bind(circle)
    arm.move(p)
    q = run(gen, 15.0)
    pts = positions(q[-200:])
    r = np.linalg.norm(pts[:, :2] - (centre[:2] + [-0.01, 0.0]), axis=1)
    assert np.all(np.abs(r - 0.01) < 2e-4)   # the arm traces the circle (Figure 5.3b)


def test_configuration_change_in_joint_mode_with_setconf():
    gen, arm = make(36.0)
    start = K.config_of(Q0)
    arm.setmod("joint")
    arm.setconf("n" if start.wrist < 0 else "f")
    p, _ = at(trsl(0.02, 0.0, 0.0), "p")
    r = arm.move(p)
    q = run_until(gen, lambda: r.status == "done")
    assert K.config_of(q[-1]).wrist == -start.wrist
    assert np.allclose(K.fk(q[-1]), p.solve(), atol=1e-9)


# ------------------------------------------------------------------------------------------
# errors: refused at the planning level, before anything moves
# ------------------------------------------------------------------------------------------
def test_unreachable_target_is_refused_at_move():
    gen, arm = make()
    far, _ = at(trsl(0.5, 0.5, 0.5), "far")
    with pytest.raises(UnreachableTarget, match="move\\(far\\)"):
        arm.move(far)
    assert len(arm.queue) == 0


def test_joint_range_is_checked_at_move():
    gen, arm = make()
    arm.setmod("c")
    q = Q0.copy()
    q[4] = math.radians(-110.0)   # joint 5 beyond its 100 degree range, same configuration
    low = makeposition("low", T6, EQ, Trsf("L", K.fk(q)), TL, T6)
    with pytest.raises(UnreachableTarget, match="joint 5"):
        arm.move(low)
    arm.setmod("j")
    with pytest.raises(UnreachableTarget, match="joint 5 at -1.9199 rad"):
        arm.move(low)


def test_cartesian_path_through_wrist_singularity_is_refused():
    q_a = np.array([0.0, math.radians(80), math.radians(-170), 0.0, -0.3, 0.0])
    gen, arm = make(q0=q_a)
    q_b = q_a.copy()
    q_b[4] = 0.3
    p = makeposition("flip", T6, EQ, Trsf("B", K.fk(q_b)), TL, T6)
    arm.setmod("cartesian")
    with pytest.raises(SingularPath, match="singularity"):
        arm.move(p)
    arm.setmod("joint")
    r = arm.move(p)  # joint mode goes there (keeping the configuration: joints 4 and 6 turn instead)
    q = run_until(gen, lambda: r.status == "done")
    assert np.allclose(K.fk(q[-1]), p.solve(), atol=1e-9)


def test_cartesian_mode_refuses_a_configuration_change():
    gen, arm = make()
    arm.setmod("c")
    arm.setconf("flip" if K.config_of(Q0).wrist > 0 else "noflip")
    p, _ = at(trsl(0.01, 0.0, 0.0), "p")
    with pytest.raises(ConfigurationChange, match="joint"):
        arm.move(p)


@pytest.mark.parametrize("call", [
    lambda a: a.setvel(-1.0, 1.0), lambda a: a.setvel(0.1, float("nan")), lambda a: a.settime(0.0, 1.0),
    lambda a: a.setmod("spline"), lambda a: a.setconf("x"), lambda a: a.setconf("lr"),
    lambda a: a.move("not a position"), lambda a: a.stop(1.0),
])
def test_bad_requests_are_named(call):
    gen, arm = make()
    with pytest.raises(BadRequest):
        call(arm)


def test_target_moving_out_of_reach_stops_the_arm_without_a_jump():
    gen, arm = make(36.0)
    arm.setmod("c")
    p, t = at(trsl(0.05, 0.0, 0.0), "p", kind="variable")
    arm.setvel(0.05, 0.5)
    r = arm.move(p)
    run(gen, 0.5)
    t.p = t.p + np.array([0.6, 0.0, 0.0])   # the target jumps out of the workspace
    q = run(gen, 1.0)
    assert gen.faulted is not None
    assert np.all(np.abs(np.diff(q, axis=0)) <= LIM.joint_velocity * gen.dt * 1.25)
    assert r.status == "failed"
    with pytest.raises(TrajectoryFault, match="stopped the arm"):
        arm.waitfor(p.end, timeout=1.0)


def test_request_refused_at_the_control_level_holds_the_arm_and_is_reported():
    gen, arm = make(36.0)
    arm.setmod("c")
    pa, _ = at(trsl(0.03, 0.0, 0.0), "pa")
    pb, tb = at(trsl(0.0, 0.03, 0.0), "pb", kind="variable")
    ra, rb = arm.move(pa), arm.move(pb)        # both fine when queued
    tb.p = tb.p + np.array([0.5, 0.0, 0.0])   # pb moves out of reach before its motion starts
    q = run_until(gen, lambda: rb.status != "queued" and rb.status != "running")
    q = np.concatenate([q, run(gen, 1.0)])
    assert ra.status == "done" and rb.status == "failed" and isinstance(rb.error, UnreachableTarget)
    assert gen.faulted is None                         # not a freeze: the arm decelerated and holds at pa
    assert np.allclose(K.fk(q[-1]), pa.solve(), atol=1e-9)
    assert np.all(np.abs(np.diff(np.diff(q, axis=0), axis=0)) <= LIM.joint_acceleration * gen.dt ** 2 * 1.05)
    with pytest.raises(TrajectoryFault, match="refused.*pb"):
        arm.move(pa)
    arm.move(pa)                                       # reported once; the session goes on


def test_recover_after_a_fault():
    gen, arm = make(36.0)
    arm.setmod("c")
    p, t = at(trsl(0.05, 0.0, 0.0), "p", kind="variable")
    arm.move(p)
    run(gen, 0.5)
    t.p = t.p + np.array([0.6, 0.0, 0.0])
    run(gen, 0.2)
    with pytest.raises(TrajectoryFault):
        arm.move(p)
    with pytest.raises(TrajectoryFault, match="recover"):
        arm.move(p)
    q_frozen = gen.q.copy()
    arm.recover()
    t.p = t.p - np.array([0.6, 0.0, 0.0])
    r = arm.move(p)
    q = run_until(gen, lambda: r.status == "done")
    assert np.all(np.abs(np.diff(q, axis=0)) <= LIM.joint_velocity * gen.dt * 1.001)
    assert np.allclose(q[0], q_frozen, atol=LIM.joint_velocity.max() * gen.dt)
    # Figure 5.4: a segment whose (variable) destination moved is left from where the arm is, and
    # the holds that follow converge onto the destination (5e-7 m after 0.5 s, 4e-9 m after 1 s)
    q = run(gen, 1.5)
    assert np.allclose(K.fk(q[-1]), p.solve(), atol=1e-9)


def test_cartesian_into_joint_mode_with_a_configuration_change_is_continuous():
    gen, arm = make(100.0)
    start = K.config_of(Q0)
    arm.setmod("c")
    arm.setvel(0.1, 1.0)
    pa, _ = at(trsl(0.04, 0.0, 0.0), "pa")
    pb, _ = at(trsl(0.04, 0.04, 0.0), "pb")
    arm.move(pa)
    arm.setmod("j")
    arm.setconf("n" if start.wrist < 0 else "f")
    r = arm.move(pb)
    q = run_until(gen, lambda: r.status == "done")
    v, a = _fd(q, gen.dt)
    assert np.all(np.abs(np.diff(v, axis=0)) <= LIM.joint_acceleration * gen.dt * 1.05)
    assert np.all(np.abs(v) <= LIM.joint_velocity * 1.001)
    assert K.config_of(q[-1]).wrist == -start.wrist
    assert np.allclose(K.fk(q[-1]), pb.solve(), atol=1e-9)


from hypothesis import HealthCheck, given, settings, strategies as st  # noqa: E402

offset = st.tuples(st.floats(-0.04, 0.04), st.floats(-0.04, 0.04), st.floats(-0.03, 0.03), st.floats(-0.3, 0.3))
move = st.tuples(offset, st.sampled_from(["joint", "cartesian"]), st.floats(0.02, 0.3), st.booleans())


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(move, min_size=1, max_size=4), st.sampled_from([36.0, 100.0]))
def test_random_programs_stay_within_limits_and_end_on_target(moves, rate):
    gen, arm = make(rate)
    last = None
    for (dx, dy, dz, ang), mode, speed, stop in moves:
        p, _ = at(trsl(dx, dy, dz) @ rot("z", ang), f"p{len(moves)}")
        arm.setmod(mode)
        arm.setvel(speed, 10 * speed)
        last = arm.move(p)
        if stop:
            last = arm.stop(0.1)
    q = run_until(gen, lambda: last.status == "done", limit_s=60.0)
    q = np.concatenate([q, run(gen, 0.3)])
    v = np.diff(q, axis=0) / gen.dt
    assert np.all(np.abs(v) <= LIM.joint_velocity * 1.001)
    assert np.all(np.abs(np.diff(v, axis=0)) <= LIM.joint_acceleration * gen.dt * 1.05)
    assert np.allclose(K.fk(q[-1]), last.position.solve(), atol=1e-9)
    assert not gen.errors


def test_sharp_reversal_stops_at_the_corner_instead_of_crawling():
    gen, arm = make(36.0)
    arm.setmod("c")
    arm.setvel(0.3, 3.0)
    pa, ta = at(trsl(0.06, 0.0, 0.0), "pa")
    home, th = at(np.eye(4), "home")
    arm.move(pa)
    r = arm.move(home)     # straight back: too sharp to blend at 0.3 m/s in a 0.2 s transition
    q = run_until(gen, lambda: r.status == "done", limit_s=5.0)
    pts = positions(q)
    assert np.min(np.linalg.norm(pts - ta.p, axis=1)) < 1e-5     # it stopped at pa (between two samples)
    assert len(q) * gen.dt < 2.5                                  # and went back at speed
    v = np.diff(q, axis=0) / gen.dt
    assert np.all(np.abs(np.diff(v, axis=0)) <= LIM.joint_acceleration * gen.dt * 1.05)


class _CountingKinematics:
    """The stand-in's functions, counting the inverse kinematics calls (one pose each)."""

    def __init__(self) -> None:
        self.calls = 0
        self.fk, self.config_of, self.Config, self.ROBOT = K.fk, K.config_of, K.Config, K.ROBOT

    def ik(self, T, config, q_ref=None):
        self.calls += 1
        return K.ik(T, config, q_ref)


def test_path_checked_once_at_move_and_each_cycle_solves_one_pose():
    counting = _CountingKinematics()
    kin = Kinematics(counting)
    gen = TrajectoryGenerator(kin, LIM, 1.0 / 36.0, Q0.copy())
    arm = Planner(kin, LIM, gen)
    arm.setmod("cartesian")
    arm.setvel(0.1, 1.0)
    tour = [at(o, f"p{i}")[0] for i, o in enumerate(
        [trsl(0.05, 0.0, 0.0), trsl(0.05, 0.05, 0.02) @ rot("z", 0.2), trsl(0.0, 0.05, 0.0) @ rot("x", 0.1), np.eye(4)])]
    before = counting.calls
    reqs = [arm.move(p) for p in tour]
    assert counting.calls - before >= 4 * 8          # move() solved every path at >= 8 points
    per_cycle, starts = [], 0
    while not reqs[-1].status == "done":
        seg, n = gen.seg, counting.calls
        gen.step()
        per_cycle.append(counting.calls - n)
        starts += gen.seg is not seg
        assert len(per_cycle) < 2000
    assert not gen.errors and starts >= 4
    assert max(per_cycle) == 1                        # segment starts included: the checked path is reused


def test_variable_target_made_singular_after_move_is_refused_before_its_motion():
    q_a = np.array([0.0, math.radians(80), math.radians(-170), 0.0, -0.3, 0.0])
    gen, arm = make(q0=q_a)
    q_c = q_a.copy()
    q_c[4] = -0.6                                     # first target: further from theta5 = 0
    q_flip = q_a.copy()
    q_flip[4] = 0.3                                   # the other side of the wrist singularity
    pa = makeposition("pa", T6, EQ, Trsf("A", K.fk(q_c)), TL, T6)
    tb = Trsf("B", K.fk(q_a), kind="variable")
    pb = makeposition("pb", T6, EQ, tb, TL, T6)
    arm.setmod("cartesian")
    ra, rb = arm.move(pa), arm.move(pb)               # pb (back to the start) is a fine path when queued
    tb.set(K.fk(q_flip))                              # now the line from pa to pb crosses theta5 = 0
    q = run_until(gen, lambda: rb.status not in ("queued", "running"))
    q = np.concatenate([q, run(gen, 1.0)])
    assert ra.status == "done" and rb.status == "failed" and isinstance(rb.error, SingularPath)
    assert "singularity" in str(rb.error)
    assert gen.faulted is None                        # refused before it started: the arm holds at pa
    assert np.allclose(K.fk(q[-1]), pa.solve(), atol=1e-9)
    assert np.all(np.abs(np.diff(q, axis=0)) <= LIM.joint_velocity * gen.dt * 1.001)
    with pytest.raises(TrajectoryFault, match="singularity"):
        arm.move(pa)


def test_functional_transform_shared_by_two_positions_runs_once_per_sample():
    gen, arm = make(36.0)
    arm.setmod("cartesian")
    calls = []
    w = Trsf("W", kind="variable")
    w.bind(lambda t: calls.append(gen.samples))
    base = K.fk(Q0)
    pa = makeposition("pa", T6, EQ, w, Trsf("A", trsl(0.03, 0.0, 0.0) @ base), TL, T6)
    pb = makeposition("pb", T6, EQ, w, Trsf("B", trsl(0.03, 0.03, 0.0) @ base), TL, T6)
    ra, rb = arm.move(pa), arm.move(pb)
    n = 0
    while rb.status != "done":
        gen.step()
        n += 1
        assert n < 2000
    assert ra.status == "done"
    assert len(calls) == len(set(calls))          # never twice in one sample, transitions included
    assert len(calls) >= n - 2


def test_a_step_a_little_over_the_speed_limit_is_slowed_and_caught_up_a_large_one_is_refused():
    gen, _ = make()
    ok = LIM.joint_velocity * gen.dt
    planned = Q0 + 1.1 * ok * np.eye(6)[0]             # 10 % over on joint 1: a sampled-path estimate's error
    q = gen._check_step(planned)
    assert gen.slowed == 1 and np.isclose(q[0] - Q0[0], ok[0]) and np.allclose(q[1:], Q0[1:])
    gen.q_prev, gen.q = gen.q, q
    q2 = gen._check_step(planned + 0.5 * ok * np.eye(6)[0])   # the next planned step is slow: it catches up
    assert gen.slowed == 1 and np.allclose(q2, planned + 0.5 * ok * np.eye(6)[0])
    with pytest.raises(SingularPath, match="would move"):
        gen._check_step(q2 + 1.3 * ok * np.eye(6)[0])     # beyond STEP_MARGIN of the planned step: a fault
