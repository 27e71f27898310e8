"""simula as a separate process: the link protocol, state across programs, calibration, modes.

Every test talks to a real ``python -m rci.simula`` over a real socket or pty through
rci.link (pyserial), with the frames of rci.protocol. Each wait is bounded.
"""
from __future__ import annotations

import subprocess
import sys
import time

import numpy as np
import pytest

from rci import codes, protocol
from rci.chg import CUR, POS, STOPCAL, Chg
from rci.conversions import Conversions
from rci.link import open_link
from rcci.models import load_robot
from rci.simula.process import SimulaProcess

PUMA = load_robot("puma260")
CONV = Conversions.for_robot("puma260")
WAIT = 5.0


class Controller:
    """A minimal controller on the raw protocol (the real one is rci's control task)."""

    def __init__(self, url: str, robot: str = "puma260", rate: int = 36) -> None:
        self.link = open_link(url)
        self.raw: list[bytes] = []          # every HOW frame's bytes, as received
        self.msg = 0
        self.rate = rate
        self.robot = robot

    def _msg(self, ftype: int, payload: bytes) -> None:
        self.link.send(ftype, self.msg, payload)
        self.msg += 1

    def recv(self) -> protocol.Frame:
        f = self.link.recv(WAIT)
        assert f is not None, "simula did not answer in time"
        return f

    def hello(self) -> protocol.Welcome:
        self._msg(protocol.HELLO, protocol.Hello(self.robot, self.rate, "test").encode())
        f = self.recv()
        if f.type == protocol.ERROR:
            raise RuntimeError(protocol.ErrorMsg.decode(f.payload).text)
        assert f.type == protocol.WELCOME
        return protocol.Welcome.decode(f.payload)

    def start(self):
        self._msg(protocol.START, protocol.Start(self.rate).encode())
        return self.how()

    def how(self):
        f = self.recv()
        assert f.type == protocol.HOW, f.name
        self.raw.append(protocol.encode_frame(f.type, f.seq, f.payload))
        return protocol.decode_how(f.payload, f.seq)

    def cycle(self, how, chg: Chg | None = None):
        """Answer ``how`` with ``chg`` and return the next HOW."""
        self.link.send(protocol.CHG, how.cycle, protocol.encode_chg(chg or Chg()))
        return self.how()

    def end(self, how) -> None:
        c = Chg()
        c.end.com = 1
        self.link.send(protocol.CHG, how.cycle, protocol.encode_chg(c))

    def bye(self, power_off: bool = False) -> None:
        self._msg(protocol.BYE, protocol.Bye(power_off).encode())
        while True:
            f = self.recv()
            if f.type == protocol.BYE:
                break
        self.link.close()


def power_on(ctl: Controller, how):
    c = Chg()
    c.power_on.com = 1
    return ctl.cycle(how, c)


def pos(values: dict[int, int]) -> Chg:
    c = Chg()
    for j, v in values.items():
        c.motion[j].issue(POS, int(v))
    return c


def test_serves_how_frames_and_follows_pos_within_limits():
    with SimulaProcess("-p") as sim:
        ctl = Controller(sim.url)
        w = ctl.hello()
        assert (w.robot, w.nj, w.nadc, w.mode) == ("puma260", 6, 16, protocol.MODE_LOCKSTEP)
        assert w.state & codes.CALIB_OK
        h = power_on(ctl, ctl.start())
        assert h.state & codes.POWER_ON and h.status == 0
        first = h.cycle
        ready = CONV.angles_to_counts_int(PUMA.poses["ready"])
        np.testing.assert_array_equal(h.pos, ready)
        # 0.5 rad/s on joint 2 for one second, then a step that asks for too much speed
        step = CONV.R[1, 1] * 0.5 / 36
        for k in range(1, 37):
            h = ctl.cycle(h, pos({1: ready[1] + k * step}))
        assert h.pos[1] == int(ready[1] + 36 * step) and h.cycle == first + 36
        far = h.pos[1] + int(CONV.R[1, 1] * 1.0)              # 1 rad in one period: beyond 2.99 rad/s
        q_before = CONV.counts_to_angles(h.pos)[1]
        h = ctl.cycle(h, pos({1: far}))
        moved = CONV.counts_to_angles(h.pos)[1] - q_before
        assert moved == pytest.approx(PUMA.max_velocity[1] / 36, abs=2e-4)
        ctl.end(h)
        ctl.bye()


