"""simula's control channel cannot freeze the robot (issue 13, item 3), and simula's small promises (item 7).

A client that never reads its replies, or floods commands, must not block the link or
starve a 100 Hz control; the commands that act on the arm need ``--test-channel``;
diagnostics for bad frames are rate-limited; encoder counts saturate with a status
instead of wrapping. Against real simula processes; every wait is bounded.
"""
from __future__ import annotations

import socket
import time

import numpy as np
import pytest

from rci import codes, protocol
from rci.how import How
from rci.link import open_link
from rcci.models import load_robot
from rci.session import Session
from rci.simula.arm import SimulatedArm
from rci.simula.params import truth_from_model
from rci.simula.process import SimulaProcess

WAIT = 5.0


def _control_socket(sim: SimulaProcess) -> socket.socket:
    host, port = sim.control_url.removeprefix("socket://").rsplit(":", 1)
    return socket.create_connection((host, int(port)), timeout=WAIT)


def test_arm_commands_need_the_test_channel_option():
    with SimulaProcess("-p") as sim:
        for line in ("torque 2 1.0", "torque clear", "load none"):
            reply = sim.command(line)
            assert not reply["ok"] and "--test-channel" in reply["error"], reply
        assert sim.command("state")["ok"] and sim.command("ping")["ok"]       # reading stays allowed
        assert sim.command("state")["state"]["external_torque"] == [0.0] * 6


def test_a_client_that_never_reads_and_floods_does_not_disturb_a_100_hz_control():
    with SimulaProcess("-p", "--power-on", lockstep=False) as sim:
        with Session(sim.url, "puma260", rate_hz=100, on_error="raise", signals=False, lock_memory=False) as s:
            s.control()
            c0 = s.how.cycle
            assert s.wait(seconds=WAIT, until=lambda: s.how.cycle - c0 >= 20)
            hog = _control_socket(sim)
            hog.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
            hog.settimeout(0.5)
            sent = 0
            t_end = time.monotonic() + 1.0
            while time.monotonic() < t_end:                    # 'state' replies are ~1 kB: they pile up unread
                try:
                    hog.send(b"state\n" * 50)
                    sent += 50
                except (socket.timeout, BlockingIOError):
                    pass
                except OSError:
                    break                                      # simula closed the hog: also fine
            c1 = s.how.cycle
            assert s.wait(seconds=WAIT, until=lambda: s.how.cycle - c1 >= 30)
            late = s.how.robot_overruns
            s.release()
            hog.close()
        assert s.termination is None
        assert sent > 100
        assert late <= 2, f"{late} late cycles while the channel was flooded"
        assert sim.command("ping")["ok"]                       # a well-behaved client is still served


def test_a_burst_of_commands_is_served_in_bounded_slices():
    with SimulaProcess("-p") as sim:
        c = _control_socket(sim)
        c.sendall(b"ping\n" * 60)                              # within the queue limit (64)
        buf = b""
        t0 = time.monotonic()
        while buf.count(b"\n") < 60 and time.monotonic() - t0 < WAIT:
            buf += c.recv(65536)
        assert buf.count(b"\n") == 60 and b'"ok": true' in buf
        c.sendall(b"ping\n" * 200)                             # a flood beyond the queue: disconnected
        t0 = time.monotonic()
        closed = False
        while time.monotonic() - t0 < WAIT:
            try:
                if not c.recv(65536):
                    closed = True
                    break
            except (ConnectionResetError, socket.timeout):
                closed = True
                break
        assert closed
        assert sim.command("ping")["ok"]


def test_bad_frame_diagnostics_are_rate_limited(capfd):
    with SimulaProcess("-p") as sim:
        link = open_link(sim.url)
        bad = bytearray(protocol.encode_frame(protocol.HELLO, 0, protocol.Hello("puma260").encode()))
        bad[-1] ^= 0xFF
        link.send_raw(bytes(bad) * 200)
        t0 = time.monotonic()
        while time.monotonic() - t0 < 1.5:                   # let a second window open and close
            time.sleep(0.1)
        link.send_raw(bytes(bad))
        time.sleep(0.2)
        link.close()
        assert sim.command("ping")["ok"]
    err = capfd.readouterr().err
    lines = [x for x in err.splitlines() if "bad frame" in x]
    assert 5 <= len(lines) <= 8, lines                        # 5 shown, then a count, not 200 lines
    assert any("more 'bad frame' messages" in x for x in lines)


def test_encoder_counts_saturate_with_a_status_instead_of_wrapping():
    model = load_robot("puma260")
    arm = SimulatedArm(model, truth_from_model(model), start="ready")
    arm.cal_offset[2] += 2**31 - arm.counters()[2] + 5          # joint 3's counter 5 counts past the int32 top
    smp = arm.sample()
    assert smp.pos[2] == 2**31 - 1 and smp.status == codes.ST_ENCODER_RANGE
    protocol.encode_how(How(pos=smp.pos, adcr=smp.adcr))       # sendable: saturated, not wrapped
    arm.cal_offset[2] -= 2**32 + 10                             # and past the bottom
    assert arm.sample().pos[2] == -2**31


def test_a_how_with_a_count_beyond_int32_is_refused_by_the_encoder():
    h = How(pos=np.array([0, 0, 2**31, 0, 0, 0], dtype=np.int64))
    with pytest.raises(ValueError, match=r"how.pos\[2\] = 2147483648"):
        protocol.encode_how(h)
