"""Free-air force-estimate bias per arm (issue 25, defect 5): ``python -m bench.force_bias``.

For each arm, a lockstep ``simula --robot ROBOT -p --power-on --seed S`` (a user's options:
cold joints, ADC noise, servo ripple, static friction drawn at every halt) and an adaptive
arm that takes its 5 cm probe 3 cm along the probe axis at 1 cm/s in free air with a force
monitor. Printed per run: the largest |f| of each force component over the motion, the
median of |F| (N), and the estimate's error bar at the start (``ForceEstimator.error_bar``).

``--before`` runs the estimator as it was before this change (no sample period: a fixed
1e-3 rad/s rest speed, no ADC-filter model); ``--first`` starts the move at the control's
first sample instead of after 0.3 s of servoing (the first period includes simula's pull of
each joint onto its encoder count, see docs/adaptive.md).
"""
from __future__ import annotations

import argparse
import math
import warnings

import numpy as np

ROBOTS = ("puma260", "microbo", "puma560", "stanford")


def run(robot: str, seed: int, first: bool, rate: int = 36) -> tuple[np.ndarray, np.ndarray]:
    """Forces (N, 6) over the move and the error bar (6,) at its start."""
    import rccl.adaptive
    from rccl import EQ, T6, TL, Trsf, makeposition
    from rccl.transform import trsl
    from rci.simula.process import SimulaProcess

    rows = []
    tool_m = trsl(0.0, 0.0, 0.05)
    with SimulaProcess("-p", "--power-on", robot=robot, lockstep=True, seed=seed) as sim:
        with rccl.adaptive.open(sim.url, robot=robot, timeout=2.0, rate_hz=rate) as arm:
            if not first:
                arm.rci.wait(0.3)
            tool = Trsf("PROBE", tool_m)
            x0 = arm.t6 @ tool_m
            p = makeposition("DOWN", T6, tool, EQ, Trsf("DOWN", x0 @ trsl(0.0, 0.0, 0.03)), TL, tool)
            arm.setmod("cartesian")
            arm.setvel(0.01, math.radians(10.0))
            kin = arm.adaptive.kin
            bar = arm.adaptive.estimator.error_bar(np.linalg.inv(kin.jacobian6(arm.gen.q)), tool_m)
            arm.evalfn(lambda s: rows.append(s.force.copy()), needs=("force",))
            arm.waitfor(arm.move(p))
    return np.array(rows), bar


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--robots", nargs="+", default=list(ROBOTS), choices=ROBOTS)
    ap.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    ap.add_argument("--before", action="store_true", help="the estimator without the sample period (as before)")
    ap.add_argument("--first", action="store_true", help="move at the control's first sample")
    ap.add_argument("--rate", type=int, default=36, help="sample rate (Hz), default 36")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore", RuntimeWarning)      # Python kinematics without the C kernels
    if args.before:
        from rccl.adaptive.force import ForceEstimator
        plain = ForceEstimator.net_torques
        ForceEstimator.net_torques = lambda self, q, qd, v, dt=None, sample=None: plain(self, q, qd, v)
    when = "at the first sample" if args.first else "after 0.3 s"
    print(f"estimator: {'before' if args.before else 'after'}; move {when}; {args.rate} Hz")
    print("robot     seed  max|fx|  max|fy|  max|fz|  median|F|   bar fx  bar fy  bar fz   (N)")
    for robot in args.robots:
        worst = []
        for seed in args.seeds:
            f, bar = run(robot, seed, args.first, args.rate)
            m = np.abs(f[:, :3]).max(axis=0)
            worst.append(m.max())
            med = float(np.median(np.linalg.norm(f[:, :3], axis=1)))
            print(f"{robot:9s} {seed:4d}  {m[0]:7.2f}  {m[1]:7.2f}  {m[2]:7.2f}  {med:9.2f}   "
                  f"{bar[0]:6.2f}  {bar[1]:6.2f}  {bar[2]:6.2f}", flush=True)
        print(f"{robot:9s} worst component over the seeds: {max(worst):.2f} N")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
