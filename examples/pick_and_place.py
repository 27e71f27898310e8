"""A pick and place program in RCCL (thesis Table 2.1's "RCCL pick and place program").

    .venv/bin/python examples/pick_and_place.py                  # starts its own simula (lockstep)
    .venv/bin/python examples/pick_and_place.py socket://127.0.0.1:7600   # a running simula -p --power-on
    .venv/bin/python examples/pick_and_place.py --parts 1         # one part only

Parts lie at a feeder; the arm takes ``PARTS`` of them, one by one, to places in a row.
Each part: a joint-mode move to the approach point above the feeder, a straight
(Cartesian) descent, a stop while the gripper closes, a straight lift, a joint-mode move
above its place, a straight descent, a stop while the gripper opens, a straight lift.
Then the arm goes back to park.

The stations are offsets (metres, base frame) from the hand's pose where the program
starts, with that pose's orientation; the approach points are ``CLEARANCE`` above them.
simula has no gripper, so the stops (``stop(GRIP_S)``, RCCL's dwell) stand for its
closing and opening time: the motion requests are those a real program would send.
"""
from __future__ import annotations

import math
import sys

import numpy as np

import rccl
from rccl import EQ, T6, TL, Trsf, makeposition

PARTS = 3
FEEDER = (0.04, 0.06, -0.06)                 # m from the start pose, base frame
PLACES = tuple((-0.04, 0.06 - 0.04 * k, -0.06) for k in range(PARTS))
CLEARANCE = 0.04                             # m: approach points above the stations
GRIP_S = 0.3                                 # s: the gripper's close/open time


def station(name: str, x0: np.ndarray, offset, up: float = 0.0):
    """The position ``T6 = x0`` moved by ``offset`` (m, base frame) and ``up`` m along base z."""
    x = x0.copy()
    x[:3, 3] += np.asarray(offset, float) + [0.0, 0.0, up]
    return makeposition(name, T6, EQ, Trsf(name, x), TL, T6)


def main(url: str, record: bool = False, parts: int = PARTS):
    """Run the program on the powered arm at ``url``; returns the (closed) Arm and the parts placed."""
    with rccl.open(url, robot="puma260", record=record, timeout=2.0) as arm:
        x0 = arm.t6
        pick, pick_above = station("PICK", x0, FEEDER), station("PICK_UP", x0, FEEDER, CLEARANCE)
        placed = 0
        for k, where in enumerate(PLACES[:parts]):
            place = station(f"PLACE{k}", x0, where)
            place_above = station(f"PLACE{k}_UP", x0, where, CLEARANCE)
            for above, at in ((pick_above, pick), (place_above, place)):
                arm.setmod("joint")
                arm.setvel(0.10, math.radians(60.0))
                arm.move(above)
                arm.setmod("cartesian")
                arm.setvel(0.03, math.radians(20.0))
                arm.move(at)
                arm.stop(GRIP_S)                  # the gripper closes (at the feeder) or opens
                arm.move(above)
            arm.waitfor(place_above.end)
            placed += 1
        arm.setmod("joint")
        arm.setvel(0.10, math.radians(60.0))
        arm.move(arm.park)
        arm.waitfor(arm.park.end)
    return arm, placed


def _cli(argv: list[str]) -> int:
    import argparse
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("url", nargs="?", default=None,
                    help="robot link of a powered arm (e.g. socket://127.0.0.1:7600 of `simula -p --power-on`); "
                         "default: start a lockstep simula for the run")
    ap.add_argument("--parts", type=int, default=PARTS, choices=range(1, PARTS + 1), help="how many parts to move")
    a = ap.parse_args(argv)
    if a.url:
        arm, placed = main(a.url, parts=a.parts)
    else:
        from rci.simula.process import SimulaProcess
        with SimulaProcess("-p", "--power-on", lockstep=True) as sim:
            arm, placed = main(sim.url, parts=a.parts)
    print(f"{placed} parts placed; final joint angles (deg):",
          [round(math.degrees(float(x)), 2) for x in arm.measured_q()])
    return 0 if placed == a.parts else 1


if __name__ == "__main__":
    sys.exit(_cli(sys.argv[1:]))
