"""The robot link over Zenoh (rci.bus.link, `simula --zenoh KEY`), against real processes.

Each test starts a simula process serving its arm on the bus (peer to peer over TCP on
loopback, its own port) and controllers in this process or in others; faults are real:
processes killed or stopped. The guarantees are those of the socket link: one owner, a
severe link fault when the robot goes, the arm held when the controller goes.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from rci import codes
from rci.chg import POS
from rci.exceptions import ControlTerminated, DeviceError, RobotBusy
from rci.session import Session
from rci.bus.link import free_endpoint
from rci.simula.process import SimulaProcess
from rci.bus.link import ZenohAddress, ZenohLinkError

ROOT = Path(__file__).resolve().parent.parent
WAIT = 10.0
WATCHDOG_S = 0.25
# what docs/zenoh.md and docs/safety.md promise for a robot that dies or stalls under load (a load
# of 4-5 on 2 cores): the control ended within 0.5 s. Two periods (40 ms) on an idle machine
# (5-10 ms seen), up to 0.19 s seen at that load: the detecting thread waits for a CPU
DETECT_UNDER_LOAD_S = 0.5


def _simula(*args: str, key: str = "test/puma", lockstep: bool = True) -> SimulaProcess:
    endpoint = free_endpoint()
    return SimulaProcess("-p", "--power-on", "--zenoh", key, "--zenoh-listen", endpoint, *args, lockstep=lockstep)


def _session(url: str, **kw) -> Session:
    opts = dict(rate_hz=100, on_error="raise", signals=False, lock_memory=False, realtime=False)
    opts.update(kw)
    return Session(url, "puma260", **opts)


def _cycles(s: Session, n: int) -> None:
    c0 = s.how.cycle
    assert s.wait(seconds=WAIT, until=lambda: s.how.cycle - c0 >= n), "the control stalled"


def _mover(s: Session, step: int = 2):
    def f1():
        s.chg.motion[0].issue(POS, int(s.how.pos[0]) + step)
    return f1


def test_the_address_parses_and_refuses_what_it_cannot_use():
    a = ZenohAddress.parse("zenoh/lab/puma260?connect=tcp/10.0.0.2:7447&lease=500")
    assert (a.key, a.connect, a.lease_ms) == ("lab/puma260", ("tcp/10.0.0.2:7447",), 500)
    assert a.keyexpr("c", "x", "up") == "rcci/lab/puma260/c/x/up"
    assert ZenohAddress.parse(a.url()) == a
    for bad, why in (("zenoh/", "plain key"), ("zenoh/lab/*", "plain key"), ("zenoh/a?port=3", "unknown option"),
                     ("zenoh/a?lease=soon", "milliseconds"), ("socket://x:1", "not a Zenoh")):
        with pytest.raises(ZenohLinkError, match=why):
            ZenohAddress.parse(bad)


def test_no_robot_on_the_key_is_a_clear_open_error():
    url = f"zenoh/nobody/here?connect={free_endpoint()}"
    with pytest.raises(DeviceError, match="cannot open robot link 'zenoh/nobody/here"):
        _session(url, start_timeout=2.0).open()


def test_a_frame_reaches_the_reader_on_zenohs_own_thread():
    """The link's callbacks run on the Zenoh thread that received the frame, not on a Python
    thread of zenoh-python's (an ordinary thread that waited whole periods under load)."""
    import threading

    from rci.bus.link import _declare_publisher, _on_zenoh_thread, _Pipe, open_session

    endpoint = free_endpoint()
    robot, controller = open_session(listen=(endpoint,)), open_session(connect=(endpoint,))
    pipe, threads = _Pipe(), []

    def got(sample) -> None:
        with open(f"/proc/self/task/{threading.get_native_id()}/comm") as f:
            threads.append(f.read().strip())
        pipe.push(sample.payload.to_bytes())

    sub = controller.declare_subscriber("rcci/t/up", _on_zenoh_thread(got))
    try:
        pub = _declare_publisher(robot, "rcci/t/up")
        deadline = time.monotonic() + WAIT
        received = b""
        while len(received) < 3 and time.monotonic() < deadline:
            pub.put(b"f")
            time.sleep(0.05)
            received += pipe.read() or b""
        assert received[:3] == b"fff"
        assert threads and all(name.startswith("rx-") for name in threads), threads
    finally:
        sub.undeclare()
        controller.close()
        robot.close()
        pipe.close()


