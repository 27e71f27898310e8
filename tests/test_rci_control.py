"""The control task: primitives, A.5.1 checks, faults, termination delivery (rci.session / rci.control).

A robot-side monitor (tests/robot_monitor.py) with a parroting arm runs in a thread behind a real TCP
socket; every wait is bounded, so no test can hang.
"""
from __future__ import annotations

import os
import signal
import threading
import time

import numpy as np
import pytest

from rci import codes
from rci.checks import CommandLimits
from rci.chg import CUR, POS, STOP
from rci.exceptions import (AlreadyOpen, BadFunction, ControlInProgress, ControlTerminated, NoControl,
                            NotOpen, RobotRefused)
from robot_monitor import EchoArm, Monitor
from rci.recorder import Recorder, read_log
from rci.session import Session

LIMITS = CommandLimits.linear(lower=[-3.0] * 6, upper=[3.0] * 6, max_velocity=[2.0] * 6,
                       counts_per_rad=[1000.0] * 6, max_adc=500, max_dac=600)


class Robot:
    def __init__(self, lockstep: bool, **arm_kw) -> None:
        self.arm = EchoArm(**arm_kw)
        # the in-process monitor shares this process's GIL: give its watchdog a long fuse so
        # that a scheduling hiccup on a loaded machine is not taken for a dead controller
        self.mon = Monitor(self.arm, lockstep=lockstep, watchdog=1000)
        ports: list[int] = []
        self.th = threading.Thread(target=self.mon.serve_tcp, kwargs=dict(ready=ports.append), daemon=True)
        self.th.start()
        t0 = time.monotonic()
        while not ports and time.monotonic() - t0 < 5:
            time.sleep(0.005)
        self.url = f"socket://127.0.0.1:{ports[0]}"

    def stop(self) -> None:
        self.mon.stop_event.set()
        self.th.join(3)

    def _seen(self, pred, within: float = 1.0) -> bool:
        # the monitor thread applies the release a moment after the controller sent it
        t0 = time.monotonic()
        while time.monotonic() - t0 < within:
            if any(pred(c) for c in list(self.arm.applied)):
                return True
            time.sleep(0.002)
        return False

    def released(self) -> bool:
        return self._seen(lambda c: c.end.com)

    def powered_off(self) -> bool:
        return self._seen(lambda c: c.power_off.com)


@pytest.fixture(params=[False, True], ids=["realtime", "lockstep"])
def robot(request):
    r = Robot(lockstep=request.param)
    yield r
    r.stop()


@pytest.fixture
def rt_robot():
    """A real-time robot: for the tests about timing (overrun, stall, lost frame)."""
    r = Robot(lockstep=False)
    yield r
    r.stop()


@pytest.fixture
def ls_robot():
    """A lockstep robot: deterministic, for everything that is not about timing."""
    r = Robot(lockstep=True)
    yield r
    r.stop()


def session(url: str, **kw) -> Session:
    # The monitor runs in this process (same GIL) on a shared machine: it is a jittery
    # "real-time" robot. Tests that are not about timing therefore count overruns and allow
    # a generous timeout; the timing faults have their own tests with tight settings.
    opts = dict(rate_hz=100, limits=LIMITS, on_error="raise", signals=False, lock_memory=False, realtime=False,
                overrun="count", timeout=0.3)
    opts.update(kw)
    return Session(url, "puma260", **opts)


def run_until_terminated(s: Session, start=None, limit: float = 2.0) -> codes.Termination:
    """Start (optional) and wait, bounded, until the control ends on an error; returns the termination.

    An error in the very first cycle is delivered by control() itself, hence ``start``.
    """
    with pytest.raises(ControlTerminated) as e:
        if start is not None:
            start()
        s.wait(limit)
        pytest.fail(f"no termination within {limit} s")
    return e.value.termination


# --- A.3 primitives --------------------------------------------------------------------
def test_primitive_errors(robot):
    s = session(robot.url)
    with pytest.raises(NotOpen):
        s.control(None, None)
    with pytest.raises(NotOpen):
        s.release()
    s.open()
    try:
        with pytest.raises(AlreadyOpen):
            s.open()
        with pytest.raises(NoControl):
            s.release()
        with pytest.raises(BadFunction):
            s.control(42, None)
        s.control(None, None)
        with pytest.raises(ControlInProgress):
            s.control(None, None)
        s.release()
        assert robot.released()
        s.control(None, None)      # a new control after a release
        s.wait(0.05)
    finally:
        s.close()
    with pytest.raises(NotOpen):
        s.close()


