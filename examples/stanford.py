"""RCCL on the Stanford arm (an arm added by its data file alone, models/stanford.toml): Cartesian moves to targets you can copy.

    .venv/bin/python examples/stanford.py                          # starts its own simula --robot stanford
    .venv/bin/python examples/stanford.py socket://127.0.0.1:7600  # a running `simula --robot stanford -p --power-on`

Joint 3 is a prismatic boom (0.3048-1.27 m): on the line from P1 to P2, which runs along the
boom, it slides out; P3 turns the arm about its base.

The arm goes from park to P1 (a joint move), along straight lines to P2 and P3 turning the
tool about its axis on the way (Cartesian moves), and back to park. Every target is T6 (link
6 in the base frame, metres) with the tool pointing down: copy a line
of TARGETS and change its numbers. Each move is checked before the arm moves
(``rccl.UnreachableTarget`` names the joint and its range when a target or a point of the
line is out of reach); the program prints where the encoders say T6 ended, and how far from
the target.
"""
from __future__ import annotations

import math
import sys

import numpy as np

import rccl
from rccl import EQ, T6, TL, Trsf, makeposition

ROBOT = "stanford"
# name: (x, y, z) m in the base frame, turn of the tool about its own (vertical) axis, rad
TARGETS = {
    "P1": ((0.55, 0.154, 0.30), 0.0),
    "P2": ((0.75, 0.154, 0.30), 0.0),
    "P3": ((0.70, 0.35, 0.35), 0.5),
}


def tool_down(x: float, y: float, z: float, turn: float = 0.0) -> np.ndarray:
    """T6 at (x, y, z) m with the tool (T6's z axis) pointing down, turned by ``turn`` rad about it."""
    c, s = math.cos(turn), math.sin(turn)
    T = np.eye(4)
    T[:3, :3] = np.array([[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]]) @ np.array(
        [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    T[:3, 3] = x, y, z
    return T


def run(url: str, **rci_options) -> dict[str, tuple[float, np.ndarray]]:
    """Visit the targets on the arm at ``url``; returns for each its end error (m) and joint values
    (rad, m), both as the encoders say. ``rci_options`` go to the RCI session (e.g. ``timeout``, s)."""
    errors = {}
    with rccl.open(url, robot=ROBOT, rate_hz=36, on_error="raise", **rci_options) as arm:
        arm.setvel(0.10, math.radians(45))                 # m/s, rad/s
        for k, (name, (p, turn)) in enumerate(TARGETS.items()):
            arm.setmod("joint" if k == 0 else "cartesian")  # straight lines between the targets
            goal = tool_down(*p, turn)
            pos = makeposition(name, T6, EQ, Trsf(name, goal), TL, T6)
            arm.move(pos)
            arm.waitfor(pos.end)
            arm.rci.wait(0.2)                              # let the servos settle
            q = arm.measured_q()
            reached = arm.kinematics.fk(q)
            errors[name] = (float(np.linalg.norm(reached[:3, 3] - goal[:3, 3])), q)
            print(f"{name}: T6 at ({', '.join(f'{v:.4f}' for v in reached[:3, 3])}) m, "
                  f"{1e3 * errors[name][0]:.2f} mm from the target")
        arm.setmod("joint")
        arm.move(arm.park)
        arm.waitfor(arm.park.end)
    return errors


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
