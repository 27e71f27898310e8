"""A guarded move (thesis 5.4.1): go down onto a table in Cartesian mode and stop on contact.

    .venv/bin/python examples/adaptive_guarded_move.py          # starts its own simula with a table

The arm starts at ``ready`` with a 5 cm probe along z6 (pointing down). A table top lies
at z = 0.12 m. The program moves the probe down towards z = 0.08 m (4 cm into the table)
at 1 cm/s with ``limit("fz", 8.0)``: the motion ends when the force the probe exerts along
its own z axis, estimated from the motor currents (4.37) through the inverse Jacobian
(4.56), passes 8 N. The next request (a move back up) then runs at once.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import rccl.adaptive                                  # noqa: E402
from rccl import EQ, T6, TL, Trsf, makeposition       # noqa: E402
from rccl.transform import trsl                       # noqa: E402

TABLE_Z = 0.12
PROBE = 0.05
LIMIT_N = 8.0
ENV = (f"plane:z={TABLE_Z}", f"tool:z={PROBE}")


def main(url: str):
    """Run the guarded move at ``url``; returns (arm, the down request, the up request)."""
    with rccl.adaptive.open(url, robot="puma260", record=True, timeout=2.0) as arm:
        tool = Trsf("PROBE", trsl(0.0, 0.0, PROBE))
        x0 = arm.t6 @ tool.matrix                         # the probe frame at ready (a = -z base)
        down = Trsf("DOWN", trsl(*(x0[:3, 3] - [0, 0, 0.0732])) @ np.block([[x0[:3, :3], np.zeros((3, 1))], [0, 0, 0, 1]]))
        up = Trsf("UP", x0)
        p_down = makeposition("P_DOWN", T6, tool, EQ, down, TL, tool)
        p_up = makeposition("P_UP", T6, tool, EQ, up, TL, tool)
        arm.setmod("cartesian")
        arm.setvel(0.01, math.radians(10.0))
        arm.limit("fz", LIMIT_N)
        r_down = arm.move(p_down)
        arm.setvel(0.03, math.radians(20.0))
        r_up = arm.move(p_up)
        arm.waitfor(r_up)
    return arm, r_down, r_up


def _cli(argv: list[str]) -> int:
    from adaptive_sim import example_args, run_main

    args = example_args(__doc__, argv, plot=False)

    arm, r_down, _ = run_main(main, args.url, *ENV)
    end = r_down.ended
    print("down motion:", "completed (no contact?)" if end is None else f"ended by {end}")
    return 0 if end is not None else 1


if __name__ == "__main__":
    sys.exit(_cli(sys.argv[1:]))