def test_wrong_robot_name_is_refused(robot):
    s = Session(robot.url, "microbo", limits=None, signals=False, lock_memory=False)
    with pytest.raises(RobotRefused, match="microbo"):
        s.open()


def test_context_manager_always_releases_and_closes(robot):
    s = session(robot.url)
    with pytest.raises(ZeroDivisionError):
        with s:
            s.control(None, None)
            s.wait(0.03)
            1 / 0
    assert s.link is None and robot.released() and robot.powered_off()


def test_command_is_consumed_when_dispatched(robot):
    with session(robot.url) as s:
        s.chg.power_on.com = 1
        s.chg.motion[1].issue(POS, 10)
        s.control(None, None)
        assert s.wait(1.0, until=lambda: not s.chg.pending())
        s.wait(0.05)
        s.release()
    sent = [c for c in robot.arm.applied if c.motion[1].com == POS]
    assert len(sent) == 1 and sent[0].motion[1].value == 10
    assert sum(1 for c in robot.arm.applied if c.power_on.com) == 1


# --- user-function faults ----------------------------------------------------------------
def test_exception_in_f1_ends_control_in_that_cycle(robot):
    s = session(robot.url)
    with s:
        state = {"n": 0, "cycle": None}

        def f1():
            state["n"] += 1
            if state["n"] == 10:
                state["cycle"] = s.how.cycle
                raise RuntimeError("boom")

        t = run_until_terminated(s, lambda: s.control(f1))
    assert t.number == codes.R_USERFUNC and t.cycle == state["cycle"]
    assert "RuntimeError: boom" in t.detail and "test_rci_control.py" in t.detail
    assert robot.released() and not t.severe


def test_nan_command_is_refused_before_sending(robot):
    s = session(robot.url)
    with s:
        def f1():
            s.chg.motion[0].issue(CUR, float("nan"))
        t = run_until_terminated(s, lambda: s.control(f1))
    assert t.number == codes.R_NANCMD and "motion[0]" in t.detail
    assert not any(c.motion[0].com == CUR for c in robot.arm.applied)
    assert robot.released()


def test_overrunning_user_function(rt_robot):
    """A control function too slow for the period, cycle after cycle: R_OVERRUN after late_limit late cycles."""
    s = session(rt_robot.url, rate_hz=50, overrun="error")
    with s:
        state = {"n": 0}

        def f2():
            state["n"] += 1
            if state["n"] >= 5:
                time.sleep(0.03)          # 1.5 periods, every cycle
        t = run_until_terminated(s, lambda: s.control(None, f2))
    assert t.number == codes.R_OVERRUN and not t.severe
    assert "late cycles in a row (limit 3)" in t.detail and "control functions" in t.detail
    assert s.timing.late_run_max >= 3
    assert rt_robot.released()


def test_an_isolated_overrun_is_counted_not_fatal(rt_robot):
    """The lateness policy: one slow cycle is survived and reported in the timing summary.

    The limit is 10 late cycles in a row, not the default 3: the one 1.5-period overrun under test
    makes 1-2 late cycles, and with both cores busy (the suite's rule) the machine's own delays to
    the control thread and to simula can add a few more (a fresh-clone run at load 3-4 saw a run of
    5, ended by the default limit): how many late cycles one overrun makes depends on the machine,
    what the policy does with them does not. The strict end is test_late_limit_is_configurable_and_checked's
    (late_limit=1)."""
    s = session(rt_robot.url, rate_hz=50, overrun="error", late_limit=10)
    with s:
        state = {"n": 0}

        def f2():
            state["n"] += 1
            if state["n"] == 5:
                time.sleep(0.03)          # 1.5 periods, once
        s.control(None, f2)
        s.wait(0.4)
        assert s.in_control and s.termination is None
        s.release()
    summary = s.timing.summary()
    assert summary.overruns >= 1 and summary.late_cycles >= 1
    assert summary.late_run_max < summary.late_limit == 10


