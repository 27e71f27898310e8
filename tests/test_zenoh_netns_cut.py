"""A planning process cut off by the network mid-plan, and the network back (issue 17, item 2).

Two network namespaces joined by a veth pair (``tests/test_zenoh_netns.py``'s helpers):
in A a real-time simula and the arm process (``python -m rccl.bus.arm``) driving it over
a socket on A's loopback; in B the planning process, the bus's hub, listening on B's
address. The planning process queues a long motion of the waist and a held one behind
it; the test then cuts the network between A and B, two ways: B's end of the veth down
(a cable pulled), or blackhole routes on both sides with the veth up (a network that
drops everything). The TCP connection between the two stays open (Zenoh's lease, 10 s,
does not end it and the liveliness tokens stay; the test checks the connection with
``ss``): only the heartbeats tell each side that the other went silent. The test reads
when the arm process gave the planning level up (the time it prints; one kernel, one
monotonic clock in every namespace), simula's state (from inside A: its control channel
is on A's loopback), then brings the network back and reads what the planning process
learnt: ``ArmLost`` during the cut, ``PlannerLost`` once the network is back, and a new
planning level that drives the arm again. Every wait is bounded; everything is removed
in a ``finally``.

The robot link cut the same way (simula over Zenoh in A, a controller in B): the control
ends on the controller's timeout, simula's watchdog stops the arm, nothing moves when the
network is back.
"""
from __future__ import annotations

import ctypes
import json
import os
import signal
import socket
import subprocess
import sys
import textwrap
import threading
import time
import uuid

import numpy as np
import pytest

from rccl.bus.planning import HEARTBEAT_S, SILENCE_S
from rci import codes
from rci.simula.process import ToolProcess
from tests.test_zenoh_flag_faults import _line, held_where_it_is, waist_on_its_way
from tests.test_zenoh_netns import ADDR_A, ADDR_B, _ip, _namespaces, _remove_all

PORT = 7448
RATE_HZ = 50
CLONE_NEWNET = 0x40000000

PLANNER = textwrap.dedent("""
    import sys, time
    from rccl.bus.planning import ArmLost, BusEvents, PlannerLost
    from rccl.events import DONE
    from rccl.position import joint_position
    from rci.bus import Bus

    def waist(arm, q, delta, name):
        q = q.copy()
        q[0] += delta
        return joint_position(name, arm.kinematics, q)

    with Bus(sys.argv[1], tasks=("planning",), listen=(sys.argv[2],)) as bus:
        print("listening", flush=True)
        ev = BusEvents(bus)
        puma = ev.arm("puma", timeout=60.0)
        q0 = puma.q
        a = ev.move_ev(puma, waist(puma, q0, 0.5, "long_way"))
        b = ev.move_ev(puma, waist(puma, q0, 0.0, "back"), start=None)           # held behind it
        ev.wait_ev(a, started=True, timeout=10.0)
        print(f"moving {a.serial} {b.serial} {ev.id}", flush=True)
        try:
            ev.wait_ev(a, timeout=10.0)                # the network is cut meanwhile
            print("not cut", flush=True)
        except ArmLost as exc:
            print(f"lost t={time.monotonic():.6f} {type(exc).__name__}: {exc}", flush=True)
        sys.stdin.readline()                           # the test brought the network back
        back = time.monotonic()
        while ev.given_up("puma") is None and time.monotonic() - back < 8.0:
            time.sleep(0.01)
        print(f"told after {time.monotonic() - back:.3f} s: {ev.given_up('puma')}", flush=True)
        for what, call in (("wait_ev", lambda: ev.wait_ev(a, timeout=2.0)), ("request", lambda: puma.q),
                           ("start_ev", lambda: ev.start_ev(3, b))):
            try:
                call()
                print(f"{what} not refused", flush=True)
            except ArmLost as exc:
                print(f"{what} refused: {type(exc).__name__}: {exc}", flush=True)
        ev.close()
        ev = BusEvents(bus)                            # a new planning level drives the arm again
        puma = ev.arm("puma", timeout=10.0)
        q1 = puma.q
        c = ev.move_ev(puma, waist(puma, q1, -0.05, "again"))
        status = ev.wait_ev(c, timeout=10.0)
        print(f"again {int(status == DONE)} {float(q1[0])!r} {float(puma.q[0])!r}", flush=True)
        puma.close()
        ev.close()
""")


