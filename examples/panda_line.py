"""RCCL on a redundant arm, the Franka Emika Panda (7 joints): straight lines with a rule for the free joint q7, and a self-motion.

    .venv/bin/python examples/panda_line.py                          # starts its own simula --robot panda
    .venv/bin/python examples/panda_line.py socket://127.0.0.1:7600  # a running `simula --robot panda -p --power-on`

A 6-joint arm's pose fixes its joints; the Panda keeps one joint free. RCCL asks the program
for a rule for it, as setconf is for a configuration (docs/redundancy.md):

1. a straight line 10 cm out with the default rule: q7 holds the value it has;
2. a self-motion: q7 turns 0.4 rad back while the flange stands still (the elbow swings);
3. the line back with ``setfree("far")``: each sample q7 moves (at most 0.02 rad) the way
   that keeps the joints away from their limits and from singularities;
4. a line sideways with q7 a function of time (seconds from the motion's start).

After each motion the program prints where the encoders say the flange (T6, base frame, m)
is and the value of q7; each motion is checked before the arm moves (a line or a
self-motion that would leave a joint range is refused naming the joint and where).
"""
from __future__ import annotations

import math
import sys

import numpy as np

import rccl
from rccl import EQ, T6, TL, Trsf, makeposition

ROBOT = "panda"
OUT = np.array([0.10, 0.0, -0.05])      # m: the first line, from the ready pose (base frame)
SIDEWAYS = np.array([0.0, 0.08, 0.0])   # m: the last line
SELF_TURN = -0.4                        # rad: the self-motion's change of q7


def report(arm, name: str) -> tuple[np.ndarray, float]:
    """Print where the encoders say T6 is and q7; return (T6's point, m; q7, rad)."""
    arm.rci.wait(0.2)                   # let the servos settle
    q = arm.measured_q()
    p = arm.kinematics.fk(q)[:3, 3]
    print(f"{name}: T6 at ({', '.join(f'{v:.4f}' for v in p)}) m, q7 = {q[6]:.4f} rad")
    return p, float(q[6])


def line(arm, name: str, goal: np.ndarray):
    pos = makeposition(name, T6, EQ, Trsf(name, goal), TL, T6)
    arm.move(pos)
    arm.waitfor(pos.end)


def run(url: str, **rci_options) -> dict[str, tuple[np.ndarray, float]]:
    """The program on the Panda at ``url``; returns for each stop T6's point (m) and q7 (rad) as the
    encoders say. ``rci_options`` go to the RCI session (e.g. ``timeout``, s)."""
    out = {}
    with rccl.open(url, robot=ROBOT, rate_hz=36, on_error="raise", **rci_options) as arm:
        t0 = arm.t6.copy()
        arm.setmod("cartesian")
        arm.setvel(0.05, 0.3)                       # m/s, rad/s
        a = t0.copy()
        a[:3, 3] += OUT
        line(arm, "OUT", a)                         # 1. q7 held (the default)
        out["OUT"] = report(arm, "OUT")
        req = arm.selfmove(q7=arm.q[6] + SELF_TURN, duration=2.0)   # 2. the elbow swings, the flange stays
        arm.waitfor(req)
        out["SELF"] = report(arm, "SELF")
        arm.setfree("far")                          # 3. q7 away from limits and singularities
        line(arm, "BACK", t0)
        out["BACK"] = report(arm, "BACK")
        q7_start = float(arm.q[6])
        arm.setfree(q7=lambda t: q7_start + 0.15 * math.sin(t))    # 4. q7 a function of time
        b = t0.copy()
        b[:3, 3] += SIDEWAYS
        line(arm, "SIDE", b)
        out["SIDE"] = report(arm, "SIDE")
        arm.setfree()                               # back to the default
    return out


def main(argv: list[str]) -> int:
    import argparse
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("url", nargs="?", help=f"robot link of a powered {ROBOT} (default: start a lockstep simula)")
    args = ap.parse_args(argv)
    if args.url:
        run(args.url)
        return 0
    from rci.simula.process import SimulaProcess
    with SimulaProcess("-p", "--power-on", robot=ROBOT, lockstep=True) as sim:
        run(sim.url, timeout=2.0)     # a lockstep simula's cycles are not wall-clock time: a busy machine may pause it
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
