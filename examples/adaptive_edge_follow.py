"""Compliant edge-following with slip caught by a deviation limit (thesis 5.4.3).

    .venv/bin/python examples/adaptive_edge_follow.py [--plot]     # starts its own simula with a block

A block's top face lies at z = 0.12 m and ends at an edge x = 0.235 m. With a 5 cm
probe pointing down, the program

1. moves (Cartesian) to 2 mm above the face;
2. ``comply("fz", 10.0)``: along the probe's z (down) the arm now pushes 10 N, the joint
   best placed for it force-servoed in current mode, the others following the path as
   displaced by the comply transform; it settles on the face;
3. slides along +x at 1 cm/s towards a point beyond the edge, with
   ``limit("dz", 0.012)``: when the probe slips off the edge it falls, its deviation along
   the compliant axis passes 12 mm and the motion ends (5.4.3);
4. ``lock("fz")`` and moves back up.

With ``--plot`` it writes ``reports/adaptive-edge.png`` (probe height and true contact
force against time) from the joint angles simula reported.
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

FACE_Z = 0.12
EDGE_X = 0.235
PROBE = 0.05
FORCE_N = 10.0
SLIP_M = 0.012
ABOVE_M = 0.002          # the slide path runs this far above the face (the comply offset absorbs it)
ENV = (f"box:x1={EDGE_X},z1={FACE_Z}", f"tool:z={PROBE}")


def _at(x0: np.ndarray, dx: float, dz: float) -> np.ndarray:
    x = x0.copy()
    x[0, 3] += dx
    x[2, 3] += dz
    return x


def main(url: str):
    """Run the program; returns (arm, requests dict, settle interval (t0, t1) s, slide request)."""
    with rccl.adaptive.open(url, robot="puma260", record=True, timeout=2.0) as arm:
        tool = Trsf("PROBE", trsl(0.0, 0.0, PROBE))
        x0 = arm.t6 @ tool.matrix                          # probe at ready: x 0.2032, z 0.1532, pointing down
        above = Trsf("ABOVE", _at(x0, -0.02, FACE_Z + ABOVE_M - x0[2, 3]))
        beyond = Trsf("BEYOND", _at(x0, 0.06, FACE_Z + ABOVE_M - x0[2, 3]))
        home = Trsf("HOME", x0)
        pos = {n: makeposition(n, T6, tool, EQ, t, TL, tool) for n, t in
               (("ABOVE", above), ("BEYOND", beyond), ("HOME", home))}
        arm.setmod("cartesian")
        arm.setvel(0.02, math.radians(20.0))
        r_above = arm.move(pos["ABOVE"])
        arm.waitfor(r_above)
        arm.comply("fz", FORCE_N)
        r_settle = arm.stop(1.5)                           # stay 1.5 s: the probe settles on the face
        arm.waitfor(r_settle)
        t_settled = arm.gen.t
        arm.setvel(0.01, math.radians(10.0))
        arm.limit("dz", SLIP_M)
        r_slide = arm.move(pos["BEYOND"])
        arm.waitfor(r_slide)
        arm.lock("fz")
        arm.setvel(0.03, math.radians(20.0))
        r_home = arm.move(pos["HOME"])
        arm.waitfor(r_home)
    reqs = {"above": r_above, "settle": r_settle, "slide": r_slide, "home": r_home}
    return arm, reqs, t_settled


def world(arm) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(times s, probe points m (N, 3), true contact force N) from the measured joint angles (Pinocchio)."""
    import pinocchio as pin
    from rcci.models import load_robot
    from rci.simula.environment import parse_environment

    pm = pin.buildModelFromUrdf(str(load_robot("puma260").urdf_path))
    pd = pm.createData()
    env = parse_environment(list(ENV))
    t = np.array([x[0] for x in arm.adaptive_trace])
    q = np.array([x[3] for x in arm.adaptive_trace])
    p = np.array([env.tool_point(pm, pd, qi)[0] for qi in q])
    qd = np.vstack([np.zeros((1, 6)), np.diff(q, axis=0) * arm.rate_hz])
    f = np.array([env.force(pi, env.tool_point(pm, pd, qi)[1] @ qdi) for pi, qi, qdi in zip(p, q, qd)])
    return t, p, f


def plot(arm, reqs, t_settled, out: Path | None = None) -> Path:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = out or Path(__file__).resolve().parent.parent / "reports" / "adaptive-edge.png"
    t, p, f = world(arm)
    end = reqs["slide"].ended
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    a1.plot(t, 1000 * p[:, 2], label="probe z (mm)")
    a1.plot(t, 1000 * p[:, 0] - 100, label="probe x - 100 (mm)")
    a1.axhline(1000 * FACE_Z, color="k", lw=0.6, ls=":", label="face")
    a1.legend(fontsize=8)
    a1.set_ylabel("mm")
    a2.plot(t, f[:, 2], label="true contact force (N, simula's model)")
    a2.axhline(FORCE_N, color="r", lw=0.8, ls="--", label=f"comply fz {FORCE_N:g} N")
    for ax in (a1, a2):
        ax.axvline(t_settled, color="g", lw=0.6)
        if end is not None:
            ax.axvline(end.t, color="m", lw=0.6)
    a2.set_xlabel("t (s)   green: slide starts; magenta: dz limit ends the slide (slip)")
    a2.set_ylabel("N")
    a2.legend(fontsize=8)
    fig.suptitle("Compliant edge-following (5.4.3) in simula\n"
                 "rebuilt by: .venv/bin/python examples/adaptive_edge_follow.py --plot", fontsize=9)
    from adaptive_sim import save_figure

    return save_figure(fig, out)


def _cli(argv: list[str]) -> int:
    from adaptive_sim import example_args, run_main

    args = example_args(__doc__, argv, plot=True)

    arm, reqs, t_settled = run_main(main, args.url, *ENV)
    end = reqs["slide"].ended
    print("slide:", "completed (no slip seen)" if end is None else f"ended by {end}")
    print("force-servoed joint(s) used:", sorted({j + 1 for x in arm.adaptive_trace for j in x[4]}))
    t, p, f = world(arm)
    sliding = (t > t_settled + 0.5) & (p[:, 0] < EDGE_X - 0.003) & (t < (end.t if end else t[-1]))
    print(f"contact force while sliding: mean {f[sliding, 2].mean():.2f} N, sd {f[sliding, 2].std():.2f} N "
          f"(asked {FORCE_N:g} N); at rest before the slide: {f[(t > t_settled - 0.5) & (t < t_settled), 2].mean():.2f} N")
    if args.plot:
        print("wrote", plot(arm, reqs, t_settled, args.out))
    return 0 if end is not None else 1


if __name__ == "__main__":
    sys.exit(_cli(sys.argv[1:]))
