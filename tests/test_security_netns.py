"""Nobody on the network moves the arm (issue 26): attackers on a second host against a secured cell.

Two network namespaces joined by a veth pair, made by the test (as tests/test_zenoh_netns.py):
in A, ``simula --zenoh lab/puma`` with the cell's robot configuration (mutual TLS, access
control: ``python -m rci.bus.keys``); in B, the owner (a control holding the arm at 50 Hz,
for a few seconds) and one attacker process at a time (tests/security_attacker.py). Each
test asserts, from simula's own record (its control channel, reached inside namespace A),
that the arm did not move, that the owner's control went on (simula: still running, the
same owner; the owner: no termination, every cycle run), and what was reported; in the
hello flood, that a new controller asking in the middle of it is answered at once (the
fairness rule: at most HELLO_PER_SESSION_HZ hellos a second from any one session).
Figures for docs/security.md: ``pytest -s`` prints them.
"""
from __future__ import annotations

import ctypes
import json
import os
import select
import socket
import subprocess
import sys
import textwrap
import threading
import time
import uuid
from pathlib import Path

import numpy as np
import pytest

from rci.bus.keys import make_cell
from rci.bus.link import HELLO_PER_SESSION_HZ
from rci.simula.process import ToolProcess
from test_zenoh_netns import ADDR_A, PORT, _namespaces, _remove_all

ROOT = Path(__file__).resolve().parent.parent
KEY = "lab/puma"
HOLD_S = 40.0                 # the owner's control at most; it releases the arm when told the attacks are over
STILL_RAD = np.radians(0.01)  # "did not move": joint 1 within 0.01 deg of where it was
HELLO_ANSWERED_S = 3.0        # a controller asking during a hello flood is answered within this (docs/security.md)

OWNER = textwrap.dedent("""
    import json, sys, threading, time
    from rci.session import Session
    url, seconds = sys.argv[1], float(sys.argv[2])
    told = threading.Event()           # a line on stdin: the attacks are over, release the arm
    threading.Thread(target=lambda: (sys.stdin.readline(), told.set()), daemon=True).start()
    # generous lateness and timeout: the attacks are under test here, not the timing of a loaded machine
    # a controller as a user runs one: real time (SCHED_FIFO where allowed), on a machine that the
    # attacker's floods load too; generous lateness and timeout for a loaded test machine
    s = Session(url, "puma260", rate_hz=50, on_error="raise", signals=False, lock_memory=False, realtime=True,
                timeout=0.5, late_limit=50, client="owner")
    s.open()
    port = s.link.transport.port
    s.control(None)
    print(json.dumps({"id": port.id}), flush=True)
    c0, t0, ended = s.how.cycle, time.monotonic(), None
    try:
        s.wait(seconds, until=told.is_set)
    except Exception as exc:
        ended = f"{type(exc).__name__}: {exc}"
    out = {"cycles": s.how.cycle - c0, "seconds": time.monotonic() - t0, "ended": ended,
           "rejected": port.rejected.total, "why": port.rejected.describe()}
    if ended is None:
        s.release()
    s.close()
    print(json.dumps(out), flush=True)
""")


def _in_namespace(ns: str, fn):
    """Run ``fn()`` on a thread that joined network namespace ``ns`` (setns is per thread), and
    return its result: a socket made there stays in that namespace."""
    box: dict = {}

    def run() -> None:
        libc = ctypes.CDLL(None, use_errno=True)
        fd = os.open(f"/var/run/netns/{ns}", os.O_RDONLY)
        try:
            if libc.setns(fd, 0x40000000) != 0:          # CLONE_NEWNET
                box["error"] = OSError(ctypes.get_errno(), "setns")
                return
            box["value"] = fn()
        except Exception as exc:
            box["error"] = exc
        finally:
            os.close(fd)

    t = threading.Thread(target=run)
    t.start()
    t.join(10)
    if "error" in box:
        raise box["error"]
    return box["value"]


