"""RCI against a real simula process: a killed or stalled simulator, a pty, the default handler."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from rci import codes
from rci.chg import POS
from rci.exceptions import ControlTerminated
from rci.session import Session
from rci.simula.process import SimulaProcess

ROOT = Path(__file__).resolve().parent.parent


def _mover(s: Session):
    def f1():
        s.chg.motion[0].issue(POS, int(s.how.pos[0]) + 20)
    return f1


def test_simula_killed_mid_motion_is_detected_within_two_cycles():
    with SimulaProcess("-p", "--power-on", lockstep=False) as sim:
        s = Session(sim.url, "puma260", rate_hz=50, on_error="raise", signals=False, lock_memory=False)
        with s:
            s.control(_mover(s))
            s.wait(0.3)
            last = s.how.cycle
            os.kill(sim.proc.pid, signal.SIGKILL)
            t_kill = time.monotonic()
            with pytest.raises(ControlTerminated) as e:
                s.wait(2.0)
            detected = time.monotonic() - t_kill
    t = e.value.termination
    # the socket closes when the kernel has torn the process down (tens of ms for a process
    # with locked memory): whichever comes first, end of file or two silent periods, is right
    assert t.number in (codes.R_BTEST, codes.R_TIMEOUT) and t.severe
    assert t.cycle - last <= 2 and detected < 2 * 0.02 + 0.05


def test_stalled_simula_is_a_timeout():
    with SimulaProcess("-p", "--power-on", lockstep=False) as sim:
        s = Session(sim.url, "puma260", rate_hz=50, on_error="raise", signals=False, lock_memory=False)
        try:
            with s:
                s.control(_mover(s))
                s.wait(0.3)
                os.kill(sim.proc.pid, signal.SIGSTOP)
                t_stop = time.monotonic()
                with pytest.raises(ControlTerminated) as e:
                    s.wait(2.0)
                detected = time.monotonic() - t_stop
        finally:
            os.kill(sim.proc.pid, signal.SIGCONT)
    assert e.value.termination.number == codes.R_TIMEOUT
    assert detected < 2 * 0.02 + 0.1           # two periods after the last HOW, plus slack


def test_session_with_simula_over_a_pty():
    with SimulaProcess("-p", lockstep=True, pty=True) as sim:
        assert sim.url.startswith("/dev/")
        with Session(sim.url, "puma260", rate_hz=100, on_error="raise", signals=False, lock_memory=False) as s:
            s.chg.power_on.com = 1
            s.control(_mover(s))
            c0 = s.how.cycle
            assert s.wait(until=lambda: s.how.cycle - c0 >= 50, seconds=20)
            s.release()
        assert s.timing.count >= 50


def test_default_handler_prints_terminate_and_exits_nonzero():
    """The zero-gravity program blocked in input(): simula dies; the program prints TERMINATE and exits 1."""
    with SimulaProcess("-c", "--warm", lockstep=False) as sim:
        proc = subprocess.Popen([sys.executable, "examples/zero_gravity.py", sim.url], cwd=ROOT,
                                stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            assert proc.stdout.readline().startswith("Type <CR> to exit")
            os.kill(sim.proc.pid, signal.SIGKILL)
            proc.wait(timeout=10)            # stdin stays open: the program is still blocked in input()
            err = proc.stderr.read()
        finally:
            if proc.poll() is None:
                proc.kill()
            proc.stdin.close()
    assert proc.returncode == 1
    assert err.startswith("TERMINATE/ ")
    assert err.rstrip().endswith(("/ robot communication link failure", "/ control task timed out, no response from robot"))


@pytest.mark.parametrize("new_rate", [250, 500, 1000])
def test_a_rate_change_from_36_hz_runs_on_a_real_time_simula(new_rate):
    """The HOW that follows a rate command ends the cycle already running at 36 Hz: the
    controller waits for it by the old period, not the new one (it ended with R_TIMEOUT)."""
    with SimulaProcess("-p", "--power-on", lockstep=False) as sim:
        with Session(sim.url, "puma260", rate_hz=36, on_error="raise", signals=False, lock_memory=False) as s:
            n = {"cycles": 0}

            def f1():
                n["cycles"] += 1
                if n["cycles"] == 5:
                    s.chg.rate.issue(1, new_rate)
            s.control(f1)
            assert s.wait(5.0, until=lambda: s.how.rate_hz == new_rate and n["cycles"] > 5 + new_rate // 2)
            assert s.termination is None and s.in_control
            s.release()
