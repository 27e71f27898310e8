"""Event flag triples (rccl.events, thesis 5.6.3) on two RCCL arms, each on its own lockstep simula.

A PUMA 260 and a Microbo Ecureuil (rccl.adaptive arms, and a plain rccl.open PUMA with an
adaptive Microbo); motions are waist turns from where
each arm stands. Ordering across arms is checked on the wall clock (``t_started``,
``t_ended``) and on what each arm was commanded while it had to wait.
"""
from __future__ import annotations

import time

import numpy as np
import pytest

import rccl
import rccl.adaptive
from rccl import events as ev
from rccl.events import ABORTED, DONE, NULL, START, Deadlock, EventError, UnknownEvent
from rccl.position import joint_position
from rci.simula.process import SimulaProcess


# a request completes in the sample its outgoing transition ends, before that sample's command is
# stored: read right after, the last command can still be the quartic's tail, 1e-4 rad short
END_TOL = 1e-4
from simula_pair import SLACK, sims  # noqa: E402,F401  (sims is a fixture)


@pytest.fixture
def arms(sims):
    with rccl.adaptive.open(sims[0].url, "puma260", **SLACK) as puma, \
            rccl.adaptive.open(sims[1].url, "microbo", **SLACK) as mic:
        ev.attach(puma, "puma")
        ev.attach(mic, "microbo")
        try:
            yield puma, mic
        finally:
            ev.detach(puma)
            ev.detach(mic)


def assert_arrived(arm, q: np.ndarray, tol: float = 2e-3, timeout: float = 10.0) -> None:
    """The arm itself (its encoders in ``how``, not only its commands) settles at ``q`` (rad):
    simula runs with power on, so the arms do move."""
    deadline = time.monotonic() + timeout
    while np.max(np.abs(arm.measured_q() - q)) > tol:
        assert time.monotonic() < deadline, f"measured {arm.measured_q()}, commanded to {q}"
        time.sleep(0.01)


def waist(arm, delta: float, name: str):
    """A position with the waist turned by ``delta`` rad (towards the middle of its range)."""
    q = arm.q.copy()
    q[0] += -abs(delta) if q[0] > 0 else abs(delta)
    return joint_position(name, arm.kinematics, q), q


def test_a_motion_of_one_arm_waits_for_the_end_of_the_others(arms):
    puma, mic = arms
    pa, _ = waist(puma, 0.4, "pa")
    pb, qb = waist(mic, 0.3, "pb")
    mic_q0 = mic.q.copy()
    a1 = ev.move_ev(puma, pa)
    b1 = ev.move_ev(mic, pb, start=a1)          # the Microbo starts when the PUMA's motion ends
    polled = 0
    while a1.status >= 0:                        # while the PUMA is pending or moving...
        assert b1.status == NULL and b1.start == NULL
        np.testing.assert_array_equal(mic.q, mic_q0)          # ...the Microbo is commanded to stay
        polled += 1
        time.sleep(0.001)
    assert polled > 3
    assert ev.wait_ev(b1, timeout=20) == DONE
    assert a1.status == DONE and b1.start == START
    assert a1.t_ended <= b1.t_started < a1.t_ended + 0.1      # started by A's trajectory level, at once
    np.testing.assert_allclose(mic.q, qb, atol=END_TOL)
    assert_arrived(mic, qb)
    assert_arrived(puma, pa.joints)


def test_start_ev_starts_two_arms_together(arms):
    puma, mic = arms
    pa, qa = waist(puma, 0.2, "pa")
    pb, qb = waist(mic, 0.2, "pb")
    q0 = puma.q.copy(), mic.q.copy()
    a, b = ev.move_ev(puma, pa, start=None), ev.move_ev(mic, pb, start=None)    # postponed
    time.sleep(0.2)                               # hundreds of samples of both lockstep arms
    assert (a.status, b.status) == (NULL, NULL)
    np.testing.assert_array_equal(puma.q, q0[0])
    np.testing.assert_array_equal(mic.q, q0[1])
    t_a, t_b = puma.gen.t, mic.gen.t             # each arm's own clock when the flag is set
    ev.start_ev(7, a, b)
    assert ev.wait_ev(a, timeout=20) == DONE and ev.wait_ev(b, timeout=20) == DONE
    assert (a.start, b.start) == (7, 7)
    # together: each motion begins in the first sample of its arm's clock after the flag (not a
    # wall-clock bound between two lockstep processes, see test_stop_ev_stops_two_arms_together)
    assert 0 <= a.traj_started - t_a <= puma.gen.dt + 1e-9
    assert 0 <= b.traj_started - t_b <= mic.gen.dt + 1e-9
    np.testing.assert_allclose(puma.q, qa, atol=END_TOL)
    np.testing.assert_allclose(mic.q, qb, atol=END_TOL)
    assert_arrived(puma, qa)
    assert_arrived(mic, qb)


