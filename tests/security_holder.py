"""The planning level of a secured workcell, for tests/test_security_arm_netns.py: ``python tests/security_holder.py ...``.

    python tests/security_holder.py SIMULA_URL CELL HUB_ENDPOINT HUB_CONFIG ARM_CONFIG

Runs in the workcell's network namespace: the bus's hub (this process, ``rci.bus.Bus`` with
the hub's configuration: mutual TLS, the workcell's access control) and one arm process
(``python -m rccl.bus.arm puma``, with its own identity) driving simula over a socket. It
takes the arm (a first motion), queues a second one held (waiting for its start flag),
writes the shared value it owns, and prints one JSON line (its planner id, the serials);
then, on a line on stdin (in the middle of a flood of requests), it stops the held motion,
moves the arm back and prints a JSON line (when); on another line (the attacks are over), it
waits for the arm process's report of the flood, releases the arm and prints a last JSON
line: what it saw, and every line the arm process printed meanwhile (its reports).
"""
from __future__ import annotations

import json
import os
import sys
import threading
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from rccl.bus import arm as bus_arm  # noqa: E402
from rccl.bus.planning import BusEvents  # noqa: E402
from rccl.events import DONE  # noqa: E402
from rccl.position import joint_position  # noqa: E402
from rci.bus import Bus  # noqa: E402

RATE_HZ = 50


def _waist(arm, delta: float, name: str):
    q = arm.q.copy()
    q[0] += delta
    return joint_position(name, arm.kinematics, q)


def main(sim_url: str, cell: str, hub: str, hub_config: str, arm_config: str) -> int:
    lines: list[str] = []
    with Bus(cell, tasks=("planning",), listen=(hub,), config=hub_config) as bus:
        # generous lateness (25 cycles) and HOW timeout for a loaded test machine: the attacks are under test
        proc = bus_arm.spawn("puma", sim_url, "puma260", cell, (hub,), RATE_HZ, how_timeout=0.25,
                             extra=("--late-limit", "25", "--zenoh-config", arm_config))
        reader = threading.Thread(target=lambda: lines.extend(x.decode(errors="replace").rstrip()
                                                              for x in iter(proc.stdout.readline, b"")), daemon=True)
        reader.start()
        ev = BusEvents(bus)
        puma = ev.arm("puma", timeout=10.0)
        a = ev.move_ev(puma, _waist(puma, 0.05, "first"))             # the first request that moves takes the arm
        first = ev.wait_ev(a, timeout=10.0)
        held = ev.move_ev(puma, _waist(puma, 0.3, "held back"), start=None)   # waits for its start flag
        bus.shared["plan"] = 1
        print(json.dumps({"planner": ev.id, "first": first, "held": held.serial}), flush=True)
        sys.stdin.readline()                                          # the attacks are on: drive the arm
        out: dict = {"plan": bus.shared.get("plan"), "held_flags": ev.flags("puma", held.serial)}
        t0 = time.monotonic()
        ev.stop_ev(-5, held)
        back = ev.move_ev(puma, _waist(puma, -0.05, "back"))
        during = {"back": ev.wait_ev(back, timeout=10.0), "t_asked": t0, "t_done": time.monotonic()}
        print(json.dumps(during), flush=True)
        sys.stdin.readline()                                          # the attacks are over: release the arm
        deadline = time.monotonic() + 10.0                            # once the arm process reported the flood
        while not any("a flood of requests" in x for x in lines) and time.monotonic() < deadline:
            time.sleep(0.1)
        puma.close()                                                  # the arm process releases the arm and ends
        out["arm_exit"] = proc.wait(15)
        ev.close()
        reader.join(5)
        out["lines"] = lines
        out["back"] = during["back"]
    print(json.dumps(out), flush=True)
    return 0 if out["back"] == DONE else 1


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:]))
