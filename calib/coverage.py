"""`calib coverage`: how often the printed gravity intervals hold, measured over simula seeds.

For each seed, a hidden truth (rcci.calib.hidden_truth, the same seed) is drawn for the arm, its
gravity sweeps (`calib record gravity`'s plans, warm-ups included) are recorded on a lockstep
simula of that truth with that seed, and fitted with the truth's own torque sensitivities (so
that the gravity fit's own interval is what is tested, not the sensitivities'). Each coefficient
is counted inside when |fit - truth| <= its printed error (99.73 %). Prints one line per seed
and the total, and with ``--report`` writes them as a Markdown report (seeds, truths, each
coefficient's |fit - truth| / error); the claim in docs/calib.md quotes its output.
"""
from __future__ import annotations

import argparse
import os
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np

from rcci.calib.exceptions import CalibError

Row = tuple[str, float, float, float]       # name, fit, error, truth (N m)
ATTEMPTS = 3      # a seed's recording is started again on a fresh simula when one stops (a watchdog
                  # under load has been seen to: "no CHG for 1 cycles"), its finished logs kept


def gravity_coverage(robot: str, seed: int, speed_deg: float, folder: str,
                     warmup: bool = True) -> list[Row]:
    """(name, fit, error, truth) of every gravity coefficient for one seed (module docstring);
    without ``warmup`` the plans' warm-ups are skipped (the joints then cool while the others
    are swept, and warm up again during their own sweep: docs/calib.md). A log already in
    ``folder`` for this seed (an earlier run's, same truth) is fitted again, not re-recorded."""
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
    todo, paths = [], []
    for plan in plans(info, speed_deg):
        path = os.path.join(folder, f"{seed}-{plan.name}{'' if warmup else '-cold'}.rcilog")
        paths.append(path)
        if not _same_sweep(path, plan.meta):
            todo.append((plan, path))
    LOGS[(robot, seed)] = (len(todo), len(paths) - len(todo))
    if todo:
        with SimulaProcess("-p", *args, robot=robot, lockstep=True, seed=seed) as sim:
            for plan, path in todo:
                if not warmup:
                    plan.warmup = None
                run_plan(sim.url, plan, path + ".part", robot, rate_hz=36,
                         extra_meta={"truth": truth_meta(seed, truth_file, args)})
                os.replace(path + ".part", path)
    traces = [load_trace(p) for p in paths]
    sigma = data["motors"]["torque_sensitivity"]
    params = {"calib": {"robot": robot}, "motors": {"torque_sensitivity": sigma}}
    out = run_fit("gravity", traces, info, params)
    truth = truth_of(traces, info)
    g = out.results
    SWEEP_ERRORS[(robot, seed)] = sweep_errors(g.rows, truth.gravity)
    return [(n, float(g.value[k]), float(g.error[k]), float(truth.gravity[k])) for k, n in enumerate(g.names)]


# (robot, seed) -> (logs recorded, logs reused from --keep) of the last run of that seed
LOGS: dict[tuple[str, int], tuple[int, int]] = {}
# (robot, seed) -> sweep_errors of the last fit of that seed (for the report)
SWEEP_ERRORS: dict[tuple[str, int], list[tuple[str, int, float, float]]] = {}


def sweep_errors(rows, truth: np.ndarray) -> list[tuple[str, int, float, float]]:
    """(position, joint, err+, err-) per sweep: each direction's tau0 less what the truth's
    coefficients give for its row (N m), NaN for a direction not measured. Opposite errors
    (err+ = -err-) are one error of the sweep's combination (rcci.calib.gravity.sweep_observations)."""
    out: dict[tuple[str, int], list[float]] = {}
    for r in rows:
        e = out.setdefault((r.position, r.joint), [float("nan"), float("nan")])
        e[0 if r.direction > 0 else 1] = float(r.tau0 - r.row @ truth)
    return [(pos, j, ep, em) for (pos, j), (ep, em) in out.items()]


def _same_sweep(path: str, meta: dict) -> bool:
    """True when ``path`` is a log of the sweep ``meta`` describes (joint, start pose, window)."""
    from rcci.calib.logs import load_trace

    if not os.path.exists(path):
        return False
    m = load_trace(path).meta
    return (m.get("joint") == meta["joint"] and np.allclose(m.get("q_start", []), meta["q_start"])
            and np.isclose(m.get("phi_low", np.nan), meta["phi_low"]))


def _ratio(r: Row) -> float:
    return abs(r[1] - r[3]) / r[2] if r[2] > 0 else float("inf")


def seed_lines(seed: int, rows: list[Row]) -> list[str]:
    """The printed summary of one seed."""
    ok = [abs(v - t) <= e for _, v, e, t in rows]
    worst = max(rows, key=_ratio)
    out = [f"seed {seed}: {sum(ok)}/{len(ok)} inside their printed interval; worst {worst[0]}: "
           f"|fit - truth| = {abs(worst[1] - worst[3]):.4f} = {_ratio(worst):.2f} x its error {worst[2]:.4f}"]
    out += [f"    {n:6s} fit {v:9.4f} +- {e:7.4f}  truth {t:9.4f}  |d|/error {_ratio((n, v, e, t)):5.2f}"
            for n, v, e, t in rows]
    return out


