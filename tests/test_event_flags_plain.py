"""Event flag triples (rccl.events, thesis 5.6.3) on plain RCCL generators, stepped sample by sample.

No RCI and no simula: a Planner on a TrajectoryGenerator (the kinematics stand-in), so the
sample in which a flag takes effect is exact. Checks the base generator's early exit
(``abort``, a request's per-sample ``watch``) and that a request queued or admitted while
the arm holds at rest starts at the next sample.
"""
from __future__ import annotations

import numpy as np
import pytest

import test_rccl_standin as K
from rccl import events as ev
from rccl.ending import MotionEnd
from rccl.events import ABORTED, DONE, NULL, EventError
from rccl.limits import load_limits
from rccl.planner import Planner
from rccl.position import joint_position
from rccl.trajectory import Kinematics, TrajectoryGenerator

Q0 = np.radians([0.0, 80.0, -170.0, 10.0, -60.0, 0.0])
KIN = Kinematics(K)
LIM = load_limits("puma260")
DT = 1.0 / 36.0


@pytest.fixture
def arms():
    """Two stand-in arms attached to the event flags (detached afterwards)."""
    made = []
    for name in ("left", "right"):
        gen = TrajectoryGenerator(KIN, LIM, DT, Q0.copy())
        arm = Planner(KIN, LIM, gen)
        ev.attach(arm, name)
        made.append(arm)
    yield made
    for arm in made:
        ev.detach(arm)


def waist(arm, delta: float, name: str):
    q = arm.gen.q.copy()
    q[0] += delta
    return joint_position(name, KIN, q), q


def slow_far_motion(arm):
    """Queue a 20 s waist turn of 0.8 rad with an EFT; (its EFT, the destination joints)."""
    far, q_far = waist(arm, 0.8, "far")
    arm.settime(0.2, 20.0)
    return ev.move_ev(arm, far), q_far


def run(*arms, samples: int) -> None:
    for _ in range(samples):
        for arm in arms:
            arm.gen.step()


def rest(arm, limit: int = 4000) -> None:
    """Step until the arm has nothing queued or running and its command stands still."""
    for _ in range(limit):
        q = arm.gen.q.copy()
        arm.gen.step()
        if not arm.gen.busy and np.array_equal(arm.gen.q, q):
            return
    raise AssertionError("the arm did not come to rest")


def first_moving_sample(arm, q_before: np.ndarray, limit: int = 50) -> int:
    """Step until the command leaves ``q_before``; how many steps that took."""
    for k in range(1, limit + 1):
        arm.gen.step()
        if not np.array_equal(arm.gen.q, q_before):
            return k
    raise AssertionError("the arm did not move")


def test_a_move_from_rest_starts_at_the_next_sample():
    gen = TrajectoryGenerator(KIN, LIM, DT, Q0.copy())
    arm = Planner(KIN, LIM, gen)
    run(arm, samples=40)                          # well into the hold
    p, _ = waist(arm, 0.3, "p")
    arm.move(p)
    assert first_moving_sample(arm, Q0) == 1


def test_a_postponed_motion_holds_then_starts_at_the_next_sample_after_start_ev(arms):
    left, _ = arms
    p, q_dest = waist(left, 0.3, "p")
    e = ev.move_ev(left, p, start=None)
    run(left, samples=60)                          # 1.7 s: several hold segments' worth
    assert e.status == NULL and e.request.status == "queued"
    np.testing.assert_array_equal(left.gen.q, Q0)
    ev.start_ev(9, e)
    assert first_moving_sample(left, Q0) == 1
    assert e.status == 9
    rest(left)
    assert e.status == DONE
    np.testing.assert_allclose(left.gen.q, q_dest, atol=1e-9)


