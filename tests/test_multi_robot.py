"""Multi-robot RCI (rci.multi, thesis 2.4) on two simula processes: a PUMA 260 and a Microbo, lockstep.

The program under test is examples/two_arms.py (the PUMA publishes its angles in shared
data, the Microbo mirrors its waist and reports to the planning level on a channel).
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import pytest

from rci import codes
from rci.multi import (PLANNING, ArmTerminated, Channel, ChannelFull, MultiError, Shared, Workcell)
from rci.simula.process import SimulaProcess

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "examples"))
import two_arms  # noqa: E402


from simula_pair import SLACK, sims  # noqa: E402,F401  (sims is a fixture)


def arms(sims):
    p, m = sims
    return {"puma": (p.url, "puma260"), "microbo": (m.url, "microbo")}


def running(sim) -> bool:
    return bool(sim.command("state")["running"])


# --- both arms, data between their control functions ----------------------------------------
def test_lockstep_two_arms_each_sample_sees_the_other_arms_previous_sample(sims):
    cell, log = two_arms.main(sims[0].url, sims[1].url, seconds=1.5, **SLACK)
    n = len(log.microbo_q)
    assert n >= 54 and abs(len(log.puma_q) - n) <= 1          # one cycle each per sync sample
    assert log.microbo_seen[0] is None                         # nothing published before sample 0's barrier
    for k in range(1, n):                                      # sample k sees exactly the PUMA's sample k - 1
        np.testing.assert_array_equal(log.microbo_seen[k], log.puma_q[k - 1])
    # the Microbo really followed: its measured waist mirrors the PUMA's swing
    p0, m0 = log.puma_q[0][0], log.microbo_q[0][0]
    swing = log.puma_q[-2][0] - p0
    assert abs(swing) > 0.1
    assert log.microbo_q[-1][0] - m0 == pytest.approx(-swing, abs=0.03)
    # reports reached the planning level through the channel, in order, from the Microbo
    assert [s for s, _ in log.reports] == ["microbo"] * len(log.reports)
    assert [r["sample"] for _, r in log.reports] == [k for k in range(1, n) if k % two_arms.REPORT_EVERY == 0]
    assert not cell["puma"].in_control and not cell["microbo"].in_control
    assert not running(sims[0]) and not running(sims[1])


def test_lockstep_at_different_rates_meets_every_slow_sample(sims):
    t0 = [s.command("state")["state"]["t"] for s in sims]
    cell, log = two_arms.main(sims[0].url, sims[1].url, seconds=1.0, rates=(72, 36), **SLACK)
    n = len(log.microbo_q)
    assert abs(len(log.puma_q) - 2 * n) <= 2                   # 72 Hz runs two cycles per 36 Hz cycle
    for k in range(1, n):                                      # the last PUMA cycle of the previous sync sample
        np.testing.assert_array_equal(log.microbo_seen[k], log.puma_q[2 * k - 1])
    dt = [s.command("state")["state"]["t"] - t for s, t in zip(sims, t0)]
    assert dt[0] == pytest.approx(dt[1], abs=2.5 / 36)          # both simulated clocks advanced alike


def test_free_mode_readers_see_whole_values_never_torn():
    # free sync: each arm on its own robot clock, so real-time simulas (lockstep ones left free
    # would each run as fast as it is answered, and the mirror would step too fast)
    with SimulaProcess("-p", "--power-on", robot="puma260", lockstep=False) as p, \
            SimulaProcess("-p", "--power-on", robot="microbo", lockstep=False) as m:
        # overruns counted, not errors: this test is about the data, on a shared, loaded machine
        cell, log = two_arms.main(p.url, m.url, seconds=1.0, sync="free", overrun="count")
    published = {arr.tobytes() for arr in log.puma_q}
    seen = [s for s in log.microbo_seen if s is not None]
    assert len(seen) > len(log.microbo_seen) // 2
    assert all(s.tobytes() in published for s in seen)         # every read is one complete published value


def test_planning_level_directives_and_replies_through_send_receive(sims):
    """c1/c2 through the thesis's send/receive: the planner sends goals, the PUMA acknowledges each."""
    with Workcell(arms(sims), sync="lockstep", on_error="raise", **SLACK) as cell:
        got = []

        def puma_f() -> None:
            r = cell.receive()                   # non-blocking, from any sender
            if r is not None:
                sender, msg = r
                got.append((cell.sample, sender, msg))
                cell.send(sender, {"ack": msg["goal"]})

        cell.control(puma=puma_f, microbo=lambda: None)
        for g in range(3):
            cell.send("puma", {"goal": g})
        replies = [cell.receive("puma", timeout=2.0) for _ in range(3)]
        cell.release()
    assert [s for _, s, _ in got] == [PLANNING] * 3
    assert [m["goal"] for _, _, m in got] == [0, 1, 2]
    assert replies == [("puma", {"ack": 0}), ("puma", {"ack": 1}), ("puma", {"ack": 2})]