def test_refuses_motion_uncalibrated_and_calibrates_with_zindex_stopcal():
    with SimulaProcess(seed=5) as sim:
        ctl = Controller(sim.url)
        assert not ctl.hello().state & codes.CALIB_OK
        h = power_on(ctl, ctl.start())
        h = ctl.cycle(h, pos({0: 100}))
        assert h.status == codes.ST_NOT_CALIBRATED
        # a calibration program: potentiometers (ADC 6..11) for the coarse angle, zindex,
        # creep every joint until it freezes on its index mark, then STOPCAL the true count
        c = Chg()
        c.zindex.issue(1, 0b111111)
        h = ctl.cycle(h, c)
        assert h.state & codes.ZINDEX_ACTIVE
        target = h.pos.astype(float)
        direction = np.sign(np.diag(CONV.R))
        still = np.zeros(6, dtype=int)
        for _ in range(600):
            before = h.pos.copy()
            target = np.where(still < 3, target + 20 * direction, target)
            h = ctl.cycle(h, pos({j: target[j] for j in range(6) if still[j] < 3}))
            still = np.where(h.pos == before, still + 1, 0)
            if np.all(still >= 3):
                break
        assert np.all(still >= 3), "some joint never found its index mark"
        q_coarse = PUMA.lower + (h.adcr[6:12] + 2000) / 4000 * (PUMA.upper - PUMA.lower)
        n = PUMA.conversion.encoder_counts_per_motor_rev.values
        marks = np.rint(CONV.angles_to_counts(q_coarse) / n) * n
        c = Chg()
        for j in range(6):
            c.motion[j].issue(STOPCAL, int(marks[j]))
        h = ctl.cycle(h, c)
        h = ctl.cycle(h)
        assert h.state & codes.CALIB_OK and h.status == 0
        truth = sim.command("state")["state"]
        np.testing.assert_allclose(CONV.counts_to_angles(h.pos), truth["q"], atol=2e-4)   # calibrated = true angles
        h = ctl.cycle(h, pos({0: h.pos[0] + 50}))
        assert h.status == 0
        ctl.end(h)
        ctl.bye()


def test_remembers_state_across_two_programs():
    with SimulaProcess("-c") as sim:
        ctl = Controller(sim.url)
        ctl.hello()
        h = power_on(ctl, ctl.start())
        goal = h.pos.copy()
        goal[0] -= 3000
        goal[2] += 2000
        for k in range(1, 21):
            h = ctl.cycle(h, pos({0: h.pos[0] - 150, 2: h.pos[2] + 100}))
        np.testing.assert_array_equal(h.pos[[0, 2]], goal[[0, 2]])
        last = h.cycle
        ctl.end(h)
        ctl.bye()
        second = Controller(sim.url)
        w = second.hello()
        assert w.state & codes.POWER_ON and w.state & codes.CALIB_OK
        h2 = second.start()
        np.testing.assert_array_equal(h2.pos, h.pos)
        assert h2.cycle == last + 1                          # HOW numbering does not restart
        second.end(h2)
        second.bye(power_off=True)
        third = Controller(sim.url)
        assert not third.hello().state & codes.POWER_ON
        third.bye()


def test_current_mode_holds_with_gravity_compensation_and_moves_when_pushed():
    """The zero-gravity program of 2.2.2 against the process, pushed via the control channel."""
    with SimulaProcess("-c", "--warm", "--test-channel") as sim:
        ctl = Controller(sim.url)
        ctl.hello()
        h = power_on(ctl, ctl.start())
        q0 = CONV.counts_to_angles(h.pos)

        def weightless(how):
            q = CONV.counts_to_angles(how.pos)
            s23, c23 = np.sin(q[1] + q[2]), np.cos(q[1] + q[2])
            c12, c13, c15 = 5.509, -1.762, -1.192
            w = (c23 * np.cos(q[3]) * np.sin(q[4]) + np.cos(q[4]) * s23) * c15
            tg = np.array([0, w + s23 * c13 + np.cos(q[1]) * c12, w + s23 * c13,
                           -s23 * np.sin(q[3]) * np.sin(q[4]) * c15,
                           (c23 * np.sin(q[4]) + np.cos(q[3]) * np.cos(q[4]) * s23) * c15, 0])
            c = Chg()
            for j, v in enumerate(CONV.tortodac(tg)):
                c.motion[j].issue(CUR, int(v))
            return c

        for _ in range(72):
            h = ctl.cycle(h, weightless(h))
        assert np.max(np.abs(CONV.counts_to_angles(h.pos) - q0)) < 1e-3
        assert sim.command("torque 2 3.0")["ok"]
        for _ in range(18):
            h = ctl.cycle(h, weightless(h))
        moved = CONV.counts_to_angles(h.pos) - q0
        assert moved[1] > 0.01
        assert sim.command("torque clear")["ok"]
        ctl.end(h)
        ctl.bye()


def _lockstep_run(seed: int) -> list[bytes]:
    with SimulaProcess("-c", seed=seed) as sim:
        ctl = Controller(sim.url)
        ctl.hello()
        h = power_on(ctl, ctl.start())
        for k in range(60):
            c = pos({1: h.pos[1] + 30})
            c.motion[4].issue(CUR, 40)
            h = ctl.cycle(h, c)
        ctl.end(h)
        ctl.bye()
        return ctl.raw


def test_lockstep_is_deterministic():
    a, b = _lockstep_run(7), _lockstep_run(7)
    assert len(a) == 62 and a == b
    assert _lockstep_run(8) != a


