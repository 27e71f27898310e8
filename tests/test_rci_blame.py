"""Faults are blamed on the party that caused them (issue 13, item 4; docs/safety.md).

User faults (an exception of any kind in a control function, a broken or mistyped chg
entry, a bad ``terminate``) end the control with R_USERFUNC / R_BADCMD naming the entry,
not severe, and leave the session able to run the next control. Link faults seen by the
robot keep their link codes. Against one lockstep simula process shared by the module.
"""
from __future__ import annotations

import time

import pytest

from rci import codes
from rci.chg import CUR, POS, Cmd
from rci.exceptions import ControlTerminated
from rci.session import Session
from rci.simula.process import SimulaProcess

WAIT = 5.0


@pytest.fixture(scope="module")
def sim():
    with SimulaProcess("-p", "--power-on", lockstep=True) as s:
        yield s


def _session(url: str) -> Session:
    return Session(url, "puma260", rate_hz=50, on_error="raise", signals=False, lock_memory=False, realtime=False)


def _terminated(s: Session, f1=None, f2=None) -> codes.Termination:
    with pytest.raises(ControlTerminated) as e:
        s.control(f1, f2)
        s.wait(WAIT)
    return e.value.termination


def _next_control_runs(s: Session) -> None:
    """A fault must not poison the session: a plain control with a command runs."""
    def hold():
        s.chg.motion[0].issue(POS, int(s.how.pos[0]))
    s.control(hold)
    c0 = s.how.cycle
    assert s.wait(seconds=WAIT, until=lambda: s.how.cycle - c0 >= 5)
    s.release()


@pytest.mark.parametrize("exc", [SystemExit(0), KeyboardInterrupt(), RuntimeError("boom")],
                         ids=["sys.exit", "KeyboardInterrupt", "RuntimeError"])
def test_anything_raised_in_a_control_function_is_r_userfunc_not_a_link_failure(sim, exc):
    with _session(sim.url) as s:
        def f1():
            raise exc
        t = _terminated(s, f1)
        assert t.number == codes.R_USERFUNC and not t.severe, t
        assert type(exc).__name__ in t.detail and "in f1" in t.detail
        assert s.is_open
        _next_control_runs(s)


@pytest.mark.parametrize("mistake, where, number", [
    (lambda s: s.chg.motion.__setitem__(2, None), "chg.motion[2]", codes.R_BADCMD),
    (lambda s: setattr(s.chg, "hand", 2), "chg.hand", codes.R_BADCMD),
    (lambda s: setattr(s.chg, "setparam", []), "chg.setparam", codes.R_BADCMD),
    (lambda s: s.chg.motion[0].issue(300, 0), "chg.motion[0].com = 300", codes.R_BADCMD),
    (lambda s: s.chg.hand.issue(300, 1), "chg.hand.com = 300", codes.R_BADCMD),
    (lambda s: s.chg.motion[0].issue("1", 0), "chg.motion[0].com = '1'", codes.R_BADCMD),
    (lambda s: s.chg.motion[0].issue(POS, "12"), "chg.motion[0].value = '12'", codes.R_BADCMD),
    (lambda s: s.chg.motion[0].issue(CUR, None), "chg.motion[0].value = None", codes.R_BADCMD),
    (lambda s: s.chg.motion[0].issue(POS, 2**40), "does not fit", codes.R_BADCMD),
    (lambda s: s.chg.motion[0].issue(POS, float("nan")), "chg.motion[0].value = nan", codes.R_NANCMD),
], ids=["motion-None", "hand-int", "setparam-empty", "motion-com-300", "hand-com-300", "com-text",
        "value-text", "value-None", "value-2**40", "value-nan"])
def test_a_bad_chg_entry_is_named_and_does_not_poison_the_next_control(sim, mistake, where, number):
    with _session(sim.url) as s:
        t = _terminated(s, lambda: mistake(s))
        assert t.number == number and not t.severe, t
        assert where in t.detail, t.detail
        # the record is whole again: every entry is a command, nothing pending
        assert all(isinstance(c, Cmd) for c in s.chg.motion) and len(s.chg.setparam) == 6
        assert s.chg.pending() == []
        _next_control_runs(s)


@pytest.mark.parametrize("value", ["abc", 1.5, None, -3], ids=["text", "float", "None", "negative"])
def test_a_terminate_that_is_not_a_code_is_a_user_error(sim, value):
    with _session(sim.url) as s:
        def f1():
            s.terminate = value
        t = _terminated(s, f1)
        assert t.number == codes.R_USERFUNC and not t.severe
        assert "s.terminate" in t.detail
        _next_control_runs(s)


def test_a_user_code_still_ends_the_control_with_that_code(sim):
    with _session(sim.url) as s:
        def f2():
            s.terminate = codes.R_USER_BASE + 7
        t = _terminated(s, None, f2)
        assert t.code == codes.R_USER_BASE + 7


def test_robot_side_link_reports_keep_link_codes():
    assert codes.error_number(codes.for_status(codes.ST_WATCHDOG)) == codes.R_CHGLATE
    assert codes.error_number(codes.for_status(codes.ST_BAD_FRAME)) == codes.R_CHKSUM
    assert codes.error_number(codes.for_status(codes.ST_JOINT_LIMIT)) == codes.R_ROBOT
    assert all(codes.is_severe(codes.for_status(st)) for st in range(1, 10))


def test_close_after_a_lost_link_returns_at_once_without_spinning():
    with SimulaProcess("-p", lockstep=True) as sim:
        s = _session(sim.url)
        s.open()
        sim.stop()                                   # the robot vanishes between controls
        time.sleep(0.1)
        cpu0, t0 = time.process_time(), time.monotonic()
        s.close()
        assert time.monotonic() - t0 < 0.2 and time.process_time() - cpu0 < 0.1
        assert not s.is_open