# --- errors -------------------------------------------------------------------------------------
def test_error_on_one_arm_names_it_and_releases_both(sims):
    with pytest.raises(ArmTerminated) as ei:
        two_arms.main(sims[0].url, sims[1].url, seconds=3.0, fail_at=20, **SLACK)
    e = ei.value
    assert e.arm == "microbo"
    assert e.termination.number == codes.R_USERFUNC
    assert "sample 20" in e.termination.detail and "RuntimeError" in e.termination.detail
    assert e.arm_termination.released == ["puma"]
    assert "arm 'microbo' (microbo)" in str(e)
    deadline = time.monotonic() + 2.0
    while (running(sims[0]) or running(sims[1])) and time.monotonic() < deadline:
        time.sleep(0.02)
    assert not running(sims[0]) and not running(sims[1])      # both arms released on the robot side


def test_lockstep_barrier_timeout_names_the_late_arm(sims):
    with Workcell(arms(sims), sync="lockstep", sync_timeout=0.3, on_error="raise", **SLACK) as cell:
        k = [0]

        def slow() -> None:
            k[0] += 1
            if k[0] == 5:
                time.sleep(0.8)          # the Microbo's function stalls: the PUMA waits at the barrier

        with pytest.raises(ArmTerminated) as ei:
            cell.control(puma=lambda: None, microbo=slow)
            cell.wait(5.0)
    e = ei.value
    assert e.arm == "puma" and "SyncTimeout" in e.termination.detail and "'microbo'" in e.termination.detail
    assert e.arm_termination.released == ["microbo"]


def test_control_function_may_not_wait_in_receive(sims):
    with Workcell(arms(sims), on_error="raise", **SLACK) as cell:
        with pytest.raises(ArmTerminated) as ei:     # delivered as soon as it happens, maybe within control()
            cell.control(puma=lambda: cell.receive(timeout=0.1), microbo=lambda: None)
            cell.wait(3.0)
    assert ei.value.arm == "puma" and "must not wait" in ei.value.termination.detail


def test_bad_use_is_refused_with_the_names(sims):
    with Workcell(arms(sims), sync="lockstep", on_error="raise") as cell:
        with pytest.raises(MultiError, match=r"no arm 'kuka'.*\['microbo', 'puma'\]"):
            cell.control(kuka=lambda: None)
        with pytest.raises(MultiError, match="starts all its arms together"):
            cell.control(puma=lambda: None)
        with pytest.raises(MultiError, match="not callable"):
            cell.control(puma=42, microbo=None)
        with pytest.raises(MultiError, match="cannot send to itself"):
            cell.channel("puma", "puma")
    with pytest.raises(MultiError, match="rates given for unknown arms"):
        Workcell(arms(sims), rates={"pumma": 72})
    with pytest.raises(MultiError, match="sync must be"):
        Workcell(arms(sims), sync="sometimes")


# --- the data mechanisms on their own ----------------------------------------------------------
def test_channel_overflow_policies():
    ch = Channel("a", "b", capacity=2, overflow="drop_oldest")
    for i in range(5):
        ch.send(i)
    assert (ch.dropped, ch.receive(), ch.receive(), ch.receive()) == (3, 3, 4, None)
    ch = Channel("a", "b", capacity=1, overflow="error")
    ch.send(np.zeros(3))
    with pytest.raises(ChannelFull, match="a->b is full"):
        ch.send(1)
    ch = Channel("a", "b", capacity=1, overflow="block")
    ch.send(1)
    t = time.monotonic()
    with pytest.raises(ChannelFull, match="still full after 0.05 s"):
        ch.send(2, timeout=0.05)
    assert time.monotonic() - t >= 0.05
    ch = Channel("a", "b", capacity=1, overflow="block", is_control_thread=lambda: True)
    ch.send(1)
    with pytest.raises(ChannelFull, match="never waits"):
        ch.send(2)
    with pytest.raises(MultiError, match="overflow must be"):
        Channel("a", "b", overflow="spill")


