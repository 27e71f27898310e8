"""The robot link over loop://, a pty and a TCP socket (rci.link), with a robot-side monitor."""
from __future__ import annotations

import os
import threading
import time

import numpy as np
import pytest

from rci import protocol as p
from rci.chg import POS
from rci.exceptions import DeviceError, LinkClosed
from rci.how import How
from rci.link import open_link
from robot_monitor import EchoArm, Monitor
from rci.session import Session


def test_loop_url_round_trips_frames():
    link = open_link("loop://")
    try:
        h = How()
        h.pos[:] = [1, -2, 3, 40000, 5, 6]
        link.send(p.HOW, 9, p.encode_how(h))
        link.send(p.BYE, 10, p.Bye(True).encode())
        f = link.recv(0.5)
        assert f.seq == 9 and np.array_equal(p.decode_how(f.payload, 9).pos, h.pos)
        assert p.Bye.decode(link.recv(0.5).payload).power_off
        t0 = time.monotonic()
        assert link.recv(0.05) is None and time.monotonic() - t0 < 0.5
    finally:
        link.close()


def test_bad_url_is_a_device_error_naming_it():
    with pytest.raises(DeviceError, match="/dev/no-such-robot"):
        open_link("/dev/no-such-robot")


def _released(arm: EchoArm, within: float = 2.0) -> bool:
    """The monitor thread applies the release a moment after the controller sent it."""
    t0 = time.monotonic()
    while time.monotonic() - t0 < within:
        if any(c.end.com for c in list(arm.applied)):
            return True
        time.sleep(0.002)
    return False


def _run_short_control(url: str, rate: int = 100, seconds: float = 0.3) -> tuple[Session, int]:
    s = Session(url, "puma260", rate_hz=rate, limits=None, on_error="raise", signals=False,
                lock_memory=False, realtime=False)
    s.open()
    n = [0]

    def f1():
        n[0] += 1
        s.chg.motion[2].issue(POS, 1000 + n[0])

    s.control(f1)
    s.wait(seconds)
    s.release()
    s.close()
    return s, n[0]


def test_session_over_a_pty():
    master, slave = os.openpty()
    path = os.ttyname(slave)
    arm = EchoArm()
    mon = Monitor(arm, lockstep=True, rate_hz=100)
    th = threading.Thread(target=mon.serve_fd, args=(master,), daemon=True)
    th.start()
    try:
        s, n = _run_short_control(path)
        assert n >= 15                                   # lockstep: as fast as both sides go
        assert s.how.pos[2] == 1000 + n - 1 or s.how.pos[2] == 1000 + n
        assert s.timing.summary().cycles == n
        assert _released(arm)
    finally:
        mon.stop_event.set()
        os.close(slave)
        th.join(2)
    assert not th.is_alive()


def test_session_over_a_socket_and_link_closed_on_peer_exit():
    arm = EchoArm()
    mon = Monitor(arm, lockstep=True)
    ports: list[int] = []
    th = threading.Thread(target=mon.serve_tcp, kwargs=dict(ready=ports.append), daemon=True)
    th.start()
    for _ in range(200):
        if ports:
            break
        time.sleep(0.01)
    try:
        s, n = _run_short_control(f"socket://127.0.0.1:{ports[0]}", rate=250, seconds=0.2)
        assert n > 10
        assert _released(arm)
    finally:
        mon.stop_event.set()
        th.join(2)
    # the server is gone: the next open fails with a DeviceError naming the URL
    with pytest.raises(DeviceError, match=str(ports[0])):
        open_link(f"socket://127.0.0.1:{ports[0]}")
