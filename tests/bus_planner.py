"""A planning process for tests/test_zenoh_flag_faults.py, to be killed or stopped mid-plan.

    python tests/bus_planner.py CELL ENDPOINT ARM DELTA [--connect] [--silence S]

It is the bus's hub (listens on ENDPOINT, as in examples/two_arm_flags.py --bus; with
``--connect``, a client of the hub there), prints ``listening`` (``connected``), waits for
the arm process serving ARM, queues a motion of its waist by DELTA rad and a held motion
behind it, prints ``moving A B ID`` (their serials, its planning level's id) once the first
has begun, and waits for it: the test kills or stops it there. Stopped (SIGSTOP) and
continued, it finds itself given up: it prints ``given up: PlannerLost: ...`` (what
``wait_ev`` raised) and ``refused: ...`` (what a request to the arm raised after it) and
ends with status 0. ``--silence S``: its BusEvents' silence (the arm gives it up after S s
without a heartbeat of it; default rccl.bus.planning.SILENCE_S).
"""
from __future__ import annotations

import sys

from rccl.bus.planning import SILENCE_S, BusEvents, PlannerLost
from rccl.position import joint_position
from rci.bus import Bus


def main(cell: str, endpoint: str, arm_name: str, delta: float, connect: bool = False,
         silence: float = SILENCE_S) -> int:
    where = {"connect": (endpoint,)} if connect else {"listen": (endpoint,)}
    with Bus(cell, tasks=("planning",), **where) as bus:
        print("connected" if connect else "listening", flush=True)
        ev = BusEvents(bus, silence=silence)
        arm = ev.arm(arm_name, timeout=60.0)
        q0 = arm.q
        q1 = q0.copy()
        q1[0] += delta
        a = ev.move_ev(arm, joint_position("long_way", arm.kinematics, q1))
        b = ev.move_ev(arm, joint_position("back", arm.kinematics, q0), start=None)     # held
        ev.wait_ev(a, started=True, timeout=10.0)
        print(f"moving {a.serial} {b.serial} {ev.id}", flush=True)
        try:
            ev.wait_ev(a, timeout=60.0)
        except PlannerLost as exc:
            print(f"given up: {type(exc).__name__}: {exc}", flush=True)
            try:
                arm.q
            except PlannerLost as again:
                print(f"refused: {type(again).__name__}: {again}", flush=True)
            ev.close()
            return 0
        print("not killed", flush=True)
    return 1


if __name__ == "__main__":
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("cell")
    ap.add_argument("endpoint")
    ap.add_argument("arm")
    ap.add_argument("delta", type=float)
    ap.add_argument("--connect", action="store_true")
    ap.add_argument("--silence", type=float, default=SILENCE_S)
    a = ap.parse_args()
    sys.exit(main(a.cell, a.endpoint, a.arm, a.delta, connect=a.connect, silence=a.silence))