class _Control:
    """simula's control channel, reached from inside namespace ``ns`` (its socket is made there)."""

    def __init__(self, ns: str, url: str, timeout: float = 5.0) -> None:
        host, port = url.removeprefix("socket://").rsplit(":", 1)
        made: list = []

        def connect() -> None:           # a thread enters the namespace (setns is per thread)
            libc = ctypes.CDLL(None, use_errno=True)
            with open(f"/var/run/netns/{ns}") as f:
                if libc.setns(f.fileno(), CLONE_NEWNET) != 0:
                    made.append(OSError(ctypes.get_errno(), f"setns into {ns}"))
                    return
            try:
                made.append(socket.create_connection((host, int(port)), timeout=timeout))
            except OSError as exc:
                made.append(exc)

        t = threading.Thread(target=connect)
        t.start()
        t.join(timeout + 1.0)
        if not made or isinstance(made[0], Exception):
            raise RuntimeError(f"cannot reach simula's control channel {url} inside {ns}: {made}")
        self.sock, self.buf = made[0], b""

    def command(self, line: str) -> dict:
        self.sock.sendall(line.encode() + b"\n")
        while b"\n" not in self.buf:
            data = self.sock.recv(65536)
            if not data:
                raise RuntimeError("simula closed its control channel")
            self.buf += data
        raw, _, self.buf = self.buf.partition(b"\n")
        return json.loads(raw)

    def q(self) -> np.ndarray:
        return np.array(self.command("state")["state"]["q"])


def _links(ns: str) -> set[str]:
    """The established TCP connections inside ``ns`` to the planning process's port (local ends)."""
    out = subprocess.run(["ip", "netns", "exec", ns, "ss", "-Htn", "state", "established", "dst",
                          f"{ADDR_B}:{PORT}"], capture_output=True, text=True, check=True).stdout
    return {line.split()[-2] for line in out.splitlines() if line.strip()}


def _cut(how: str, ns_a: str, ns_b: str, veth_b: str, cut: bool) -> None:
    """Cut the network between the namespaces (``cut``) or bring it back: ``veth`` takes B's
    end of the veth down (a cable pulled: A's end loses its carrier); ``blackhole`` leaves the
    veth up and routes each side's packets to the other into a blackhole (a network that
    drops everything on the way). Neither closes a socket or tells the processes."""
    if how == "veth":
        _ip("-n", ns_b, "link", "set", veth_b, "down" if cut else "up")
    else:
        for ns, other in ((ns_a, ADDR_B), (ns_b, ADDR_A)):
            _ip("-n", ns, "route", "add" if cut else "del", "blackhole", f"{other}/32")


def _end(proc: subprocess.Popen | None) -> None:
    if proc is not None and proc.poll() is None:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(5)