def test_realtime_mode_keeps_its_clock_and_watchdog_stops_the_arm():
    with SimulaProcess("-p", "--watchdog", "4", "--watchdog-time", "0", lockstep=False) as sim:
        ctl = Controller(sim.url, rate=100)
        assert ctl.hello().mode == protocol.MODE_REALTIME
        h = ctl.start()
        # never answer: the robot keeps sending, counting the missing CHGs, then stops
        frames = [h]
        while True:
            f = ctl.recv()
            frames.append(protocol.decode_how(f.payload, f.seq))
            if frames[-1].status:
                break
        assert [x.cycle for x in frames] == list(range(h.cycle, h.cycle + len(frames)))
        assert frames[-1].status == codes.ST_WATCHDOG and len(frames) == 5
        assert frames[-2].robot_overruns == 3
        dt = np.diff([x.time_ns for x in frames]) / 1e9
        np.testing.assert_allclose(dt, 0.01, atol=1e-9)       # robot clock: one period per HOW
        assert ctl.link.recv(0.2) is None                     # and nothing more
        ctl.bye()


def test_pty_transport():
    with SimulaProcess("-p", pty=True) as sim:
        assert sim.url.startswith("/dev/")
        ctl = Controller(sim.url)
        ctl.hello()
        h = ctl.start()
        h2 = ctl.cycle(h)
        assert h2.cycle == h.cycle + 1 and h2.state & codes.CALIB_OK
        ctl.end(h2)
        ctl.bye()


def test_wrong_robot_is_refused():
    with SimulaProcess("-p", robot="microbo") as sim:
        ctl = Controller(sim.url, robot="puma260")
        with pytest.raises(RuntimeError, match="microbo"):
            ctl.hello()
        ctl.link.close()
        ok = Controller(sim.url, robot="microbo")
        assert ok.hello().robot == "microbo"
        ok.bye()


def test_new_connection_replaces_a_dead_one_and_verbose_prints_seconds():
    with SimulaProcess("-p", "-v") as sim:
        ctl = Controller(sim.url)
        ctl.hello()
        h = ctl.start()
        for _ in range(40):
            h = ctl.cycle(h)
        ctl.link.close()                                    # program killed mid-control
        ctl2 = Controller(sim.url)
        ctl2.hello()
        h = ctl2.start()
        ctl2.cycle(h)
        ctl2.bye()
        # simula's stdout is read by a thread of SimulaProcess: on a loaded machine the line
        # can come in a little after the exchange that made it
        deadline = time.monotonic() + 5.0
        while not any(line.startswith("t=     1.0 s  q(deg) =") for line in sim.lines):
            assert time.monotonic() < deadline, sim.lines
            time.sleep(0.02)


def test_bad_command_line_exits_with_a_message(tmp_path):
    bad = tmp_path / "p.toml"
    bad.write_text("[calib]\nschema = 'nope'\n")
    for args, text in ((["--params", str(bad)], "schema"), (["--robot", "nosuch"], "nosuch"),
                       (["--load", "pulley:joint=7,mass=1,radius=0.1"], "joint")):
        r = subprocess.run([sys.executable, "-m", "rci.simula", "--port", "0", *args],
                           capture_output=True, text=True, timeout=60)
        assert r.returncode == 2 and text in r.stderr


def test_environment_option_presses_the_tool_on_a_plane():
    with SimulaProcess("-p", "--warm", "--env", "plane:z=0.1542", "--env", "tool:z=0.05") as sim:
        ctl = Controller(sim.url)
        ctl.hello()
        h = power_on(ctl, ctl.start())
        hold = h.pos.copy()
        for _ in range(20):
            h = ctl.cycle(h, pos({j: hold[j] for j in range(6)}))
        force = sim.command("state")["state"]["contact_force"]
        assert force[2] == pytest.approx(2e4 * (0.1542 - 0.1532), rel=0.05)
        ctl.end(h)
        ctl.bye()


def test_control_channel_reports_bad_commands():
    with SimulaProcess("-p", "--no-control") as quiet:
        assert quiet.control_url == "" and quiet.url.startswith("socket://")
    with SimulaProcess("-p", "--test-channel") as sim:
        assert sim.command("ping")["ok"]
        for line, text in (("torque 9 1.0", "joint 9"), ("torque 1 nan", "not finite"), ("torque 1", "usage"),
                           ("load pulley:joint=1", "missing"), ("fly", "unknown command"), ("", "empty")):
            reply = sim.command(line) if line else sim.command(" ")
            assert not reply["ok"] and text in reply["error"], (line, reply)
        assert sim.command("load pulley:joint=3,mass=1.5,radius=0.05")["load"] == {
            "joint": 3, "mass": 1.5, "radius": 0.05, "sign": 1}
        assert sim.command("torque 2 -0.5")["external_torque"][1] == -0.5
        st = sim.command("state")["state"]
        assert st["external_torque"][1] == -0.5 and st["calibrated"] == [True] * 6 and not st["power"]
