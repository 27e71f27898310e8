"""One controller owns the arm (issue 13, item 2; docs/protocol.md "Ownership").

Against a real simula process: a second controller is refused with BUSY naming the
owner, a bare connection does not disturb a running control, a takeover is refused while
the owner controls and granted once the robot's watchdog has stopped a frozen owner; on a
pty the line itself is exclusive. Every wait is bounded.
"""
from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time

import pytest

from rci import codes, protocol
from rci.chg import Chg
from rci.exceptions import DeviceError, RobotBusy
from rci.link import open_link
from rci.session import Session
from rci.simula.process import SimulaProcess

WAIT = 5.0


def _session(url: str, **kw) -> Session:
    opts = dict(rate_hz=50, on_error="raise", signals=False, lock_memory=False, realtime=False)
    opts.update(kw)
    return Session(url, "puma260", **opts)


def _cycles(s: Session, n: int) -> None:
    c0 = s.how.cycle
    assert s.wait(seconds=WAIT, until=lambda: s.how.cycle - c0 >= n), "the control stalled"


def test_second_controller_gets_busy_naming_the_owner_and_the_control_goes_on():
    with SimulaProcess("-p", lockstep=True) as sim:           # lockstep: about ownership, not timing
        with _session(sim.url, client="owner-program") as owner:
            owner.control()
            _cycles(owner, 5)
            other = _session(sim.url, client="intruder")
            with pytest.raises(RobotBusy) as e:
                other.open()
            assert isinstance(e.value, DeviceError)                  # the documented open() error
            assert e.value.code == codes.ST_BUSY
            text = str(e.value)
            assert f"pid {os.getpid()}" in text and "owner-program" in text and "127.0.0.1:" in text
            assert "control running" in text
            assert not other.is_open
            _cycles(owner, 10)                                       # undisturbed
            assert owner.in_control and owner.termination is None
            owner.release()
        # the owner has gone: the robot is free for the next program
        with _session(sim.url) as nxt:
            nxt.control()
            _cycles(nxt, 3)
            nxt.release()


def test_a_bare_connection_does_not_end_a_running_control():
    with SimulaProcess("-p", lockstep=True) as sim:
        host, port = sim.url.removeprefix("socket://").rsplit(":", 1)
        with _session(sim.url) as owner:
            owner.control()
            _cycles(owner, 5)
            bare = [socket.create_connection((host, int(port)), timeout=WAIT) for _ in range(3)]
            bare[0].sendall(b"\x00garbage\xa5")                      # and one that sends rubbish
            _cycles(owner, 10)
            for b in bare:
                b.close()
            _cycles(owner, 5)
            assert owner.in_control and owner.termination is None
            owner.release()


def test_several_programs_opening_at_once_get_device_errors_not_link_errors():
    with SimulaProcess("-p", lockstep=True) as sim:
        sessions = [_session(sim.url) for _ in range(4)]
        opened, refused = [], []
        for s in sessions:
            try:
                s.open()
                opened.append(s)
            except DeviceError as e:
                refused.append(e)
        assert len(opened) == 1 and len(refused) == 3
        assert all(isinstance(e, RobotBusy) for e in refused)
        opened[0].close()


def _frozen_owner(url: str) -> subprocess.Popen:
    """A controller process that starts a control, says so, and is then stopped (SIGSTOP)."""
    code = ("import sys, time\n"
            "from rci.session import Session\n"
            f"s = Session({url!r}, 'puma260', rate_hz=50, on_error='raise', signals=False, lock_memory=False,"
            " client='frozen')\n"
            "s.open(); s.control(); print('running', flush=True); time.sleep(60)\n")
    return subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)