@pytest.mark.parametrize("how", ["veth", "blackhole"])
def test_a_planning_process_cut_off_by_the_network_is_given_up_and_told_when_it_is_back(how: str):
    tag = uuid.uuid4().hex[:6]
    made: list[str] = []
    sim = planner = arm = ctl = None
    try:
        made += _namespaces(tag)
        ns_a, ns_b = made
        veth_b = f"vr{tag}b"
        sim = ToolProcess(["ip", "netns", "exec", ns_a, sys.executable, "-m", "rci.simula", "--robot", "puma260",
                           "-p", "--power-on", "--watchdog-time", "0.25", "--port", "0"]).start()
        ctl = _Control(ns_a, sim.control_url)
        endpoint = f"tcp/{ADDR_B}:{PORT}"
        planner = subprocess.Popen(["ip", "netns", "exec", ns_b, sys.executable, "-c", PLANNER, f"cut-{tag}", endpoint],
                                   stdout=subprocess.PIPE, stdin=subprocess.PIPE, cwd=os.getcwd())
        _line(planner, 30.0, "listening")
        arm = subprocess.Popen(["ip", "netns", "exec", ns_a, sys.executable, "-m", "rccl.bus.arm", "puma", sim.url,
                                "puma260", "--cell", f"cut-{tag}", "--rate", str(RATE_HZ), "--bus", endpoint,
                                "--timeout", "0.25"], stdout=subprocess.PIPE, stdin=subprocess.DEVNULL, cwd=os.getcwd())
        _line(arm, 30.0, "puma: serving")
        moving = _line(planner, 30.0, "moving").split()
        serials, planner_id = [int(x) for x in moving[1:3]], moving[3]
        time.sleep(0.2)
        t2, q2, speed = waist_on_its_way(ctl.q)                 # on its way to 0.5 rad
        links = _links(ns_a)
        assert len(links) == 1, links                          # the arm process's one link to the hub

        # the cut: nothing tells either TCP end
        t_cut = time.monotonic()                   # before the cut: the figure can only be too long
        _cut(how, ns_a, ns_b, veth_b, cut=True)
        said = _line(arm, 5.0, "aborted, the arm holds")
        assert f"the planning process {planner_id} went silent: no heartbeat for" in said, said
        assert f"motion(s) #{serials[0]}, #{serials[1]} aborted" in said
        t_held = float(said.rsplit("t=", 1)[1].rstrip(")"))     # one kernel: one monotonic clock in both namespaces
        detected = t_held - t_cut
        quiet = float(said.split("no heartbeat for ", 1)[1].split(" s", 1)[0])
        assert quiet >= SILENCE_S, said
        assert 0.0 < detected < SILENCE_S + HEARTBEAT_S + 0.1, f"given up {detected:.3f} s after the cut: {said}"
        print(f"cut ({how}): the arm process gave the planning level up {detected:.3f} s after the cut")
        # and the planning process gave its arm up by the arm's silence (its wait may have been
        # asking the arm for its flags, a 0.5 s query, when the silence came: up to that longer)
        lost = _line(planner, 5.0, "lost t=")
        assert "ArmLost: wait_ev:" in lost and "'puma'" in lost and "went silent" in lost, lost
        arm_lost = float(lost.split("t=", 1)[1].split()[0]) - t_cut
        assert 0.0 < arm_lost < SILENCE_S + 0.5 + 0.2, f"the planning process lost its arm {arm_lost:.3f} s after the cut"
        print(f"cut ({how}): the planning process lost its arm {arm_lost:.3f} s after the cut")
        # the arm holds where it is, under its control (simula's owner is still the arm process)
        q4 = held_where_it_is(lambda: ctl.command("state"), q2, speed, t_held, t2, 0.4, "the cut")
        assert _links(ns_a) == links                           # the TCP link is still open: only the heartbeat told

        # the network back: the same TCP link carries on; the planning process learns it was given up
        _cut(how, ns_a, ns_b, veth_b, cut=False)
        t_back = time.monotonic()
        planner.stdin.write(b"back\n")
        planner.stdin.flush()
        told = _line(planner, 10.0, "told after")
        # by the arm process's held notice (sent during the cut, delivered now) or its heartbeat's gone list
        assert ("its process says: the planning process " + planner_id + " went silent") in told \
            or "lists this planning level as given up in its heartbeat" in told, told
        assert _links(ns_a) == links                           # the same TCP link: Zenoh did not reconnect
        learnt = float(told.split("told after ", 1)[1].split(" s", 1)[0])
        print(f"back ({how}): the planning process learnt it was given up {learnt:.3f} s after the network came back "
              f"({time.monotonic() - t_back:.3f} s here)")
        for what in ("wait_ev", "request", "start_ev"):
            refused = _line(planner, 5.0, what)
            assert f"{what} refused: PlannerLost" in refused and "gave this planning level up" in refused, refused
        assert np.max(np.abs(ctl.q() - q4)) < 1e-5                # nothing of the old plan moved
        again = _line(planner, 15.0, "again").split()
        assert again[1] == "1" and abs(float(again[3]) - (float(again[2]) - 0.05)) < 2e-3, again
        assert abs(ctl.q()[0] - (q4[0] - 0.05)) < 2e-3
        assert planner.wait(10) == 0
        assert arm.wait(10) == 0
        assert arm.stdout.read().decode().strip().endswith("puma: released")
        assert _links(ns_a) == set()
    finally:
        _end(planner)
        _end(arm)
        if ctl is not None:
            ctl.sock.close()
        if sim is not None:
            sim.stop()
        _remove_all(tag, made)


