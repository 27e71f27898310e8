"""Circle tracing with a functionally defined transform (thesis 5.4.4, Figure 5.3 (a) and (b)).

    .venv/bin/python examples/adaptive_circle.py [--plot]      # starts its own simula

The program of 5.3.4 (p0 from t T6 = B), but with t placing p0 at (0.20, -0.12, 0.17) m,
in front of the arm near ``ready``, where a Cartesian approach keeps every joint inside
its range and away from the wrist singularity (at the listing's position, scaled as in
examples/rccl_program_534.py, the waist has turned 225 degrees and joint 6 runs out of
range along the approach), with its transform ``t`` bound to ``trace_circle``, which moves t's x and y on a circle at one
degree per trajectory sample. The robot goes (joint mode) to a point A 8 cm from p0, then
moves in Cartesian mode at 5 mm/s to p0, which follows the circle: a circle superimposed
on the straight path, Figure 5.3 (a); then it
"stops" at p0 for 12 s and the trajectory is the circle itself, Figure 5.3 (b); then the
binding is removed (``t.bind(None)``: const again) and the robot returns to park.

The thesis's listing sets p.x = sin(angle), p.y = cos(angle) in RCCL's millimetres, which
would throw the target to the base axis; the centre and the radius were lost in print.
We keep t's own x, y as the centre and take a radius of 2 cm (an ``estimate`` that makes
the figure readable on a 0.4 m arm). ``--plot`` writes reports/adaptive-circle.png.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import rccl.adaptive                                             # noqa: E402
from rccl import EQ, T6, TL, Trsf, gentr_rot, gentr_trsl, makeposition, yunit  # noqa: E402

RADIUS = 0.02            # m, estimate (see the module docstring)
STOP_S = 12.0
APPROACH_M = 0.08        # m: the Cartesian approach to p0 starts this far off along x
APPROACH_SPEED = 0.005   # m/s: 16 s for the approach, about 1.6 turns of the circle
REPORT = Path(__file__).resolve().parent.parent / "reports" / "adaptive-circle.png"


class TraceCircle:
    """The thesis's trace_circle: one degree per call, about the transform's initial x, y."""

    def __init__(self, centre_xy) -> None:
        self.centre = np.array(centre_xy, dtype=float)
        self.time = 0                    # sample counter, as the C listing's static time
        self.calls = 0

    def __call__(self, transform) -> None:
        angle = 2.0 * math.pi * self.time / 360.0
        p = transform.p
        p[0] = self.centre[0] + RADIUS * math.sin(angle)
        p[1] = self.centre[1] + RADIUS * math.cos(angle)
        transform.p = p
        self.time += 1
        self.calls += 1


def main(url: str):
    """Run the program; returns (arm, trace_circle, p0 request, stop request, park request)."""
    t = gentr_trsl("T", -0.20, 0.12, -0.17, kind="variable")
    r = gentr_rot("B", 0.0, 0.0, 0.0, yunit, math.radians(180.0))
    p0 = makeposition("P0", t, T6, EQ, r, TL, T6)
    trace_circle = TraceCircle(t.p[:2])
    a_t6 = p0.solve().copy()
    a_t6[0, 3] += APPROACH_M                                  # the start of the approach, 8 cm off p0 along x
    a = makeposition("A", T6, EQ, Trsf("A", a_t6), TL, T6)
    with rccl.adaptive.open(url, robot="puma260", record=True, timeout=2.0) as arm:
        arm.setmod("joint")          # as 5.3.4: from park a Cartesian line would leave joint 3's range
        arm.setvel(0.05, math.radians(30.0))
        arm.waitfor(arm.move(a))
        t.bind(trace_circle)                                  # t->fn = trace_circle;
        arm.setmod("cartesian")
        arm.setvel(APPROACH_SPEED, math.radians(10.0))
        r_p0 = arm.move(p0)
        r_stop = arm.stop(STOP_S)
        arm.waitfor(r_stop)
        t.bind(None)                                          # t->fn = const;
        arm.setmod("joint")
        r_park = arm.move(arm.park)
        arm.waitfor(arm.park.end)
    return arm, trace_circle, r_p0, r_stop, r_park


def world_xy(arm) -> tuple[np.ndarray, np.ndarray]:
    """(times, XY of link 6 in metres) from the measured joint angles, by Pinocchio on the URDF."""
    import pinocchio as pin
    from rcci.models import load_robot

    pm = pin.buildModelFromUrdf(str(load_robot("puma260").urdf_path))
    pd = pm.createData()
    fid = pm.getFrameId("link6")
    ts, xy = [], []
    for t, _, _, q, _ in arm.adaptive_trace:
        pin.framesForwardKinematics(pm, pd, q)
        ts.append(t)
        xy.append(pd.oMf[fid].translation[:2].copy())
    return np.array(ts), np.array(xy)


def plot(arm, r_p0_end_t: float, out: Path = REPORT) -> Path:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ts, xy = world_xy(arm)
    first = (ts <= r_p0_end_t) & (ts >= r_p0_end_t - APPROACH_M / APPROACH_SPEED - 0.5)
    stopped = (ts > r_p0_end_t + 1.0) & (ts <= r_p0_end_t + STOP_S - 0.5)
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.8))
    for ax, sel, title in ((axes[0], first, "(a) moving toward a point which follows a circle"),
                           (axes[1], stopped, "(b) \"stopped\" at a point which follows a circle")):
        ax.plot(1000 * xy[sel, 0], 1000 * xy[sel, 1], "-", lw=1.2, label="T6 path (measured)")
        ax.plot(1000 * xy[sel, 0][0], 1000 * xy[sel, 1][0], "o", ms=4, label="start of the path shown")
        ax.legend(fontsize=7, loc="lower left")
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("x (mm)")
        ax.set_ylabel("y (mm)")
        ax.set_title(title, fontsize=9)
        ax.grid(alpha=0.3)
    fig.suptitle("Figure 5.3: XY projection of the measured T6 path (simula, 36 Hz)\n"
                 "rebuilt by: .venv/bin/python examples/adaptive_circle.py --plot", fontsize=9)
    from adaptive_sim import save_figure

    return save_figure(fig, out)


def _cli(argv: list[str]) -> int:
    from adaptive_sim import example_args, run_main

    args = example_args(__doc__, argv, plot=True)

    arm, fn, r_p0, r_stop, _ = run_main(main, args.url)
    print(f"trace_circle called {fn.calls} times; functional changes limited in {arm.gen.functional.limited} samples")
    if args.plot:
        print("wrote", plot(arm, _end_time(arm, r_p0), args.out or REPORT))
    return 0


def _end_time(arm, req) -> float:
    """Trajectory time (s) at which ``req`` finished (recorded by the adaptive generator)."""
    return float(req.finished_t)


if __name__ == "__main__":
    sys.exit(_cli(sys.argv[1:]))