def test_stop_flag_halts_a_running_motion_and_the_next_one_runs(arms):
    puma, _ = arms
    q0 = puma.q.copy()
    far, q_far = waist(puma, 0.6, "far")
    puma.settime(0.2, 20.0)                      # slow: 20 s of robot time
    a = ev.move_ev(puma, far)
    puma.settime(0.2, 1.0)
    back = joint_position("back", puma.kinematics, q0)
    b = ev.move_ev(puma, back)
    ev.wait_ev(a, started=True, timeout=10)
    ev.stop_ev(-5, a)
    assert ev.wait_ev(a, timeout=10) == -5
    end = a.request.ended
    assert (end.reason, end.what, end.code) == ("stop", "stop_ev", -5)
    assert ev.wait_ev(b, timeout=20) == DONE
    # it turned back well before reaching `far`
    assert a.request.finished_t < 10.0
    np.testing.assert_allclose(puma.q, q0, atol=END_TOL)
    assert abs(q_far[0] - q0[0]) == pytest.approx(0.6)


def test_stop_ev_stops_two_arms_together(arms):
    puma, mic = arms
    fa, qa = waist(puma, 0.6, "fa")
    fb, qb = waist(mic, 0.6, "fb")
    q0a, q0b = puma.measured_q(), mic.measured_q()
    puma.settime(0.2, 20.0)
    mic.settime(0.2, 20.0)
    a, b = ev.move_ev(puma, fa), ev.move_ev(mic, fb)
    ev.wait_ev(a, started=True, timeout=10)
    ev.wait_ev(b, started=True, timeout=10)
    deadline = time.monotonic() + 10
    while min(abs(puma.measured_q()[0] - q0a[0]), abs(mic.measured_q()[0] - q0b[0])) < 0.02:
        assert time.monotonic() < deadline, "the arms did not move"
        time.sleep(0.005)
    t_a, t_b = puma.gen.t, mic.gen.t             # each arm's own clock when the flag is set
    ev.stop_ev(-4, a, b)
    assert ev.wait_ev(a, timeout=10) == -4 and ev.wait_ev(b, timeout=10) == -4
    # together: each arm's motion ends at the first sample of its own clock after the flag (in
    # lockstep an arm's samples are not wall-clock time: a loaded machine delays one simula
    # process or the other, which a wall-clock bound between the two arms would read as a fault)
    assert 0 <= a.request.finished_t - t_a <= puma.gen.dt + 1e-9
    assert 0 <= b.request.finished_t - t_b <= mic.gen.dt + 1e-9
    for arm, q0, q_far in ((puma, q0a, qa), (mic, q0b, qb)):   # each arm did move, and stopped short
        assert_arrived(arm, arm.q)
        assert 0.02 < abs(arm.measured_q()[0] - q0[0]) < abs(q_far[0] - q0[0]) - 0.1
    assert a.request.finished_t < 10.0 and b.request.finished_t < 10.0   # halfway at most
    time.sleep(0.05)
    assert abs(puma.q[0] - qa[0]) > 0.2 and abs(mic.q[0] - qb[0]) > 0.2


def test_stop_before_start_deletes_the_motion_from_the_queue(arms):
    puma, _ = arms
    never, q_never = waist(puma, 0.5, "never")
    other, q_other = waist(puma, -0.2, "other")
    a = ev.move_ev(puma, never, start=None)
    b = ev.move_ev(puma, other)                  # queued behind a: waits while a is held
    time.sleep(0.1)
    assert b.status == NULL
    ev.stop_ev(-7, a)
    assert ev.wait_ev(b, timeout=20) == DONE
    assert a.status == -7 and a.request.status == "failed" and a.t_started is None
    np.testing.assert_allclose(puma.q, q_other, atol=END_TOL)