def test_takeover_refused_while_the_owner_controls_granted_after_the_watchdog_stopped_it():
    with SimulaProcess("-p", "--power-on", lockstep=False) as sim:
        proc = _frozen_owner(sim.url)
        try:
            assert proc.stdout.readline().strip() == "running"
            with pytest.raises(RobotBusy, match="takeover refused: its control is running"):
                _session(sim.url, takeover=True).open()
            os.kill(proc.pid, signal.SIGSTOP)                       # the owner hangs, its socket stays open
            t0 = time.monotonic()
            while sim.command("state")["running"] and time.monotonic() - t0 < WAIT:
                time.sleep(0.01)
            state = sim.command("state")
            assert not state["running"] and not state["state"]["power"]      # watchdog: held, power off
            assert state["owner"]["faulted"] and state["owner"]["program"] == "frozen"
            with pytest.raises(RobotBusy, match="one controller at a time"):
                _session(sim.url).open()                            # without asking: still refused
            with _session(sim.url, takeover=True) as new:           # the documented takeover
                assert sim.command("state")["owner"]["pid"] == os.getpid()
                new.chg.power_on.com = 1
                new.control()
                _cycles(new, 5)
                assert new.how.power
                new.release()
        finally:
            proc.kill()
            proc.wait(WAIT)


def test_takeover_of_a_live_idle_owner_is_refused():
    with SimulaProcess("-p", lockstep=True) as sim:
        with _session(sim.url) as owner:
            with pytest.raises(RobotBusy, match="did not end on a robot-side fault"):
                _session(sim.url, takeover=True).open()
            owner.control()
            _cycles(owner, 3)
            owner.release()


def test_a_pty_line_is_opened_by_one_controller_only():
    with SimulaProcess("-p", lockstep=True, pty=True) as sim:
        first = open_link(sim.url)
        try:
            with pytest.raises(DeviceError, match="another program has this line open"):
                open_link(sim.url)
        finally:
            first.close()
        open_link(sim.url).close()                                  # free again once closed


def test_busy_refusal_on_the_raw_protocol_and_the_running_control_keeps_its_cycle():
    """The robot's half, byte level: ERROR(ST_BUSY) to the newcomer; HOWs keep coming to the owner."""
    with SimulaProcess("-p", lockstep=True) as sim:
        owner = open_link(sim.url)
        owner.send(protocol.HELLO, 0, protocol.Hello("puma260", 36, "raw-owner", 4242).encode())
        assert owner.recv(WAIT).type == protocol.WELCOME
        owner.send(protocol.START, 1, protocol.Start(36).encode())
        how = owner.recv(WAIT)
        other = open_link(sim.url)
        other.send(protocol.HELLO, 0, protocol.Hello("puma260", 36, "raw-other", 4343).encode())
        f = other.recv(WAIT)
        assert f.type == protocol.ERROR
        msg = protocol.ErrorMsg.decode(f.payload)
        assert msg.code == codes.ST_BUSY and "pid 4242" in msg.text and "raw-owner" in msg.text
        other.close()
        owner.send(protocol.CHG, how.seq, protocol.encode_chg(Chg()))
        nxt = owner.recv(WAIT)
        assert nxt.type == protocol.HOW and nxt.seq == how.seq + 1
        end = Chg()
        end.end.com = 1
        owner.send(protocol.CHG, nxt.seq, protocol.encode_chg(end))
        owner.close()


def test_the_reference_monitor_follows_the_same_rule():
    """the reference monitor (tests/robot_monitor.py: the protocol's robot half for a real arm) refuses a second controller too."""
    import threading

    from robot_monitor import EchoArm, Monitor
    mon = Monitor(EchoArm(), lockstep=True)
    ports: list[int] = []
    th = threading.Thread(target=mon.serve_tcp, kwargs=dict(ready=ports.append), daemon=True)
    th.start()
    t0 = time.monotonic()
    while not ports and time.monotonic() - t0 < WAIT:
        time.sleep(0.005)
    url = f"socket://127.0.0.1:{ports[0]}"
    try:
        with _session(url) as owner:
            owner.control()
            _cycles(owner, 5)
            with pytest.raises(RobotBusy, match="robot busy: owned by the controller at 127.0.0.1:"):
                _session(url).open()
            _cycles(owner, 5)
            owner.release()
    finally:
        mon.stop_event.set()
        th.join(WAIT)