class Control:
    """simula's control channel, inside namespace A (JSON lines)."""

    def __init__(self, ns: str, url: str) -> None:
        host, port = url.removeprefix("socket://").rsplit(":", 1)
        self.sock = _in_namespace(ns, lambda: socket.create_connection((host, int(port)), timeout=5))
        self.buf = b""

    def __call__(self, line: str) -> dict:
        self.sock.sendall(line.encode() + b"\n")
        while b"\n" not in self.buf:
            data = self.sock.recv(1 << 20)
            assert data, "simula closed its control channel"
            self.buf += data
        raw, _, self.buf = self.buf.partition(b"\n")
        return json.loads(raw)


@pytest.fixture(scope="module")
def cell(tmp_path_factory):
    tag = uuid.uuid4().hex[:6]
    made: list[str] = []
    try:
        made += _namespaces(tag)
        keys = make_cell(tmp_path_factory.mktemp("cell"), [KEY], [ADDR_A], PORT)
        yield made[0], made[1], keys
    finally:
        _remove_all(tag, made)


def _run_in(ns: str, *argv: str, timeout: float = 40.0) -> subprocess.CompletedProcess:
    return subprocess.run(["ip", "netns", "exec", ns, sys.executable, *argv], capture_output=True, text=True,
                          timeout=timeout, cwd=ROOT)