def test_late_limit_is_configurable_and_checked(rt_robot):
    """late_limit=1 is the strict policy: the first late cycle ends the control."""
    s = session(rt_robot.url, rate_hz=50, overrun="error", late_limit=1)
    with s:
        state = {"n": 0}

        def f2():
            state["n"] += 1
            if state["n"] == 5:
                time.sleep(0.03)
        t = run_until_terminated(s, lambda: s.control(None, f2))
    # the first late cycle ends it: the user's sleep at cycle 5 (R_OVERRUN), or on a loaded machine
    # an earlier cycle the control thread was not scheduled in time for (R_CHGLATE); either way limit 1
    assert t.number in (codes.R_OVERRUN, codes.R_CHGLATE) and "(limit 1)" in t.detail and t.cycle <= 6
    assert Session(rt_robot.url).late_limit_for(1000) == 20 and Session(rt_robot.url).late_limit_for(36) == 3
    for bad in (0, -2, 1.5, True, "3"):
        with pytest.raises(ValueError, match="late_limit"):
            Session(rt_robot.url, late_limit=bad)


def test_hung_user_function_is_released_by_the_watchdog(robot):
    s = session(robot.url, rate_hz=50, overrun="error")
    go = threading.Event()
    with s:
        state = {"n": 0}

        def f1():
            state["n"] += 1
            if state["n"] == 3:
                go.wait(5.0)              # an "infinite loop" that we can end after the test
        s.control(f1)
        t0 = time.monotonic()
        t = run_until_terminated(s)
        detected = time.monotonic() - t0
        # a new control is refused while f1 is still hung, after 1 s (not session.FINISH_WAIT)
        t1 = time.monotonic()
        with pytest.raises(ControlInProgress, match="has not returned yet"):
            s.control(None, None)
        refused = time.monotonic() - t1
        go.set()
    assert 0.9 < refused < 2.0
    assert t.number == codes.R_OVERRUN
    assert detected < 0.2                 # 2 periods (40 ms) + watchdog interval + slack
    assert robot.released()


def test_user_generated_termination_a52(robot):
    s = session(robot.url)
    with s:
        def f1():
            if s.how.cycle > 3:
                s.terminate = codes.R_USER_BASE + 7
        t = run_until_terminated(s, lambda: s.control(f1))
    assert t.code == codes.R_USER_BASE + 7 and "user-generated" in codes.reason(t.code)


# --- link faults -------------------------------------------------------------------------
def test_stalled_link_is_a_timeout_within_two_periods(rt_robot):
    state = {"stall_from": None}

    def fault(seq, data):
        if seq >= 20:
            if state["stall_from"] is None:
                state["stall_from"] = time.monotonic()
            return None
        return data
    rt_robot.mon.fault = fault
    s = session(rt_robot.url, rate_hz=50, timeout=None)
    with s:
        t = run_until_terminated(s, lambda: s.control(None, None))
        late = time.monotonic() - s.how.received
    assert t.number == codes.R_TIMEOUT and t.severe
    assert late < 2 * 0.02 + 0.06          # two periods after the last HOW, plus scheduling slack
    assert rt_robot.released() and rt_robot.powered_off()


def test_corrupted_frame_is_r_chksum(robot):
    def fault(seq, data):
        if seq == 15:
            b = bytearray(data)
            b[30] ^= 0x10
            return bytes(b)
        return data
    robot.mon.fault = fault
    s = session(robot.url)
    with s:
        t = run_until_terminated(s, lambda: s.control(None, None))
    assert t.number == codes.R_CHKSUM and t.cycle == 14    # the last good HOW was 14
    assert robot.released()


def test_lost_frame_is_a_sequence_gap(rt_robot):
    rt_robot.mon.fault = lambda seq, data: None if seq == 12 else data
    s = session(rt_robot.url, rate_hz=50, timeout=0.1)
    with s:
        t = run_until_terminated(s, lambda: s.control(None, None))
    assert t.number == codes.R_SEQGAP and t.cycle == 13


def test_robot_vanishing_mid_motion_is_detected(robot):
    def fault(seq, data):
        if seq >= 10:
            robot.mon.stop_event.set()     # the monitor drops the connection
            return None
        return data
    robot.mon.fault = fault
    s = session(robot.url, timeout=1.0)
    with s:
        def f1():
            s.chg.motion[0].issue(POS, int(s.how.pos[0]) + 5)
        t = run_until_terminated(s, lambda: s.control(f1))
    assert t.number == codes.R_BTEST and "link lost" in t.detail and t.severe


def test_robot_status_error_is_r_robot(robot):
    s = session(robot.url)
    with s:
        s.control(None, None)
        robot.arm.status = codes.ST_EXTERNAL_STOP
        t = run_until_terminated(s)
    assert t.number == codes.R_ROBOT and "emergency stop" in t.detail


