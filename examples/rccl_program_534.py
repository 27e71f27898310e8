"""The RCCL program of thesis 5.3.4, line for line in Python, run against simula.

    .venv/bin/python examples/rccl_program_534.py                 # starts its own simula (lockstep)
    .venv/bin/python examples/rccl_program_534.py socket://127.0.0.1:7600   # a running simula -p --power-on

The robot moves to p0 and back to park, continuously (it does not stop at p0). With
``--plot`` it writes ``reports/rccl-path.png`` from the joint angles simula reported.

Differences from the C listing, and why: SI units (the listing's 250, 250, 328.9 mm and
100 mm/s, 100 deg/s); and t is scaled by 0.6 to (150, 150, 197.3) mm, because T6 = T^-1 B
with the listing's numbers lies 0.48 m from the shoulder, beyond the PUMA 260's 0.425 m
reach (docs/rccl.md, "Thesis print vs derivation").
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import rccl                                                   # 1  #include <robot/rccl.h>
from rccl import EQ, T6, TL, gentr_rot, gentr_trsl, makeposition, yunit

SCALE = 0.6  # see the module docstring: the listing's t is out of the PUMA 260's reach


def main(url: str, record: bool = False):                      # 3  main()
    """Run the program on the robot at ``url``; returns the (closed) Arm, with its trace if ``record``."""
    global P0_T6                                               # 5-6  TRSF_PTR t, r; POS_PTR p0;
    # Allocate and initialize the transforms and position equation             (8)
    t = gentr_trsl("T", SCALE * 0.250, SCALE * 0.250, SCALE * 0.3289)        # 10
    r = gentr_rot("B", 0.0, 0.0, 0.0, yunit, math.radians(180.0))            # 11
    p0 = makeposition("P0", t, T6, EQ, r, TL, T6)                            # 12
    P0_T6 = p0.solve()

    with rccl.open(url, robot="puma260", record=record,                      # 14  rccl_open(0, 0);
                   timeout=2.0) as arm:                                      # 15  rccl_control(1);
        arm.setvel(0.100, math.radians(100.0))                               # 17  setvel(100, 100);
        arm.move(p0)                                                         # 18  move(p0);
        arm.move(arm.park)                                                   # 19  move(park);
        arm.waitfor(arm.park.end)                                            # 21  waitfor(park->end);
    return arm                                                               # 22  rccl_close(1);


P0_T6 = None


def _cli(argv: list[str]) -> int:
    import argparse
    import warnings
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("url", nargs="?", default=None,
                    help="robot link of a powered arm (e.g. socket://127.0.0.1:7600 of `simula -p --power-on`); "
                         "default: start a lockstep simula for the run")
    ap.add_argument("--plot", action="store_true", help="write the path plot to reports/rccl-program-534.png")
    a = ap.parse_args(argv)
    plot = a.plot
    if a.url:
        arm = main(a.url, record=plot)
    else:
        from rci.simula.process import SimulaProcess
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            with SimulaProcess("-p", "--power-on", lockstep=True) as sim:
                arm = main(sim.url, record=plot)
    q = arm.measured_q()
    print("p0 T6 position (m):", [round(float(x), 4) for x in P0_T6[:3, 3]])
    print("final joint angles (deg):", [round(math.degrees(float(x)), 3) for x in q])
    if plot:
        from rccl.plots import path_plot
        out = path_plot(arm, [("p0", P0_T6), ("park", arm.park.solve())], title="thesis 5.3.4: move(p0); "
                        "move(park) (simula, 36 Hz)", out=Path(__file__).resolve().parent.parent / "reports"
                        / "rccl-program-534.png")
        print("wrote", out)
    return 0


if __name__ == "__main__":
    sys.exit(_cli(sys.argv[1:]))
