"""A planning process for tests/test_zenoh_flag_faults.py, to be killed mid-plan.

    python tests/bus_planner.py CELL LISTEN ARM DELTA

It is the bus's hub (listens on LISTEN, as in examples/two_arm_flags.py --bus), prints
``listening``, waits for the arm process serving ARM, queues a motion of its waist by DELTA
rad and a held motion behind it, prints ``moving A B`` (their serials) once the first has
begun, and waits for it: the test kills it there.
"""
from __future__ import annotations

import sys

from rccl.bus_events import BusEvents
from rccl.position import joint_position
from rci.bus import Bus


def main(cell: str, listen: str, arm_name: str, delta: float) -> int:
    with Bus(cell, tasks=("planning",), listen=(listen,)) as bus:
        print("listening", flush=True)
        ev = BusEvents(bus)
        arm = ev.arm(arm_name, timeout=60.0)
        q0 = arm.q
        q1 = q0.copy()
        q1[0] += delta
        a = ev.move_ev(arm, joint_position("long_way", arm.kinematics, q1))
        b = ev.move_ev(arm, joint_position("back", arm.kinematics, q0), start=None)     # held
        ev.wait_ev(a, started=True, timeout=10.0)
        print(f"moving {a.serial} {b.serial}", flush=True)
        ev.wait_ev(a, timeout=60.0)
        print("not killed", flush=True)
    return 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1], sys.argv[2], sys.argv[3], float(sys.argv[4])))