CONTROLLER = textwrap.dedent("""
    import sys, time
    from rci.chg import POS
    from rci.exceptions import ControlTerminated
    from rci.session import Session
    # an ordinary process: 0.2 s without a HOW ends its control (the link is under test, not
    # the timing of a loaded machine)
    s = Session(sys.argv[1], "puma260", rate_hz=50, on_error="raise", signals=False, lock_memory=False,
                realtime=False, timeout=0.2, late_limit=25)
    with s:
        def f1():
            s.chg.motion[0].issue(POS, int(s.how.pos[0]) + 40)   # the waist on its way, every sample
        s.control(f1)
        s.wait(seconds=1.0)
        print("running", flush=True)
        try:
            s.wait(seconds=10.0)
            print("survived", flush=True)
        except ControlTerminated as exc:
            print(f"ended t={time.monotonic():.6f} {exc.termination.number} {exc}", flush=True)
""")


def test_the_robot_link_cut_ends_the_control_on_both_sides_and_the_arm_holds():
    """The robot link over Zenoh cut between namespaces (simula in A, the controller in B, B's
    end of the veth down, the TCP connection left open): the controller's control ends on its
    timeout, simula's watchdog stops the arm, and nothing moves when the network is back."""
    tag = uuid.uuid4().hex[:6]
    made: list[str] = []
    sim = controller = ctl = None
    try:
        made += _namespaces(tag)
        ns_a, ns_b = made
        sim = ToolProcess(["ip", "netns", "exec", ns_a, sys.executable, "-m", "rci.simula", "--robot", "puma260",
                           "-p", "--power-on", "--watchdog-time", "0.25", "--zenoh", "lab/puma",
                           "--zenoh-listen", f"tcp/{ADDR_A}:{PORT}", "--port", "0"]).start()
        ctl = _Control(ns_a, sim.control_url)
        controller = subprocess.Popen(["ip", "netns", "exec", ns_b, sys.executable, "-c", CONTROLLER, sim.url],
                                      stdout=subprocess.PIPE, stdin=subprocess.DEVNULL, cwd=os.getcwd())
        _line(controller, 30.0, "running")
        t2, q2, speed = waist_on_its_way(ctl.q)
        assert ctl.command("state")["running"]

        t_cut = time.monotonic()
        _cut("veth", ns_a, ns_b, f"vr{tag}b", cut=True)
        ended = _line(controller, 5.0, "ended")
        t_end = float(ended.split("t=", 1)[1].split()[0])
        assert int(ended.split()[2]) == codes.R_TIMEOUT, ended
        assert 0.0 < t_end - t_cut < 0.2 + 0.3, ended        # its timeout, and the wait's poll
        # simula: its watchdog ended the control and holds the arm (about --watchdog-time after
        # the last CHG); the waist went on at most until then
        deadline = time.monotonic() + 3.0
        while ctl.command("state")["running"] and time.monotonic() < deadline:
            time.sleep(0.05)
        state = ctl.command("state")
        assert not state["running"], state
        events = ctl.command("events")["events"]
        stops = [e for e in events if "watchdog" in e["cause"]]
        assert stops, events
        held_after = stops[-1]["wall"] - t_cut                   # simula's time.monotonic(): one kernel
        assert 0.0 < held_after < 0.25 + 2 * 0.02 + 0.1, stops[-1]   # --watchdog-time, a period or two
        q3 = ctl.q()
        time.sleep(0.3)
        q4 = ctl.q()
        assert np.max(np.abs(q4 - q3)) < 1e-5
        assert abs(q3[0] - q2[0]) <= speed * (time.monotonic() - t2) + 1e-3
        assert abs(q3[0] - q2[0]) <= speed * (t_cut - t2 + 0.25 + 0.1) + 1e-3, (q2, q3, speed)
        print(f"robot link cut: the controller's control ended {t_end - t_cut:.3f} s after the cut, "
              f"simula's watchdog stopped the arm {held_after:.3f} s after it")
        # the network back: nothing of the ended control moves the arm
        _cut("veth", ns_a, ns_b, f"vr{tag}b", cut=False)
        time.sleep(0.5)
        assert np.max(np.abs(ctl.q() - q4)) < 1e-5 and not ctl.command("state")["running"]
        assert controller.wait(10) == 0
    finally:
        _end(controller)
        if ctl is not None:
            ctl.sock.close()
        if sim is not None:
            sim.stop()
        _remove_all(tag, made)
