"""simula's real-time clock: a CHG is in time if it arrives before the tick, even in the busy-wait.

The server runs in a thread of the test process (so the test can read its clock) and is
driven over a real TCP socket through rci.link. The rate is low and the busy-wait window
widened (50 ms of a 100 ms period) so the timing holds on a loaded machine; every wait is
bounded.
"""
from __future__ import annotations

import sys
import threading
import time

import numpy as np
import pytest

from rci import protocol
from rci.chg import Chg
from rci.link import open_link
from rcci.models import load_robot
from rci.simula import server as server_mod
from rci.simula.arm import SimulatedArm
from rci.simula.params import truth_from_model

RATE = 10            # Hz: 100 ms period
SPIN = 0.05          # s of busy-wait before each tick (the real default is 200 us)
WAIT = 5.0


@pytest.fixture
def running(monkeypatch, tmp_path):
    monkeypatch.setattr(server_mod, "SPIN_S", SPIN)
    # the server busy-waits in this process: let the test thread have the GIL promptly
    saved_interval = sys.getswitchinterval()
    sys.setswitchinterval(1e-4)
    trace = tmp_path / "trace.npz"
    monkeypatch.setenv("RCI_SIMULA_TRACE", str(trace))
    model = load_robot("puma260")
    arm = SimulatedArm(model, truth_from_model(model), seed=0, start="ready")
    arm.power = True
    srv = server_mod.Server(arm, model.name, lockstep=False, rate_hz=RATE)
    url = srv.listen("tcp", host="127.0.0.1", port=0)
    th = threading.Thread(target=srv.serve_forever, daemon=True)
    th.start()
    link = open_link(url)
    link.send(protocol.HELLO, 0, protocol.Hello("puma260", RATE, "test").encode())
    f = link.recv(WAIT)
    assert f is not None and f.type == protocol.WELCOME
    link.send(protocol.START, 1, protocol.Start(RATE).encode())
    yield srv, link, trace
    end = Chg()
    end.end.com = 1
    f = link.recv(WAIT)
    if f is not None:
        link.send(protocol.CHG, f.seq, protocol.encode_chg(end))
    link.close()
    srv.stop()
    th.join(WAIT)
    assert not th.is_alive()
    srv.close()
    sys.setswitchinterval(saved_interval)


def _next_tick(srv) -> float:
    """The tick that closes the cycle whose HOW was just received (the server advances
    ``next_tick`` just after writing that HOW, so give it a moment)."""
    time.sleep(0.005)
    return srv.next_tick


def _how(link) -> tuple[protocol.Frame, int]:
    f = link.recv(WAIT)
    assert f is not None and f.type == protocol.HOW, f
    return f, protocol.decode_how(f.payload, f.seq).robot_overruns


def _sleep_until(t: float) -> None:
    while (left := t - time.monotonic()) > 0:
        time.sleep(min(left, 0.005))


def test_chg_in_the_busy_wait_before_the_tick_is_in_time(running):
    srv, link, trace = running
    empty = protocol.encode_chg(Chg())
    f, over0 = _how(link)
    in_busy_wait = 0
    for _ in range(40):
        # half-way through the busy-wait: the old loop did not read the socket there
        tick = _next_tick(srv)
        _sleep_until(tick - SPIN / 2)
        if tick - time.monotonic() < 0.005:
            # on a loaded machine the test thread woke too late to land in the busy-wait: this
            # cycle tests nothing, answer it in time anyway and try the next one
            link.send(protocol.CHG, f.seq, empty)
            f, over0 = _how(link)
            continue
        link.send(protocol.CHG, f.seq, empty)
        f, over = _how(link)
        assert over == over0, "a CHG sent in the busy-wait before the tick was counted late"
        in_busy_wait += 1
        if in_busy_wait == 4:
            break
    assert in_busy_wait == 4, f"only {in_busy_wait} of 40 cycles reached the busy-wait in time"


def test_chg_after_the_tick_counts_as_late(running):
    srv, link, trace = running
    empty = protocol.encode_chg(Chg())
    f, over0 = _how(link)
    _sleep_until(_next_tick(srv) + 0.02)         # the tick has come and gone
    link.send(protocol.CHG, f.seq, empty)        # too late: stale
    f, _ = _how(link)
    f, over = _how(link)
    assert over > over0


def test_tick_trace_is_written(running):
    srv, link, trace = running
    empty = protocol.encode_chg(Chg())
    for _ in range(4):
        f, _ = _how(link)
        link.send(protocol.CHG, f.seq, empty)
    srv.trace.save()                              # what close() does when simula exits
    d = np.load(trace)
    assert len(d["deadline"]) >= 2
    sent_after = d["sent"] - d["deadline"]
    assert np.all(sent_after >= 0) and np.all(sent_after < 0.05)     # HOW leaves at the tick
    assert np.all(np.diff(d["deadline"]) == pytest.approx(1.0 / RATE))