def test_a_reader_that_stops_reading_ends_its_pipe_and_zenohs_thread_never_waits():
    from rci.bus.link import _Pipe

    pipe = _Pipe()
    t0 = time.monotonic()
    pushed = 0
    while not pipe.overflowed and pushed < 1_000_000:
        pipe.push(b"x" * 100)
        pushed += 1
    assert pipe.overflowed and time.monotonic() - t0 < 5.0
    assert pushed > 250                              # at least the OS's default buffer's worth
    kept = b""
    while (data := pipe.read()) is not None:         # what fitted, then end of file
        assert data, "an overflowed pipe must read as ended, not as empty"
        kept += data
    assert 0 < len(kept) < pushed * 100
    pipe.push(b"late")                               # after the end: ignored, no error
    pipe.close()


def test_a_control_over_the_bus_moves_the_arm_and_releases_it():
    with _simula() as sim:
        assert sim.url.startswith("zenoh/test/puma?connect=tcp/127.0.0.1:")
        q0 = sim.command("state")["state"]["q"][0]
        with _session(sim.url) as s:
            s.control(_mover(s))
            _cycles(s, 50)
            s.release()
        assert s.termination is None
        state = sim.command("state")
        assert abs(state["state"]["q"][0] - q0) > 0.01 and not state["running"] and state["owner"] is None


def test_a_second_controller_on_the_bus_gets_busy_and_the_control_goes_on():
    with _simula() as sim:
        with _session(sim.url, client="owner-program") as owner:
            owner.control(_mover(owner))
            _cycles(owner, 5)
            with pytest.raises(RobotBusy, match="robot busy: owned by pid .*owner-program"):
                _session(sim.url, client="intruder").open()
            _cycles(owner, 10)
            assert owner.in_control and owner.termination is None
            owner.release()


def _fault_after_running(inject, attempts: int = 3) -> tuple[ControlTerminated, int, float]:
    """Run a 50 Hz real-time control over Zenoh for 0.3 s, then ``inject(sim)``; returns the
    control's end, the last cycle before the fault and the seconds from the fault to its end.

    A run whose control ended before the fault (a late HOW on a loaded machine, not the fault
    under test) is repeated, up to ``attempts`` runs in all.
    """
    for _ in range(attempts):
        with _simula(lockstep=False) as sim:
            s = _session(sim.url, rate_hz=50, realtime=True)
            try:
                with s:
                    s.control(_mover(s))
                    try:
                        s.wait(0.3)
                    except ControlTerminated:
                        continue
                    last = s.how.cycle
                    inject(sim)
                    t_fault = time.monotonic()
                    with pytest.raises(ControlTerminated) as e:
                        s.wait(2.0)
                    return e.value, last, time.monotonic() - t_fault
            finally:
                if sim.proc.poll() is None:
                    os.kill(sim.proc.pid, signal.SIGCONT)
    raise AssertionError(f"the control ended before the fault in all {attempts} runs")


def test_the_robot_killed_ends_the_control_with_a_severe_link_fault():
    err, last, detected = _fault_after_running(lambda sim: os.kill(sim.proc.pid, signal.SIGKILL))
    t = err.termination
    assert t.number in (codes.R_BTEST, codes.R_TIMEOUT) and t.severe
    assert t.cycle - last <= 2 and detected < DETECT_UNDER_LOAD_S, f"ended {detected:.3f} s after the kill"


def test_the_robot_stopped_is_a_timeout():
    err, _, detected = _fault_after_running(lambda sim: os.kill(sim.proc.pid, signal.SIGSTOP))
    assert err.termination.number == codes.R_TIMEOUT
    assert detected < DETECT_UNDER_LOAD_S, f"ended {detected:.3f} s after the stop"


CONTROLLER = textwrap.dedent("""
    import sys, time
    import numpy as np
    from rci.chg import CUR
    from rci.conversions import Conversions
    from rci.session import Session
    # timeout 0.2 s (not two periods) and 25 late cycles in a row tolerated (not 3): the test
    # is about the robot's side of the fault, and a loaded machine's bus latency tails (at a
    # load of 5 on 2 cores: a HOW 40 ms late, three CHGs in a row late at the robot) must not
    # end the control from this side first
    s = Session(sys.argv[1], "puma260", rate_hz=50, on_error="raise", signals=False, lock_memory=False,
                timeout=0.2, late_limit=25)
    conv = Conversions.for_robot("puma260")
    s.open()
    last = []
    def f1():
        # joint 1 turned at 0.2 rad/s by its motor current (a speed loop; a positive current
        # turns it negatively): it keeps moving
        # until the robot holds it
        q = conv.counts_to_angles(s.how.pos)[0]
        v = (q - last[0]) * 50 if last else 0.0
        last[:] = [q]
        s.chg.motion[0].issue(CUR, int(np.clip(-70 - 1000 * (0.2 - v), -2000, 2000)))
    s.control(f1)
    print("controlling", flush=True)
    time.sleep(60)
""")


