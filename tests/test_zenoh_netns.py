"""The Zenoh link between two network namespaces joined by a veth pair (two hosts, made by the test).

The test makes two network namespaces with a veth pair between them, addresses only inside
them (10.200.0.1/24 and 10.200.0.2/24: unreachable from the test's own namespace), runs
``simula --zenoh`` in the first, listening on its namespace address, and an RCCL program in
the second that connects over the veth, moves the waist and releases the arm. Everything
is removed in a ``finally``. Making namespaces needs root (CAP_NET_ADMIN): the suite runs
as root (``.ci/run`` on a clean clone, the same user as a developer here); without it the
test fails saying so.
"""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import textwrap
import time
import uuid

import numpy as np
import pytest

from rci.simula.process import ToolProcess

ADDR_A, ADDR_B = "10.200.0.1", "10.200.0.2"
PORT = 7447

PROGRAM = textwrap.dedent("""
    import json, sys, time
    import numpy as np
    import rccl
    from rccl.position import joint_position
    # generous lateness and timeout: the link is under test here, not its timing on a loaded machine
    with rccl.open(sys.argv[1], "puma260", rate_hz=36, signals=False, lock_memory=False, timeout=0.5,
                   late_limit=50) as arm:
        before = arm.measured_q()
        q = arm.q.copy()
        q[0] += 0.2
        turned = joint_position("turned", arm.kinematics, q)
        arm.move(turned)
        arm.waitfor(turned.end)
        time.sleep(0.5)                    # the servo settles on the target
        after = arm.measured_q()
    print(json.dumps({"before": before.tolist(), "after": after.tolist(), "target": q.tolist()}))
""")


def _ip(*args: str) -> None:
    out = subprocess.run(["ip", *args], capture_output=True, text=True)
    if out.returncode != 0:
        raise RuntimeError(f"ip {' '.join(args)}: {out.stderr.strip()}")


def _namespaces(tag: str) -> tuple[str, str]:
    """Two namespaces joined by a veth pair, addresses only inside them; their names."""
    ns_a, ns_b = f"rcci-{tag}-a", f"rcci-{tag}-b"
    veth_a, veth_b = f"vr{tag[:6]}a", f"vr{tag[:6]}b"
    try:
        _ip("netns", "add", ns_a)
    except RuntimeError as exc:
        pytest.fail(f"cannot make a network namespace (this test needs root, CAP_NET_ADMIN, as the suite has "
                    f"on CI and here): {exc}")
    try:
        _ip("netns", "add", ns_b)
        _ip("link", "add", veth_a, "type", "veth", "peer", "name", veth_b)
        _ip("link", "set", veth_a, "netns", ns_a)
        _ip("link", "set", veth_b, "netns", ns_b)
        for ns, dev, addr in ((ns_a, veth_a, ADDR_A), (ns_b, veth_b, ADDR_B)):
            _ip("-n", ns, "addr", "add", f"{addr}/24", "dev", dev)
            _ip("-n", ns, "link", "set", dev, "up")
            _ip("-n", ns, "link", "set", "lo", "up")
    except RuntimeError:             # nothing left behind: the caller only learns of a complete pair
        subprocess.run(["ip", "link", "del", veth_a], capture_output=True)
        _remove(ns_a, ns_b)
        raise
    return ns_a, ns_b


def _remove(*namespaces: str) -> None:
    for ns in namespaces:          # deleting a namespace deletes its end of the veth, and so the pair
        subprocess.run(["ip", "netns", "del", ns], capture_output=True)


def _remove_all(tag: str, made: list[str]) -> None:
    """Remove the namespaces ``made`` and check that none tagged ``tag`` is left."""
    _remove(*made)
    left = subprocess.run(["ip", "netns", "list"], capture_output=True, text=True).stdout
    assert tag not in left, f"namespaces left behind: {left}"


def test_an_rccl_program_in_one_namespace_drives_simula_in_another_over_the_veth():
    tag = uuid.uuid4().hex[:6]
    made: list[str] = []
    sim = None
    try:
        made += _namespaces(tag)
        ns_a, ns_b = made
        # the addresses and the veth ends exist only inside the namespaces, none in the test's own
        here = subprocess.run(["ip", "-o", "addr"], capture_output=True, text=True, check=True).stdout
        assert "10.200.0." not in here and f"vr{tag}" not in here
        inside = subprocess.run(["ip", "-n", ns_b, "-o", "addr"], capture_output=True, text=True, check=True).stdout
        assert f"{ADDR_B}/24" in inside
        sim = ToolProcess(["ip", "netns", "exec", ns_a, sys.executable, "-m", "rci.simula", "--robot", "puma260",
                           "-p", "--power-on", "-v", "--watchdog-time", "0.5", "--zenoh", "lab/puma",
                           "--zenoh-listen", f"tcp/{ADDR_A}:{PORT}", "--port", "0"]).start()
        assert sim.url == f"zenoh/lab/puma?connect=tcp/{ADDR_A}:{PORT}"
        out = subprocess.run(["ip", "netns", "exec", ns_b, sys.executable, "-c", PROGRAM, sim.url],
                             capture_output=True, text=True, timeout=60, cwd=os.getcwd())
        assert out.returncode == 0, out.stderr[-2000:]
        moved = json.loads(out.stdout.strip().splitlines()[-1])
        before, after, target = (np.array(moved[k]) for k in ("before", "after", "target"))
        assert abs(after[0] - before[0] - 0.2) < 2e-3 and abs(after[0] - target[0]) < 2e-3
        # simula's own report (-v: joint angles once per simulated second) shows the waist turned
        deadline = time.monotonic() + 3.0
        while time.monotonic() < deadline:
            waists = [np.radians(float(m.group(1))) for line in list(sim.lines)
                      if (m := re.search(r"q\(deg\) =\s*([-+0-9.eE]+)", line))]
            if waists and abs(waists[-1] - target[0]) < 5e-3:
                break
            time.sleep(0.2)
        assert waists and abs(waists[-1] - target[0]) < 5e-3, sim.lines[-5:]
    finally:
        if sim is not None:
            sim.stop()
        _remove_all(tag, made)