def test_stop_ev_ends_a_running_motion_in_the_next_sample_and_the_arm_comes_to_rest(arms):
    left, _ = arms
    e, q_far = slow_far_motion(left)
    run(left, samples=200)                         # 5.6 s into a 20 s motion
    assert e.status > 0
    k = left.gen.samples
    ev.stop_ev(-6, e)
    left.gen.step()
    end = e.request.ended
    assert (end.reason, end.what, end.code, end.sample) == ("stop", "stop_ev", -6, k)
    assert e.status == -6 and e.request.status == "done"
    rest(left)
    q_end = left.gen.q.copy()
    run(left, samples=10)
    np.testing.assert_array_equal(left.gen.q, q_end)       # at rest
    assert abs(q_end[0] - q_far[0]) > 0.3                   # far from where it was going
    # the halt keeps within the joint acceleration limits (no jump of the commanded velocity)
    assert not left.gen.errors


def test_stop_before_start_deletes_the_motion_and_the_next_one_runs(arms):
    left, _ = arms
    never, _ = waist(left, 0.5, "never")
    a = ev.move_ev(left, never, start=None)
    other, q_other = waist(left, -0.2, "other")
    b = ev.move_ev(left, other)
    run(left, samples=20)
    assert b.status == NULL
    ev.stop_ev(-7, a)
    rest(left)
    assert a.status == -7 and a.request.status == "failed" and a.t_started is None
    assert b.status == DONE
    np.testing.assert_allclose(left.gen.q, q_other, atol=1e-9)


@pytest.mark.parametrize("leader_first", [True, False])
def test_start_after_across_two_plain_arms_starts_the_follower_within_one_sample(arms, leader_first):
    left, right = arms
    pa, _ = waist(left, 0.3, "pa")
    pb, q_b = waist(right, -0.3, "pb")
    a = ev.move_ev(left, pa)
    b = ev.move_ev(right, pb, start=a)
    order = (left, right) if leader_first else (right, left)
    while a.status >= 0:
        assert b.status == NULL
        np.testing.assert_array_equal(right.gen.q, Q0)         # the follower holds
        run(*order, samples=1)
    # the leader's last sample set the follower's start flag; the follower's next step took it:
    # in the same cycle when it steps after the leader, in the next one otherwise
    if leader_first:
        assert b.traj_started == pytest.approx(a.traj_ended)
        assert not np.array_equal(right.gen.q, Q0)
    else:
        assert b.status == NULL
        assert first_moving_sample(right, Q0) == 1
        assert b.traj_started == pytest.approx(a.traj_ended + DT)
    assert b.start == ev.START
    rest(right)
    np.testing.assert_allclose(right.gen.q, q_b, atol=1e-9)


def test_stop_abort_flushes_and_halts_a_plain_arm(arms):
    left, _ = arms
    a, q_far = slow_far_motion(left)
    left.settime(0.2, 1.0)
    b = ev.move_ev(left, joint_position("later", KIN, Q0))
    run(left, samples=100)
    ev.stop_abort(left)
    rest(left)
    assert a.status == ABORTED and b.status == ABORTED and b.t_started is None
    assert abs(left.gen.q[0] - q_far[0]) > 0.3


def test_abort_and_watch_on_the_base_generator():
    gen = TrajectoryGenerator(KIN, LIM, DT, Q0.copy())
    arm = Planner(KIN, LIM, gen)
    p, _ = waist(arm, 0.6, "p")
    arm.settime(0.2, 10.0)
    req = arm.move(p)
    run(arm, samples=50)
    fired = []

    def watch(g):
        fired.append(g.samples)
        return MotionEnd("stop", "test", code=-1, t=g.t, sample=g.samples) if g.samples >= 60 else None

    req.watch = watch
    run(arm, samples=20)
    assert fired[0] == 50 and fired[-1] == 60           # called once per sample while it ran, not after
    assert req.status == "done" and req.ended.sample == 60
    assert gen.ended == [(req, req.ended)]
    q2 = arm.move(joint_position("back", KIN, Q0))      # the arm takes new motions after an early end
    rest(arm)
    assert q2.status == "done"
    np.testing.assert_allclose(gen.q, Q0, atol=1e-9)


def test_objects_without_a_running_generator_are_refused():
    class NotAnArm:
        gen = None

    with pytest.raises(EventError, match="need an arm whose RCCL control is running"):
        ev.attach(NotAnArm(), "nothing")
