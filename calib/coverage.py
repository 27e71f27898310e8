"""`calib coverage`: how often the printed gravity intervals hold, measured over simula seeds.

For each seed, a hidden truth (rcci.calib.hidden_truth, the same seed) is drawn for the arm, its
gravity sweeps (`calib record gravity`'s plans) are recorded on a lockstep simula of that
truth with that seed, and fitted with the truth's own torque sensitivities (so that the
gravity fit's own interval is what is tested, not the sensitivities'). Each coefficient is
counted inside when |fit - truth| <= its printed error (99.73 %). Prints one line per seed and
the total; the claim in docs/calib.md quotes its output.
"""
from __future__ import annotations

import argparse
import os
import tempfile
from typing import Any

import numpy as np

from rcci.calib.exceptions import CalibError


def gravity_coverage(robot: str, seed: int, speed_deg: float, folder: str) -> list[tuple[str, float, float, float]]:
    """(name, fit, error, truth) of every gravity coefficient for one seed (module docstring)."""
    from rcci.calib.fitting import run_fit
    from rcci.calib.fits.gravity import plans
    from rcci.calib.hidden_truth import write_hidden_truth
    from rcci.calib.logs import load_trace
    from rcci.calib.program import run_plan
    from rcci.calib.robot import robot_info
    from rcci.calib.truth import truth_meta, truth_of
    from rci.simula.process import SimulaProcess

    info = robot_info(robot)
    truth_file = os.path.join(folder, f"truth-{seed}.toml")
    data = write_hidden_truth(truth_file, robot, seed)
    args = ["--warm", "--params", truth_file]
    paths = []
    with SimulaProcess("-p", *args, robot=robot, lockstep=True, seed=seed) as sim:
        for plan in plans(info, speed_deg):
            plan.warmup = None                     # a warm simula: no warm-up needed
            path = os.path.join(folder, f"{seed}-{plan.name}.rcilog")
            run_plan(sim.url, plan, path, robot, rate_hz=36,
                     extra_meta={"truth": truth_meta(seed, truth_file, args)})
            paths.append(path)
    traces = [load_trace(p) for p in paths]
    sigma = data["motors"]["torque_sensitivity"]
    params = {"calib": {"robot": robot}, "motors": {"torque_sensitivity": sigma}}
    out = run_fit("gravity", traces, info, params)
    truth = truth_of(traces, info)
    g = out.results
    return [(n, float(g.value[k]), float(g.error[k]), float(truth.gravity[k])) for k, n in enumerate(g.names)]


def _main(args: argparse.Namespace) -> int:
    check_seeds(args.seeds)
    seeds = [int(s) for s in args.seeds.split(",")]
    inside = total = 0
    with tempfile.TemporaryDirectory(prefix="calib-coverage-") as scratch:
        tmp = args.keep or scratch
        os.makedirs(tmp, exist_ok=True)
        for seed in seeds:
            rows = gravity_coverage(args.robot, seed, args.speed, tmp)
            ok = [abs(v - t) <= e for _, v, e, t in rows]
            inside, total = inside + sum(ok), total + len(ok)
            worst = max(rows, key=lambda r: abs(r[1] - r[3]) / r[2] if r[2] > 0 else np.inf)
            print(f"seed {seed}: {sum(ok)}/{len(ok)} inside their printed interval; worst {worst[0]}: "
                  f"|fit - truth| = {abs(worst[1] - worst[3]):.4f} = {abs(worst[1] - worst[3]) / worst[2]:.2f} x "
                  f"its error {worst[2]:.4f}", flush=True)
            for n, v, e, t in rows:
                print(f"    {n:6s} fit {v:9.4f} +- {e:7.4f}  truth {t:9.4f}  |d|/error {abs(v - t) / e:5.2f}",
                      flush=True)
    print(f"{args.robot} gravity, {len(seeds)} seeds at {args.speed:g} deg/s: {inside}/{total} "
          f"({100 * inside / total:.0f} %) coefficients inside their printed 99.73 % interval")
    return 0


def add_coverage(sub: Any) -> None:
    """Register `coverage` on the `calib` parser (``sub``: its subparsers)."""
    p = sub.add_parser("coverage", help="measure how often the printed gravity intervals hold, over seeds")
    p.add_argument("--robot", default="puma560")
    p.add_argument("--seeds", default="1,2,3,4,5", help="comma-separated simula seeds (each its own truth)")
    p.add_argument("--speed", type=float, default=20.0, help="sweep speed (deg/s), the plans' default 20")
    p.add_argument("--keep", metavar="DIR", help="keep the truths and logs here (default: a scratch folder)")
    p.set_defaults(func=_main)


def check_seeds(spec: str) -> None:
    try:
        [int(s) for s in spec.split(",")]
    except ValueError:
        raise CalibError(f"--seeds {spec!r}: not comma-separated integers") from None