def _attack(ns: str, *args: str, timeout: float = 40.0) -> dict:
    out = _run_in(ns, str(ROOT / "tests" / "security_attacker.py"), *args, timeout=timeout)
    assert out.returncode == 0, out.stderr[-3000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


def _secured_run(cell, attack) -> tuple[dict, dict, dict, list[float]]:
    """simula in A, the owner in B; the attack while the owner holds the arm. Returns
    (the attack's result, the owner's result, simula's bus record, joint 1 as simula sampled it)."""
    ns_a, ns_b, keys = cell
    sim = ToolProcess(["ip", "netns", "exec", ns_a, sys.executable, "-m", "rci.simula", "--robot", "puma260",
                       "-p", "--power-on", "--rate", "50", "--watchdog-time", "0.5", "--zenoh", KEY,
                       "--zenoh-config", str(keys["robot"]), "--port", "0"]).start()
    owner = None
    try:
        assert sim.url == f"zenoh/{KEY}?connect=tls/{ADDR_A}:{PORT}"
        url = f"zenoh/{KEY}?config={keys['controller']}"
        ctl = Control(ns_a, sim.control_url)
        owner = subprocess.Popen(["ip", "netns", "exec", ns_b, sys.executable, "-c", OWNER, url, str(HOLD_S)],
                                 stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                 cwd=ROOT)
        ready, _, _ = select.select([owner.stdout], [], [], 30)
        assert ready, "the owner did not take the arm within 30 s"
        first = owner.stdout.readline()
        assert first, owner.stderr.read()[-3000:]
        owner_id = json.loads(first)["id"]
        who = f"zenoh connection {owner_id}"
        state = ctl("state")
        assert state["running"] and state["owner"]["address"] == who, state["owner"]
        waist = [state["state"]["q"][0]]
        box: dict = {}
        attacker = threading.Thread(target=lambda: box.setdefault("result", attack(owner_id, state["cycle"])))
        attacker.start()
        while attacker.is_alive():              # simula's record of joint 1 all through the attack
            state = ctl("state")
            if not state["running"]:
                attacker.join(60)
                rest, err = owner.communicate("over\n", timeout=30)
                raise AssertionError(f"the owner's control ended during the attack: owner {rest!r} {err[-2000:]!r}, "
                                     f"simula {ctl('events')['events']}")
            assert state["owner"]["address"] == who, state
            waist.append(state["state"]["q"][0])
            attacker.join(0.05)
        assert "result" in box, "the attack failed (its error is above)"
        result = box["result"]
        state = ctl("state")
        assert state["running"] and state["owner"]["address"] == who, state
        waist.append(state["state"]["q"][0])
        rest, err = owner.communicate("over\n", timeout=30)
        assert owner.returncode == 0, err[-3000:]
        end = json.loads(rest.strip().splitlines()[-1])
        # simula reports a flood once it has been quiet for a second: wait for that report (the
        # owner's ending may take less than the second under load)
        time.sleep(0.6)
        deadline = time.monotonic() + 10.0
        bus = ctl("events")["bus"]
        while ((bus["rejected"] or bus.get("hello_dropped") or bus.get("hello_refused")) and not bus["reports"]
               and time.monotonic() < deadline):
            time.sleep(0.2)
            bus = ctl("events")["bus"]
        return result, end, bus, waist
    finally:
        if owner is not None and owner.poll() is None:
            owner.kill()
        sim.stop()


def _owner_went_on(end: dict) -> None:
    assert end["ended"] is None, end
    assert end["cycles"] >= 0.9 * 50 * end["seconds"] - 5, end       # every cycle ran


def _still(waist: list[float]) -> None:
    moved = max(abs(q - waist[0]) for q in waist)
    assert moved < STILL_RAD, f"joint 1 moved {np.degrees(moved):.4f} deg"


def test_an_attacker_without_credentials_reaches_nothing(cell):
    result, end, bus, waist = _secured_run(cell, lambda *_: _attack(cell[1], "nocert", f"tls/{ADDR_A}:{PORT}", KEY))
    _still(waist)
    _owner_went_on(end)
    # refused when its link opened: it saw no connection, and its own controller never met the robot
    assert result["tcp_ids_seen"] == 0 and result["tls_ids_seen"] == 0, result
    assert "opened" not in (result["tcp_link"], result["tls_link"]), result
    assert "no robot answers" in result["tls_link"], result
    assert bus["rejected"] == 0 and bus["hello_asked"] == 1, bus       # only the owner's hello came through


def test_a_member_of_the_cell_that_is_not_the_controller_is_refused_by_access_control(cell):
    result, end, bus, waist = _secured_run(
        cell, lambda owner, _: _attack(cell[1], "observer", str(cell[2]["observer"]), KEY, owner))
    _still(waist)
    _owner_went_on(end)
    assert result["ids_seen"] == 0 and result["frames_read"] == 0, result     # it reads nothing of the link
    assert "no robot answers" in result["link"], result                       # its hello never reaches the robot
    assert bus["rejected"] == 0 and bus["hello_asked"] == 1, bus              # nor do its 100 forged CHGs


def test_the_controllers_credentials_without_the_owners_key_move_nothing(cell):
    """The probe's rows 2 and 3 with the controller's own certificate: copied seq, valid checksum,
    a release, a bad checksum, the owner's own CHGs replayed; and a connection of its own."""
    result, end, bus, waist = _secured_run(cell, lambda owner, cycle: _attack(
        cell[1], "insider", str(cell[2]["controller"]), KEY, owner, str(cycle)))
    _still(waist)
    _owner_went_on(end)
    # the robot is a Zenoh peer, which routes nothing between its peers: the owner's liveliness and
    # CHGs are not seen by another controller; the robot's HOWs to the owner reach a subscriber
    # holding the controller's certificate, encrypted: not one readable
    assert result["ids_seen"] == 0 and result["down_read"] == 0, result
    assert result["up_read"] > 10 and result["how_readable"] == 0, result
    assert "RobotBusy" in result["link"] and "owner" in result["link"], result    # the owner keeps the arm
    sent = result["forged"] + result["replayed"] + result["bad_checksum"]
    assert bus["rejected"] == sent, bus
    assert bus["rejected_why"] == f"{sent} out of sequence", bus
    assert any(f"{sent} rejected" in line for line in bus["reports"]), bus["reports"]
    assert end["rejected"] == 0, end                                      # the owner's side saw nothing forged


def _attacker(ns: str, *args: str) -> subprocess.Popen:
    return subprocess.Popen(["ip", "netns", "exec", ns, sys.executable, str(ROOT / "tests" / "security_attacker.py"),
                             *args], stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            cwd=ROOT)


def _json_line(proc: subprocess.Popen, timeout: float) -> dict:
    ready, _, _ = select.select([proc.stdout], [], [], timeout)
    line = proc.stdout.readline() if ready else ""
    if not line:
        proc.kill()
        raise AssertionError(f"no line from the attacker within {timeout} s: {proc.stderr.read()[-3000:]}")
    return json.loads(line)


def test_a_flood_of_hellos_ends_no_control_and_locks_no_controller_out(cell):
    """20,000 hello queries from one session (the probe's 2000 locked a controller out for ~10 s),
    and a new controller that asks in the middle of the flood: it is answered at once (busy:
    the owner holds the arm), since Zenoh lets in at most HELLO_PER_SESSION_HZ hellos a second
    from each session (the fairness rule, docs/security.md)."""
    n, min_s = 20_000, 6.0
    keys = cell[2]

    def flood(*_):
        ctl = _attacker(cell[1], "link-on-go", str(keys["controller"]), KEY)       # its start-up done first
        hello = _attacker(cell[1], "flood-hello", str(keys["controller"]), KEY, str(n), str(min_s))
        try:
            assert _json_line(ctl, 30).get("ready"), "the controller did not start"
            flooding = _json_line(hello, 30)["flooding"]
            ctl.stdin.write("go\n")
            ctl.stdin.flush()
            after = _json_line(ctl, 30)
            hello_out = _json_line(hello, 60)
        finally:
            for p in (ctl, hello):
                if p.poll() is None:
                    p.kill()
        return hello_out, after, flooding

    (hello, after, flooding), end, bus, waist = _secured_run(cell, flood)
    _still(waist)
    _owner_went_on(end)
    print(f"\nhello flood: {hello['sent']} sent in {hello['seconds']:.1f} s; a controller asking during it answered "
          f"in {after['t_answered'] - after['t_asked']:.2f} s; at the robot: {bus['hello_asked']} asked, "
          f"{bus['hello_refused']} refused, {bus['hello_dropped']} dropped; {bus['reports']}")   # docs/security.md (pytest -s)
    assert hello["sent"] >= n, hello
    # asked during the flood and answered during it, within the bound docs/security.md promises
    assert flooding <= after["t_asked"] and after["t_answered"] < hello["t_end"], (flooding, after, hello)
    assert "RobotBusy" in after["link"] and "owner" in after["link"], after
    assert after["t_answered"] - after["t_asked"] < HELLO_ANSWERED_S, after
    # what reached the robot from the flooding session: HELLO_PER_SESSION_HZ a second at most (+1: the
    # first), the rest dropped by Zenoh where it came in; each one that reached it refused (unusable key)
    allowed = HELLO_PER_SESSION_HZ * (hello["seconds"] + 1.0) + 1
    assert 2 <= bus["hello_asked"] <= allowed + 2, (bus, hello)          # + the owner's and the new controller's
    assert bus["hello_dropped"] == 0 and bus["connections"] <= 2, bus
    assert bus["hello_asked"] - 3 <= bus["hello_refused"] < bus["hello_asked"], bus   # the legitimate ones not
    assert any("hello queries refused" in line for line in bus["reports"]), bus["reports"]


def test_floods_of_garbage_truncated_and_oversized_frames_end_no_control(cell):
    """20,000 garbage and 20,000 truncated CHGs on the owner's command key, and oversized
    publications (4 KB, 64 KB, 1 MB): each probe row ended the owner's control."""
    n = 20_000
    frames, end, bus, waist = _secured_run(cell, lambda owner, _: _attack(
        cell[1], "flood-frames", str(cell[2]["controller"]), KEY, owner, str(n)))
    _still(waist)
    _owner_went_on(end)
    # Zenoh may drop a large publication on the way (the attacker's are sent without blocking)
    assert frames["sent"] - 3 <= bus["rejected"] <= frames["sent"], bus
    # the oversized ones are counted under the first reason that drops them: "oversized", or "out
    # of sequence" / "for no connection" when their number or key comes first (seen in a run here)
    assert "too short" in bus["rejected_why"], bus
    assert "out of sequence" in bus["rejected_why"], bus
    assert any(f"{bus['rejected']} rejected" in line for line in bus["reports"]), bus["reports"]
    assert end["rejected"] == 0, end
