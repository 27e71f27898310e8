"""The live 3D view: an RCCL program traces a square above a table while the browser shows its plan.

    .venv/bin/python examples/view_demo.py          # starts its own simula (real time); open the printed address
    .venv/bin/python examples/view_demo.py socket://127.0.0.1:7600 --env box:...   # a running simula -p --power-on
    .venv/bin/python examples/view_demo.py --screenshot docs/viewer.png   # the picture in docs/viewer.md

The arm goes to the first corner in joint mode, then round the square in Cartesian mode
with its gripper tip 2 cm above a table (simula's ``--env box:...``, so the surface is
real to the simulator too), pausing at the second corner, and back to park.
``rcci.view.plan.show(arm)`` draws the arm as the robot reports it, each request's planned
path (grey done, magenta running, blue queued), the target frame and the table.

With ``--screenshot PNG`` the picture is taken during the pause (headless Chromium,
``rcci.view.screenshot``) and written to PNG; the program then finishes the square.
"""
from __future__ import annotations

import argparse
import math
import sys
import time
import warnings

import rccl
import rcci.view.plan
from rccl import EQ, T6, TL, gentr_rot, gentr_trsl, makeposition, yunit

# the table: a block beside the arm whose top is 0.15 m below the shoulder (the base frame's origin)
TABLE = "box:x0=0.16,x1=0.36,y0=-0.25,y1=0.08,z0=-0.395,z1=-0.15"
TIP = 0.18                     # m, the gripper's tip beyond link 6 (models/urdf/puma260.urdf: its box ends there)
HEIGHT = -0.13                 # m, the tip's height: 2 cm above the table
CORNERS = [(0.30, -0.18), (0.30, 0.02), (0.20, 0.02), (0.20, -0.18)]


def square():
    """The four corners as positions T6 TIP = C DOWN (the tip at the corner, pointing down), and the tool."""
    tip = gentr_trsl("TIP", 0.0, 0.0, TIP)
    down = gentr_rot("DOWN", 0.0, 0.0, 0.0, yunit, math.pi)
    return [makeposition(f"P{i + 1}", T6, tip, EQ, gentr_trsl(f"C{i + 1}", x, y, HEIGHT), down, TL, tip)
            for i, (x, y) in enumerate(CORNERS)]


def run(url: str, env: list[str], *, port: int, pause: float, delay: float, screenshot: str | None) -> None:
    p1, p2, p3, p4 = square()
    # overrun="count": a cycle made late by a busy machine (a browser drawing in software beside the
    # real-time simula) holds the arm one period; the demo counts it instead of ending the control
    with rccl.open(url, robot="puma260", timeout=2.0, overrun="count") as arm:
        view = rcci.view.plan.show(arm, env=env, port=port, quiet=True)
        print(f"view {view.url}", flush=True)
        if delay > 0 and not screenshot:
            print(f"the arm starts in {delay:.0f} s: open the address in a browser", flush=True)
            time.sleep(delay)
        arm.setvel(0.08, math.radians(60.0))
        arm.move(p1)                              # joint mode (the default) to the first corner
        arm.setmod("c")
        corner = arm.move(p2)
        arm.stop(pause)                           # stay at the second corner
        for p in (p3, p4, p1):
            arm.move(p)
        arm.setmod("j")
        arm.move(arm.park)
        if screenshot:
            from rcci.view.screenshot import screenshot as take

            arm.waitfor(corner)
            arm.rci.wait(0.3)
            take(view.url, screenshot, size=(1200, 800))
            print(f"wrote {screenshot}", flush=True)
        arm.waitfor(arm.park.end)
        view.close()


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("url", nargs="?", default=None,
                    help="robot link of a powered arm (e.g. socket://127.0.0.1:7600 of `simula -p --power-on "
                         f"--env {TABLE}`); default: start a real-time simula with the table")
    ap.add_argument("--env", action="append", default=None, metavar="SPEC",
                    help=f"surfaces to draw (simula's --env words; default the table {TABLE})")
    ap.add_argument("--port", type=int, default=8080, help="the view's HTTP port (default 8080; 0: any free one)")
    ap.add_argument("--pause", type=float, default=None,
                    help="seconds at the second corner (default 2; 15 with --screenshot)")
    ap.add_argument("--delay", type=float, default=5.0,
                    help="seconds to open the browser before the arm moves (default 5; none with --screenshot)")
    ap.add_argument("--screenshot", metavar="PNG", help="write a picture of the view during the pause (headless Chromium)")
    a = ap.parse_args(argv)
    env = a.env if a.env is not None else [TABLE]
    pause = a.pause if a.pause is not None else (15.0 if a.screenshot else 2.0)
    if a.url:
        run(a.url, env, port=a.port, pause=pause, delay=a.delay, screenshot=a.screenshot)
        return 0
    from rci.simula.process import SimulaProcess
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        # --watchdog-time 0.5: like overrun="count" in run(), room for a machine busy drawing in software
        with SimulaProcess("-p", "--power-on", "--watchdog-time", "0.5", *[f"--env={e}" for e in env],
                           lockstep=False) as sim:
            run(sim.url, env, port=a.port, pause=pause, delay=a.delay, screenshot=a.screenshot)
    return 0


if __name__ == "__main__":
    sys.exit(main())