def test_shared_copies_arrays_and_defers_until_commit():
    s = Shared(deferred=True)
    q = np.array([1.0, 2.0])
    s["q"] = q
    q[0] = 99.0                               # the writer's later change does not leak
    assert "q" not in s and s.get("q") is None
    s.commit()
    np.testing.assert_array_equal(s["q"], [1.0, 2.0])
    s["q"][1] = 7.0                           # nor a reader's
    np.testing.assert_array_equal(s["q"], [1.0, 2.0])
    with pytest.raises(KeyError, match="no 'x'"):
        s["x"]
    c = Channel("a", "b", deferred=True)
    c.send("hello")
    assert c.receive() is None
    c.commit()
    assert c.receive() == "hello"


# --- RCCL arms as the control tasks of a workcell (thesis 5.6.2, last paragraph) ------------------
def test_rccl_arms_in_a_workcell_a_dead_link_names_the_arm_and_releases_the_other():
    from rccl.adaptive.session import AdaptiveArm
    from rccl.position import joint_position
    from rccl.session import Arm

    with SimulaProcess("-p", "--power-on", robot="puma260", lockstep=True) as p, \
            SimulaProcess("-p", "--power-on", robot="microbo", lockstep=True) as m:
        puma = AdaptiveArm(p.url, "puma260", **SLACK)
        mic = Arm(m.url, "microbo", **SLACK)
        cell = Workcell({"puma": puma.rci, "microbo": mic.rci}, on_error="raise")
        puma.open()
        mic.open()
        with cell:
            q = puma.q.copy()
            q[0] += 0.3
            puma.settime(0.2, 30.0)
            req = puma.move(joint_position("far", puma.kinematics, q))
            cell.wait(0.1)
            m.proc.kill()                        # the Microbo's link dies mid-program
            with pytest.raises(ArmTerminated) as ei:
                cell.wait(5.0)
        e = ei.value
        assert e.arm == "microbo" and e.termination.number in (codes.R_BTEST, codes.R_TIMEOUT)
        assert e.termination.severe and e.arm_termination.released == ["puma"]
        assert not puma.rci.in_control and req.status in ("running", "queued")   # stopped mid-motion
        assert not running(p)


def test_opening_names_the_arm_whose_link_fails_and_closes_the_others(sims):
    cell = Workcell({"puma": (sims[0].url, "puma260"), "microbo": ("socket://127.0.0.1:1", "microbo")})
    with pytest.raises(Exception, match="arm 'microbo'"):
        cell.open()
    assert not cell["puma"].is_open


def test_none_is_not_a_message():
    with pytest.raises(MultiError, match="None cannot be sent"):
        Channel("a", "b").send(None)


def test_example_default_handler_prints_the_arm_and_exits_1():
    import subprocess
    r = subprocess.run([sys.executable, str(Path(two_arms.__file__)), "--simula", "--seconds", "2",
                        "--fail-at", "10"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 1
    line = next(x for x in r.stderr.splitlines() if x.startswith("TERMINATE/"))
    assert "arm 'microbo' (microbo)" in line and "sample 10" in line and "released puma" in line
    assert line.endswith("/ user control function raised an exception")


def test_ctrl_c_releases_every_arm_and_exits_130():
    import signal
    import subprocess
    proc = subprocess.Popen([sys.executable, str(Path(two_arms.__file__)), "--simula", "--seconds", "600"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        first = proc.stdout.readline()            # the first report: both arms are under control
        assert first.startswith("microbo: sample")
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130
    assert any(x.startswith("TERMINATE/ interrupt (every arm released, power off)") for x in err.splitlines())


def test_process_wide_realtime_settings_are_taken_once_for_all_arms(sims):
    """One arm's task starting (a full gc.collect) or ending (unfreeze) must not touch the other's control."""
    import gc
    th0, si0 = gc.get_threshold(), sys.getswitchinterval()
    with Workcell(arms(sims), on_error="raise", **SLACK) as cell:
        cell.control(puma=lambda: None, microbo=lambda: None)
        assert gc.get_threshold()[0] == 50_000 and gc.get_freeze_count() > 0
        assert sys.getswitchinterval() == pytest.approx(2e-4)
        assert cell["puma"].rt_status.gc == "left as is" == cell["microbo"].rt_status.gc
        cell.release("puma")                     # one arm ends: the other is still protected
        assert gc.get_threshold()[0] == 50_000
        cell.release()
    assert gc.get_threshold() == th0 and sys.getswitchinterval() == pytest.approx(si0)
