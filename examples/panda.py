"""RCCL on the Franka Emika Panda (7 joints, models/panda.toml): a joint-mode program you can copy.

    .venv/bin/python examples/panda.py                          # starts its own simula --robot panda
    .venv/bin/python examples/panda.py socket://127.0.0.1:7600  # a running `simula --robot panda -p --power-on`

The arm goes from its ready pose (Franka's (0, -45, 0, -135, 0, 90, 45) deg) through joint
targets and back. Each target is seven joint angles in degrees: copy a line of TARGETS and
change its numbers (the ranges are Franka's, in models/panda.toml; a target outside them is
refused before the arm moves). The program prints where the encoders say each joint ended
and where the flange (T7) is. Cartesian targets need the Panda's inverse kinematics, whose
closed-form solver (one joint free) is not derived yet: RCCL refuses such a move with an
error naming it.
"""
from __future__ import annotations

import math
import sys

import numpy as np

import rccl
from rccl.position import joint_position

ROBOT = "panda"
# name: joint angles, degrees
TARGETS = {
    "reach_left": (30.0, -30.0, -20.0, -110.0, 30.0, 70.0, 85.0),
    "reach_right": (-40.0, -55.0, 25.0, -155.0, -35.0, 115.0, -15.0),
    "ready": (0.0, -45.0, 0.0, -135.0, 0.0, 90.0, 45.0),
}


def run(url: str, **rci_options) -> dict[str, tuple[float, np.ndarray]]:
    """Visit the targets on the arm at ``url``; returns for each its largest joint error (rad)
    and the joint values (rad) the encoders say. ``rci_options`` go to the RCI session."""
    out = {}
    with rccl.open(url, robot=ROBOT, rate_hz=36, on_error="raise", **rci_options) as arm:
        arm.setmod("joint")
        arm.setvel(0.2, math.radians(60))                  # m/s, rad/s
        for name, degrees in TARGETS.items():
            goal = np.radians(degrees)
            pos = joint_position(name, arm.kinematics, goal)
            arm.move(pos)
            arm.waitfor(pos.end)
            arm.rci.wait(0.3)                              # let the servos settle
            q = arm.measured_q()
            out[name] = (float(np.abs(q - goal).max()), q)
            flange = arm.kinematics.fk(q)[:3, 3]
            print(f"{name}: joints {np.round(np.degrees(q), 2).tolist()} deg "
                  f"({math.degrees(out[name][0]):.3f} deg from the target), "
                  f"T7 at ({', '.join(f'{v:.4f}' for v in flange)}) m")
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