def test_thesis_example_a_conditional_motion_inherits_the_eft_of_the_motion_it_replaces(arms):
    """5.6.3: move(A); eft1 = move_ev(B); cond_move(condA, backupA); eft2 = move_ev(C).

    Motion B ends on its stop flag, so the conditional motion to backupA runs instead of C,
    controlled by eft2.
    """
    puma, _ = arms
    pos_a, _ = waist(puma, 0.1, "A")
    puma.move(pos_a)
    puma.settime(0.2, 20.0)
    q_b = puma.q.copy()
    q_b[0] += 0.5 if q_b[0] < 0 else -0.5
    pos_b = joint_position("B", puma.kinematics, q_b)
    eft1 = ev.move_ev(puma, pos_b)
    puma.settime(0.2, 1.0)
    q_backup = q_b.copy()
    q_backup[1] += 0.1
    backup = joint_position("backupA", puma.kinematics, q_backup)
    puma.cond("stop", backup)                    # condA: "ended by its stop flag"
    pos_c = joint_position("C", puma.kinematics, q_b)
    eft2 = ev.move_ev(puma, pos_c)
    nominal_c = eft2.request
    ev.wait_ev(eft1, started=True, timeout=10)
    ev.stop_ev(-5, eft1)
    assert ev.wait_ev(eft2, timeout=20) == DONE
    assert eft1.status == -5
    assert eft2.request is not nominal_c and eft2.request.position is backup
    assert nominal_c.status == "failed"          # C was dropped, the backup ran under eft2
    np.testing.assert_allclose(puma.q, q_backup, atol=END_TOL)


def test_stop_abort_flushes_the_queue_and_halts_the_arm(arms):
    puma, _ = arms
    far, q_far = waist(puma, 0.6, "far")
    puma.settime(0.2, 20.0)
    a = ev.move_ev(puma, far)
    puma.settime(0.2, 1.0)
    b = ev.move_ev(puma, joint_position("later", puma.kinematics, puma.q))
    ev.wait_ev(a, started=True, timeout=10)
    ev.stop_abort(puma)
    assert ev.wait_ev(a, timeout=10) == ABORTED and ev.wait_ev(b, timeout=10) == ABORTED
    assert b.t_started is None and len(puma.queue) == 0
    q_stop = puma.q.copy()
    time.sleep(0.05)
    assert abs(q_stop[0] - q_far[0]) > 0.3       # halted far from its destination


# --- bad use -------------------------------------------------------------------------------
def test_waits_that_can_never_end_are_refused_with_the_chain(arms):
    puma, mic = arms
    pa, _ = waist(puma, 0.2, "pa")
    pb, _ = waist(mic, 0.2, "pb")
    a = ev.move_ev(puma, pa, start=None)
    a2 = ev.move_ev(puma, joint_position("pa2", puma.kinematics, puma.q))
    b = ev.move_ev(mic, pb, start=a)
    with pytest.raises(Deadlock, match=r"start flag of motion #\d+ of arm 'puma' to pa is not set and nothing"):
        ev.wait_ev(a)
    with pytest.raises(Deadlock, match=r"arm 'microbo' to pb waits for motion #\d+ of arm 'puma' to pa"):
        ev.wait_ev(b)
    with pytest.raises(Deadlock, match=r"arm 'puma' to pa2 is queued behind motion #\d+ of arm 'puma' to pa"):
        ev.wait_ev(a2)
    # a cycle: a would start after b, which starts after a
    with pytest.raises(Deadlock, match=r"to pa -> motion #\d+ of arm 'microbo' to pb -> .* to pa: .*forever"):
        ev.start_after(a, b)
    ev.stop_abort(puma)                          # a ends ABORTED: b, waiting for it, can never start
    assert ev.wait_ev(a, timeout=5) == ABORTED
    with pytest.raises(Deadlock, match="which ended ABORTED"):
        ev.wait_ev(b)
    ev.stop_ev(-9, b)
    assert ev.wait_ev(b, timeout=5) == -9
    ev.free_ev(a, a2, b)
    with pytest.raises(UnknownEvent, match="was freed by free_ev"):
        ev.start_ev(START, a)


def test_unknown_flags_bad_codes_and_live_frees_are_refused(arms):
    puma, _ = arms
    pa, _ = waist(puma, 0.2, "pa")
    a = ev.move_ev(puma, pa, start=None)
    with pytest.raises(UnknownEvent, match="argument 3.*is not an event flag triple"):
        ev.start_ev(START, a, pa)
    with pytest.raises(EventError, match="start codes are positive integers.*'when ready'"):
        ev.move_ev(puma, pa, start="when ready")
    with pytest.raises(EventError, match="start codes are positive"):
        ev.start_ev(0, a)
    with pytest.raises(EventError, match="stop codes are negative"):
        ev.stop_ev(3, a)
    with pytest.raises(EventError, match="has not ended"):
        ev.free_ev(a)
    assert a.start == NULL                       # nothing was set by the refused calls
    ev.stop_ev(-1, a)
    assert ev.wait_ev(a, timeout=5) == -1
    ev.free_ev(a)