# --- A.5.1 range checks --------------------------------------------------------------------
def _one_command(robot, issue, checking=None, rate=100):
    s = session(robot.url, rate_hz=rate)
    with s:
        state = {"n": 0}

        def f1():
            state["n"] += 1
            if state["n"] == 1 and checking is not None:
                s.chg.checking.issue(1, checking)
            if state["n"] == 3:
                issue(s)
        try:
            s.control(f1)
            s.wait(0.3)
        except ControlTerminated as e:
            return e.termination
    return None


@pytest.mark.parametrize("name,issue,checking,number", [
    ("REQPOS", lambda s: s.chg.motion[1].issue(POS, 3500), None, codes.R_REQPOS),
    ("REQVEL", lambda s: s.chg.motion[1].issue(POS, 500), None, codes.R_REQVEL),
    ("REQCUR", lambda s: s.chg.motion[4].issue(CUR, 700), None, codes.R_REQCUR),
    ("MAXPOS", lambda s: s.chg.motion[1].issue(POS, 3500), codes.CHECK_ALL & ~(codes.CHECK_REQPOS | codes.CHECK_REQVEL | codes.CHECK_MAXVEL), codes.R_MAXPOS),
    ("MAXVEL", lambda s: s.chg.motion[1].issue(POS, 500), codes.CHECK_ALL & ~codes.CHECK_REQVEL, codes.R_MAXVEL),
    ("MAXCUR", lambda s: s.chg.motion[4].issue(CUR, 700), codes.CHECK_ALL & ~codes.CHECK_REQCUR, codes.R_MAXCUR),
    ("BADCMD", lambda s: s.chg.hand.issue(1, 5), None, codes.R_BADCMD),
    ("BADCMD-motion", lambda s: s.chg.motion[0].issue(9, 0), None, codes.R_BADCMD),
    ("TOOMANY", lambda s: [c.issue(1, 0) for c in s.chg.setparam] + [c.issue(STOP) for c in s.chg.motion]
     + [s.chg.stop.issue(), s.chg.power_on.issue(), s.chg.outport1.issue(1, 3), s.chg.pendant.issue(1, 1),
        s.chg.adco.issue(1, 7)], None, codes.R_TOOMANY),
])
def test_range_and_command_checks(ls_robot, name, issue, checking, number):
    t = _one_command(ls_robot, issue, checking)
    assert t is not None, f"{name}: no termination"
    assert t.number == number, (name, t)
    if number in (codes.R_REQPOS, codes.R_REQVEL, codes.R_REQCUR, codes.R_MAXPOS, codes.R_MAXVEL, codes.R_MAXCUR):
        joint = 4 if "CUR" in name else 1
        assert codes.joint_of(t.code) == joint and f"joint {joint + 1}" in t.detail
        assert bool(t.code & codes.F_RANGE)
    assert ls_robot.released()


def test_checks_switched_off_by_the_checking_bits(ls_robot):
    t = _one_command(ls_robot, lambda s: s.chg.motion[4].issue(CUR, 700), checking=0)
    assert t is None


# --- planning-level delivery ---------------------------------------------------------------
def test_error_reaches_a_main_thread_blocked_in_sleep(ls_robot):
    s = session(ls_robot.url, rate_hz=50, signals=True)
    with s:
        returned = threading.Event()     # a lockstep robot can run many cycles before control() returns

        def f1():
            if returned.is_set():
                raise ValueError("late failure")
        s.control(f1)
        returned.set()
        t0 = time.monotonic()
        with pytest.raises(ControlTerminated):
            time.sleep(5.0)              # not an RCI wait: the signal interrupts it
        assert time.monotonic() - t0 < 1.0
    assert s.termination.number == codes.R_USERFUNC


def test_default_handler_prints_terminate_and_exits(ls_robot, capsys):
    s = session(ls_robot.url, rate_hz=50, signals=True, on_error=None)
    s.open()
    with pytest.raises(SystemExit) as e:
        s.control(lambda: 1 / 0)      # the error of the first cycle is delivered before control() returns
        time.sleep(5.0)
    assert e.value.code == 1
    err = capsys.readouterr().err
    assert err.startswith("TERMINATE/ in f1: ZeroDivisionError") and "/ user control function raised an exception" in err
    assert s.link is None and ls_robot.released()