def report_text(robot: str, speed: float, warmup: bool, results: dict[int, list[Row]], command: str,
                seconds: float) -> str:
    """The Markdown report of ``calib coverage --report``."""
    names = [r[0] for r in next(iter(results.values()))]
    inside = sum(abs(v - t) <= e for rows in results.values() for _, v, e, t in rows)
    total = sum(len(rows) for rows in results.values())
    ratios = np.array([_ratio(r) for rows in results.values() for r in rows])
    recorded = sum(LOGS.get((robot, seed), (0, 0))[0] for seed in results)
    reused = sum(LOGS.get((robot, seed), (0, 0))[1] for seed in results)
    L = [f"# Gravity interval coverage: {robot}", "",
         f"Command: `{command}` ({time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, "
         f"{seconds / 60:.1f} min, load average {os.getloadavg()[0]:.1f} at the end on "
         f"{os.cpu_count()} cores; {recorded} logs recorded in this run, {reused} recorded by an earlier "
         "run of the same command and kept with --keep).", "",
         f"Each seed: the hidden truth `calib hidden-truth --robot {robot} --seed N` (sensitivities and "
         "friction 10-30 %, gravity coefficients 3-10 % away from the data file, DH errors), "
         f"the plans of `calib record gravity` at {speed:g} deg/s "
         f"({'with' if warmup else 'WITHOUT'} their warm-ups) on a lockstep simula of that truth "
         "and seed, fitted with the truth's own sensitivities.", "",
         f"**{inside} of {total} coefficients ({100 * inside / total:.0f} %) inside their printed "
         f"99.73 % interval**; |fit - truth| / error: median {np.median(ratios):.2f}, "
         f"{int((ratios > 1 / 3).sum())} of {total} beyond one third of it (a 3-sd interval "
         f"expects {0.3173 * total:.0f}).", "",
         "| seed | inside | " + " | ".join(names) + " |", "|---|---|" + "---|" * len(names)]
    for seed, rows in results.items():
        ok = sum(abs(v - t) <= e for _, v, e, t in rows)
        L.append(f"| {seed} | {ok}/{len(rows)} | " + " | ".join(f"{_ratio(r):.2f}" for r in rows) + " |")
    L += ["", "Cells: |fit - truth| / printed error (inside when <= 1). Values (N m):", ""]
    tail = ["", "Each sweep's errors (N m): tau0 less the truth's value of its row, per direction "
            "(err+ = -err-: one error the two passes share).", "",
            "| seed | sweep | joint | err+ | err- |", "|---|---|---|---|---|"]
    for seed in results:
        tail += [f"| {seed} | {pos} | {j} | {ep:+.4f} | {em:+.4f} |"
                 for pos, j, ep, em in SWEEP_ERRORS.get((robot, seed), [])]
    L += ["| seed | coefficient | truth | fit | error |", "|---|---|---|---|---|"]
    for seed, rows in results.items():
        L += [f"| {seed} | {n} | {t:.4f} | {v:.4f} | {e:.4f} |" for n, v, e, t in rows]
    return "\n".join(L + tail) + "\n"


def _main(args: argparse.Namespace) -> int:
    check_seeds(args.seeds)
    seeds = [int(s) for s in args.seeds.split(",")]
    start = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="calib-coverage-") as scratch:
        tmp = args.keep or scratch
        os.makedirs(tmp, exist_ok=True)

        def one(seed: int) -> list[Row]:
            for attempt in range(ATTEMPTS):
                try:
                    rows = gravity_coverage(args.robot, seed, args.speed, tmp, warmup=not args.no_warmup)
                    break
                except Exception as exc:          # a simula that stopped: its finished logs are kept
                    if attempt + 1 == ATTEMPTS:
                        raise
                    print(f"seed {seed}: {type(exc).__name__}: {exc}; again on a fresh simula "
                          "(the logs it finished are kept)", flush=True)
            print("\n".join(seed_lines(seed, rows)), flush=True)
            return rows

        with ThreadPoolExecutor(max_workers=max(1, args.jobs)) as pool:
            results = dict(zip(seeds, pool.map(one, seeds)))
    inside = sum(abs(v - t) <= e for rows in results.values() for _, v, e, t in rows)
    total = sum(len(rows) for rows in results.values())
    print(f"{args.robot} gravity, {len(seeds)} seeds at {args.speed:g} deg/s: {inside}/{total} "
          f"({100 * inside / total:.0f} %) coefficients inside their printed 99.73 % interval")
    if args.report:
        command = (f"calib coverage --robot {args.robot} --seeds {args.seeds} --speed {args.speed:g}"
                   + (" --no-warmup" if args.no_warmup else ""))
        with open(args.report, "w", encoding="utf-8") as f:
            f.write(report_text(args.robot, args.speed, not args.no_warmup, results, command,
                                time.monotonic() - start))
        print(f"wrote {args.report}")
    return 0


def add_coverage(sub: Any) -> None:
    """Register `coverage` on the `calib` parser (``sub``: its subparsers)."""
    p = sub.add_parser("coverage", help="measure how often the printed gravity intervals hold, over seeds")
    p.add_argument("--robot", default="puma560")
    p.add_argument("--seeds", default="1,2,3,4,5", help="comma-separated simula seeds (each its own truth)")
    p.add_argument("--speed", type=float, default=20.0, help="sweep speed (deg/s), the plans' default 20")
    p.add_argument("--keep", metavar="DIR",
                   help="keep the truths and logs here (default: a scratch folder); logs already there are reused")
    p.add_argument("--jobs", type=int, default=1, help="seeds recorded at once, each on its own simula")
    p.add_argument("--no-warmup", action="store_true",
                   help="skip the plans' warm-ups (shows the drift of joints that cooled: docs/calib.md)")
    p.add_argument("--report", metavar="FILE", help="write the figures as Markdown here")
    p.set_defaults(func=_main)


def check_seeds(spec: str) -> None:
    try:
        [int(s) for s in spec.split(",")]
    except ValueError:
        raise CalibError(f"--seeds {spec!r}: not comma-separated integers") from None