def test_a_plain_arm_and_an_adaptive_arm_share_event_flags(sims):
    with rccl.open(sims[0].url, "puma260", **SLACK) as puma, \
            rccl.adaptive.open(sims[1].url, "microbo", **SLACK) as mic:
        ev.attach(puma, "plain puma")
        ev.attach(mic, "microbo")
        try:
            far, q_far = waist(puma, 0.6, "far")
            puma.settime(0.2, 20.0)                  # slow: 20 s of robot time
            a = ev.move_ev(puma, far)
            pb, qb = waist(mic, 0.3, "pb")
            b = ev.move_ev(mic, pb, start=a)         # the Microbo moves when the plain PUMA's motion ends
            ev.wait_ev(a, started=True, timeout=10)
            assert b.status == NULL
            ev.stop_ev(-9, a)                        # halts the plain arm's motion (its generator's watch)
            assert ev.wait_ev(a, timeout=10) == -9
            end = a.request.ended
            assert (end.reason, end.what, end.code) == ("stop", "stop_ev", -9)
            assert a.request.finished_t < 10.0
            assert ev.wait_ev(b, timeout=20) == DONE           # a user's stop code still starts the follower
            assert b.start == START and b.t_started >= a.t_ended
            np.testing.assert_allclose(mic.q, qb, atol=END_TOL)
            assert abs(puma.q[0] - q_far[0]) > 0.2                # it stopped well short of `far`
        finally:
            ev.detach(puma)
            ev.detach(mic)


# --- two RCCL arms as the lockstep control tasks of one Workcell (thesis 5.6.2 + 2.4) -----------
def test_in_a_lockstep_workcell_the_follower_starts_within_one_sample_of_the_leaders_end():
    from rccl.adaptive.session import AdaptiveArm
    from rci.multi import Workcell

    with SimulaProcess("-p", "--power-on", robot="puma260", lockstep=True) as sp, \
            SimulaProcess("-p", "--power-on", robot="microbo", lockstep=True) as sm:
        puma, mic = AdaptiveArm(sp.url, "puma260", **SLACK), AdaptiveArm(sm.url, "microbo", **SLACK)
        cell = Workcell({"puma": puma.rci, "microbo": mic.rci}, sync="lockstep", on_error="raise")
        cell.start(puma.open, mic.open)          # both generators' first samples meet at the barrier
        dt = puma.gen.dt
        with cell:
            ev.attach(puma, "puma")
            ev.attach(mic, "microbo")
            try:
                lags = []
                for i in range(3):
                    pa, _ = waist(puma, 0.3, f"pa{i}")
                    pb, qb = waist(mic, 0.3, f"pb{i}")
                    a = ev.move_ev(puma, pa)
                    b = ev.move_ev(mic, pb, start=a)
                    assert ev.wait_ev(b, timeout=20) == DONE
                    lags.append(b.traj_started - a.traj_ended)      # both arms' trajectory clocks
                    np.testing.assert_allclose(mic.q, qb, atol=END_TOL)
                # the arms' trajectory clocks stay together (one sync sample per cycle at 36 Hz)
                assert abs(puma.gen.t - mic.gen.t) <= 1.5 * dt
                assert cell.sample >= int(puma.gen.t / dt)
            finally:
                ev.detach(puma)
                ev.detach(mic)
                puma.close()
                mic.close()
    # the follower, holding at rest, looks at its queue every sample: it starts in the sample the
    # leader ends (when its control task runs after the leader's in that cycle) or in the next one
    assert all(-1e-9 <= lag <= dt + 1e-9 for lag in lags), (lags, dt)


def test_a_users_monitor_still_ends_a_motion_that_has_an_eft(arms):
    puma, _ = arms
    far, q_far = waist(puma, 0.6, "far")
    puma.settime(0.2, 20.0)
    puma.evalfn(lambda s: 42 if s.t > 1.0 else None)      # 5.4.2: ends the motion after 1 s
    a = ev.move_ev(puma, far)
    assert ev.wait_ev(a, timeout=10) == ev.MONITOR         # ended by its monitor, not naturally
    end = a.request.ended
    assert (end.reason, end.code) == ("monitor", 42) and end.t < 1.2