def test_user_error_handler_can_restart_control(robot):
    seen = []
    s = session(robot.url, on_error=seen.append)
    with s:
        s.control(lambda: 1 / 0)
        s.wait(1.0, until=lambda: bool(seen))
        assert seen and seen[0].number == codes.R_USERFUNC
        s.control(None, None)            # recovery: start control again (A.5.5)
        s.wait(0.05)
        assert s.in_control
        s.release()


def test_ctrl_c_releases_and_closes(ls_robot, capsys):
    before = signal.getsignal(signal.SIGINT)   # default_int_handler; SIG_IGN in a shell's background job
    s = session(ls_robot.url, rate_hz=50, signals=True)
    s.open()
    s.control(None, None)
    threading.Timer(0.05, os.kill, args=(os.getpid(), signal.SIGINT)).start()
    with pytest.raises(SystemExit) as e:
        s.wait(5.0)
    assert e.value.code == 130
    assert s.link is None and ls_robot.released() and ls_robot.powered_off()
    assert "TERMINATE/ interrupt / interrupted from the keyboard" in capsys.readouterr().err
    assert signal.getsignal(signal.SIGINT) is before              # the session put back what it found


def test_user_interrupt_handler(ls_robot):
    hits = []
    s = session(ls_robot.url, rate_hz=50, signals=True, on_interrupt=lambda: hits.append(1))
    with s:
        s.control(None, None)
        os.kill(os.getpid(), signal.SIGINT)
        s.wait(0.05)
        assert hits == [1] and s.in_control     # A.5.3: no automatic release on interrupt
        s.release()


# --- rate, recorder, timing ----------------------------------------------------------------
def test_rate_command_changes_the_sample_rate(robot):
    with session(robot.url, rate_hz=36) as s:
        s.chg.rate.issue(1, 0)                 # thesis code 0 = 72 Hz
        s.control(None, None)
        assert s.wait(1.0, until=lambda: s.how.rate_hz == 72)
        s.chg.rate.issue(1, 250)               # any rate up to 1 kHz
        assert s.wait(1.0, until=lambda: s.how.rate_hz == 250)
        s.release()


def test_recorder_logs_every_cycle(robot, tmp_path):
    path = tmp_path / "run.rcilog"
    rec = Recorder(path, robot="puma260", rate_hz=100, user_fields={"k": ("i4", ())}, meta={"test": True})
    with session(robot.url) as s:
        s.record(rec)

        def f1():
            rec.user["k"] = s.how.cycle
            s.chg.motion[3].issue(POS, 7)
        s.control(f1)
        s.wait(0.15)
        s.release()
        n = s.timing.count
    rec.close()
    log = read_log(path)
    assert log.complete and len(log) == n and log.meta["meta"] == {"test": True}
    assert np.array_equal(log.user("k"), log.records["cycle"])
    assert (log.records["chg_motion_com"][:, 3] == POS).all()
    assert (log.records["chg_motion_value"][:, 3] == 7).all()
    assert np.all(np.diff(log.records["cycle"].astype(int)) == 1)


def test_hung_function_against_a_lockstep_robot_is_caught_after_two_seconds(ls_robot):
    s = session(ls_robot.url, rate_hz=100)          # overrun="count": slow cycles are fine here...
    go = threading.Event()
    with s:
        def f1():
            if s.how.cycle == 5:
                go.wait(10.0)                        # ...but one that never returns is not
        s.control(f1)
        t0 = time.monotonic()
        t = run_until_terminated(s, limit=5.0)
        waited = time.monotonic() - t0
        go.set()
    assert t.number == codes.R_OVERRUN and 2.0 <= waited < 2.5
    assert ls_robot.released()


def test_gc_settings_are_shared_by_every_control_task_of_the_process():
    """Two arms' control tasks: the second start neither collects again nor, when the first
    ends, leaves the second running with the collector back on (rci.realtime.GCControl)."""
    import gc

    from rci.realtime import GCControl, RealtimeStatus

    before = gc.get_threshold()
    first, second = GCControl("freeze"), GCControl("freeze")
    s1, s2 = RealtimeStatus(), RealtimeStatus()
    first.apply(s1)
    second.apply(s2)
    assert s1.gc.startswith("frozen") and "another control task" in s2.gc
    first.restore()
    assert gc.get_threshold()[0] == 50_000, "the second task's settings were undone early"
    second.restore()
    assert gc.get_threshold() == before
    second.restore()                      # a second restore changes nothing
    assert gc.get_threshold() == before
