"""rci.lifecycle on real simula processes: two sessions opened side by side in one program share
the process's signal handlers, so each one's termination still reaches the main thread at once."""
from __future__ import annotations

import signal
import time

import pytest

from rci.lifecycle import TERM_SIGNAL
from rci.exceptions import ControlTerminated
from rci.session import Session
from rci.simula.process import SimulaProcess


def test_the_first_of_two_sessions_still_delivers_its_termination_by_signal():
    before = signal.getsignal(TERM_SIGNAL), signal.getsignal(signal.SIGINT)
    with SimulaProcess("-p", "--power-on", lockstep=True) as a, SimulaProcess("-p", "--power-on", lockstep=True) as b:
        first = Session(a.url, rate_hz=100, on_error="raise", lock_memory=False, lockstep_timeout=2.0)
        second = Session(b.url, rate_hz=100, on_error="raise", lock_memory=False, lockstep_timeout=2.0)
        with first, second:       # the second session opened after the first: it used to take the handler
            assert first.lifecycle.signals_active and second.lifecycle.signals_active
            n = {"k": 0}

            def fails() -> None:
                n["k"] += 1
                if n["k"] == 20:
                    raise RuntimeError("boom")
            second.control(None)
            first.control(fails)
            t0 = time.monotonic()
            with pytest.raises(ControlTerminated) as e:
                while time.monotonic() - t0 < 10.0:      # the main thread is busy elsewhere: not in wait()
                    time.sleep(0.01)
            assert "boom" in e.value.termination.detail
            assert time.monotonic() - t0 < 5.0
            assert second.in_control                    # the other session's control goes on
            second.release()
        assert not first.lifecycle.signals_active
        assert (signal.getsignal(TERM_SIGNAL), signal.getsignal(signal.SIGINT)) == before   # given back


def test_a_ctrl_c_during_the_last_sessions_close_reaches_the_program():
    """A Ctrl-C that comes while a primitive runs is kept until it returns; when that primitive is
    the close of the last session (its signal handlers already given back), the program gets a
    KeyboardInterrupt. It used to be dropped: `calib record all`, which opens one session after
    another, went on to the end of its campaign after a Ctrl-C (tests/test_calib_record_cli.py
    failed on it now and then)."""
    import rci.lifecycle as lifecycle

    before = signal.getsignal(signal.SIGINT)      # SIG_IGN in a suite run in the background
    with SimulaProcess("-p", "--power-on", lockstep=True) as sim:
        s = Session(sim.url, "puma260", rate_hz=100, lock_memory=False, on_error="raise")
        s.open()
        assert signal.getsignal(signal.SIGINT) is lifecycle._on_sigint
        try:
            with pytest.raises(KeyboardInterrupt):
                with s.lifecycle.primitive():          # as if the Ctrl-C landed inside close()
                    lifecycle._on_sigint(signal.SIGINT, None)
                    assert lifecycle._interrupt_pending
                    s.lifecycle.restore_signals()      # close gives the handlers back before it returns
            assert not lifecycle._interrupt_pending
            assert signal.getsignal(signal.SIGINT) is before
        finally:
            s.close_quietly()


def test_no_host_left_means_pythons_own_ctrl_c():
    import rci.lifecycle as lifecycle

    with pytest.raises(KeyboardInterrupt):
        lifecycle._interrupt([])