def _controller(url: str) -> subprocess.Popen:
    proc = subprocess.Popen([sys.executable, "-c", CONTROLLER, url], cwd=ROOT, stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "controlling"
    return proc


def _held_after(sim: SimulaProcess, cause, seconds: float = 0.5) -> tuple[dict, float, float]:
    """Apply ``cause`` to a running control; the robot's state once it has ended it, how
    far joint 1 turned from the end to ``seconds`` later (rad), and how long the robot took
    to end the control (s: from the fault to the ending simula recorded, on the same monotonic
    clock, so that this process's polling on a loaded machine does not count)."""
    t0 = time.monotonic()
    cause()
    while sim.command("state")["running"]:
        assert time.monotonic() - t0 < WAIT, "the robot did not end the control"
        time.sleep(0.002)
    took = sim.command("events")["events"][-1]["wall"] - t0
    q_end = sim.command("state")["state"]["q"][0]
    time.sleep(seconds)
    state = sim.command("state")
    return state, abs(state["state"]["q"][0] - q_end), took


@pytest.mark.parametrize("how", ["killed", "stopped"])
def test_the_controller_gone_or_frozen_leaves_the_arm_held(how):
    """A controller process killed (its Zenoh session closes with it) or stopped (the
    robot's watchdog): the control ends and joint 1, driven in current mode, holds."""
    # a watchdog of 0.25 s (not simula's 0.1 s): on a loaded machine the bus's latency tails
    # must not end the control before the fault does
    with _simula("--watchdog-time", str(WATCHDOG_S), lockstep=False) as sim:
        proc = _controller(sim.url)
        try:
            q0 = sim.command("state")["state"]["q"][0]
            deadline = time.monotonic() + WAIT
            # joint 1 in current mode and turning (~0.2 rad/s): the control is under way
            while (moving := sim.command("state")["state"])["mode"][0] != "cur" or abs(moving["q"][0] - q0) < 0.02:
                assert not sim.command("events")["events"], "the control ended before the fault"
                assert time.monotonic() < deadline, moving["mode"]
                time.sleep(0.02)
            sig = signal.SIGKILL if how == "killed" else signal.SIGSTOP
            state, drift, took = _held_after(sim, lambda: os.kill(proc.pid, sig))
        finally:
            os.kill(proc.pid, signal.SIGKILL)
            proc.wait(5)
        assert state["state"]["mode"][0] in ("pos", "hold") or abs(state["state"]["current_A"][0]) < 1e-6
        print(f"{how}: control ended {1e3 * took:.1f} ms after the fault, joint 1 moved {np.degrees(drift):.4f} deg after")
        assert drift < np.radians(0.2)
        # killed: the controller's Zenoh session closes with the process (its TCP link is
        # torn down by the kernel), before the watchdog could act; stopped: the robot's
        # watchdog (WATCHDOG_S without a CHG). The cause simula recorded tells them apart (a
        # bound in time alone failed on a machine with a load of 5 on 2 cores)
        ended = sim.command("events")["events"]
        assert ended, "the robot remembers no control ending"
        cause = ended[-1]["cause"]
        if how == "killed":
            assert cause.startswith("link lost"), cause
            assert took < WATCHDOG_S
        else:
            assert cause == "watchdog", cause
            assert took < WATCHDOG_S + 0.1


# --- shared data and channels between processes (rci.bus) ------------------------------------
BUS_PEER = textwrap.dedent("""
    import sys, time
    import numpy as np
    from rci.bus import Bus
    endpoint, overflow, n = sys.argv[1], sys.argv[2], int(sys.argv[3])
    with Bus("test-cell", tasks=("arm",), connect=(endpoint,)) as bus:
        print("seen", bus.shared.get("plan"), flush=True)       # written before this process joined
        ch = bus.channel("arm", "planning", capacity=4, overflow=overflow)
        for i in range(n):
            ch.send({"i": i, "q": np.arange(6.0) * i})
        bus.shared["arm_done"] = (n, "sent")
        print("sent", n, flush=True)
        time.sleep(1.0)
""")


def _bus_peer(endpoint: str, overflow: str, n: int) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-c", BUS_PEER, endpoint, overflow, str(n)], cwd=ROOT,
                            stdout=subprocess.PIPE, text=True)


def test_shared_data_and_a_blocking_channel_between_two_processes_lose_nothing():
    from rci.bus import Bus

    endpoint = free_endpoint()
    with Bus("test-cell", tasks=("planning",), listen=(endpoint,)) as bus:
        bus.shared["plan"] = np.eye(3)
        channel = bus.channel("arm", "planning", capacity=4, overflow="block")
        peer = _bus_peer(endpoint, "block", 30)
        try:
            assert peer.stdout.readline().strip() == "seen [[1. 0. 0.]"     # numpy prints row by row
            got = []
            while len(got) < 30:
                msg = channel.receive(timeout=WAIT)
                assert msg is not None, f"only {len(got)} of 30 messages arrived"
                got.append(msg)
                assert len(channel) <= 4                 # the sender waits for the receiver's room
                time.sleep(0.005)
            assert [m["i"] for m in got] == list(range(30)) and channel.dropped == 0
            np.testing.assert_array_equal(got[7]["q"], np.arange(6.0) * 7)
            deadline = time.monotonic() + WAIT
            while bus.shared.get("arm_done") is None and time.monotonic() < deadline:
                time.sleep(0.01)
            assert bus.shared["arm_done"] == (30, "sent")
        finally:
            peer.kill()
            peer.wait(5)


def test_a_late_joiner_reads_shared_data_written_before_it_came():
    from rci.bus import Bus

    endpoint = free_endpoint()
    with Bus("test-cell", tasks=("planning",), listen=(endpoint,)) as bus:
        bus.shared["plan"] = [1, 2, 3]
        bus.channel("arm", "planning", capacity=4, overflow="drop_oldest")
        peer = _bus_peer(endpoint, "drop_oldest", 1)
        try:
            assert peer.stdout.readline().strip() == "seen [1, 2, 3]"
        finally:
            peer.kill()
            peer.wait(5)


def test_a_dropping_channel_keeps_the_newest_and_counts_the_lost():
    from rci.bus import Bus

    endpoint = free_endpoint()
    with Bus("test-cell", tasks=("planning",), listen=(endpoint,)) as bus:
        channel = bus.channel("arm", "planning", capacity=4, overflow="drop_oldest")
        peer = _bus_peer(endpoint, "drop_oldest", 50)
        try:
            assert peer.stdout.readline().startswith("seen")
            assert peer.stdout.readline().strip() == "sent 50"
            deadline = time.monotonic() + WAIT
            while channel.dropped + len(channel) < 50 and time.monotonic() < deadline:
                time.sleep(0.01)
            got = [channel.receive() for _ in range(4)]
            assert [m["i"] for m in got] == [46, 47, 48, 49] and channel.dropped == 46
            assert channel.receive() is None
        finally:
            peer.kill()
            peer.wait(5)


def test_a_channel_end_that_is_not_this_processes_task_is_refused():
    from rci.bus import Bus
    from rci.multi import MultiError

    with Bus("test-cell", tasks=("planning",), listen=(free_endpoint(),)) as bus:
        channel = bus.channel("arm", "planning")
        with pytest.raises(MultiError, match="'arm' is not a task of this process"):
            channel.send({"x": 1})
        with pytest.raises(MultiError, match="cannot cross processes"):
            bus.shared["x"] = object()


def test_two_arms_in_two_processes_coordinated_over_the_bus():
    """examples/two_arms_bus.py: the PUMA's and the Microbo's control tasks in two processes,
    each arm on its own simula over the bus; the Microbo mirrors the PUMA's waist from the
    shared data and reports to the planning process on a channel."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("two_arms_bus", ROOT / "examples" / "two_arms_bus.py")
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    # simula's watchdog at 0.25 s, as docs/zenoh.md advises on a loaded machine (the arm
    # processes' own limits are the example's: a 0.25 s timeout, 9 late cycles at 36 Hz)
    room = ("--watchdog-time", str(WATCHDOG_S))
    with SimulaProcess("-p", *room, "--zenoh", "lab/puma", "--zenoh-listen", free_endpoint(),
                       robot="puma260", lockstep=False) as puma, \
            SimulaProcess("-p", *room, "--zenoh", "lab/microbo", "--zenoh-listen", free_endpoint(),
                          robot="microbo", lockstep=False) as microbo:
        reports = example.plan({"puma": puma.url, "microbo": microbo.url},
                               free_endpoint(), seconds=3.0, quiet=True)
        assert not puma.command("state")["running"] and not microbo.command("state")["running"]
    assert len(reports) >= 4
    swung = [r for r in reports if r["sample"] >= 36]           # after the Microbo caught up
    assert max(abs(r["puma_waist"]) for r in swung) > np.radians(5)
    for r in swung:                                              # the mirror, to a sample's motion
        assert abs(r["puma_waist"] + r["command"]) < np.radians(1.0), r
