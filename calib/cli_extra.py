"""`calib record`, `calib regen-logs` and `calib report`: the commands around the fits."""
from __future__ import annotations

import argparse
import glob
import os
import tempfile

from calib.errors import CalibError

LOG_DIR = os.path.join(os.path.dirname(os.path.abspath(__file__)), "logs")
REPORT = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "reports", "calibration.md")
ORDER = ("sensitivity", "friction", "gravity", "static", "breakaway")  # each fit feeds the next


def fit_all(paths: list[str], params_path: str, quiet: bool = True) -> dict:
    """Fit every kind present among ``paths`` in ORDER, chaining through ``params_path``."""
    from calib.fitting import run_fit
    from calib.logs import load_traces
    from calib.params import read_params, update_params
    from calib.progress import progress
    from calib.robot import robot_info

    traces = load_traces([p for p in progress(paths, len(paths), "reading logs",
                                              enabled=False if quiet else None)])
    info = robot_info(traces[0].robot)
    outcomes = {}
    for kind in ORDER:
        sel = [t for t in traces if t.experiment == kind]
        if not sel:
            continue
        params = read_params(params_path) if os.path.exists(params_path) else None
        out = run_fit(kind, sel, info, params)
        update_params(params_path, info.name, out.sections, f"calib fit {kind} ({len(sel)} logs)")
        outcomes[kind] = out
    return {"info": info, "outcomes": outcomes, "traces": traces}


def _report(args: argparse.Namespace) -> int:
    from calib.plots import friction_plots
    from calib.params import _atomic_write
    from calib.report import render
    from calib.truth import simulator_truth

    paths = sorted(glob.glob(os.path.join(args.logs, "*.rcilog*")))
    if not paths:
        raise CalibError(f"no logs (*.rcilog, *.rcilog.xz, *.rcilog.gz) in {args.logs}; run `calib regen-logs`")
    out_dir = os.path.dirname(os.path.abspath(args.out))
    if args.params:
        res = fit_all(paths, args.params, quiet=args.quiet)
    else:
        with tempfile.TemporaryDirectory(prefix="calib-report-") as tmp:
            res = fit_all(paths, os.path.join(tmp, "fitted.toml"), quiet=args.quiet)
    info, outcomes = res["info"], res["outcomes"]
    plots = []
    if "friction" in outcomes:
        plots = friction_plots(outcomes["friction"].results, outcomes["friction"].extra["points"],
                               out_dir, prefix="calib-friction-j")
    from calib.truth import simula_variation
    vt = {}
    for tr in res["traces"]:
        if tr.experiment == "friction" and "simula_seed" in tr.meta:
            vt[tr.meta["joint"]] = simula_variation(info.name, int(tr.meta["simula_seed"]),
                                                    tr.meta["joint"], tuple(tr.meta["window"]))
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    rel = [os.path.relpath(os.path.abspath(p), root) for p in paths]
    text = render(info, simulator_truth(info), outcomes, "calib report",
                  "calib regen-logs", rel, [os.path.relpath(p, out_dir) for p in plots], vt)
    _atomic_write(args.out, text)
    for kind, out in outcomes.items():
        print(out.table + "\n")
    print(f"wrote {args.out}" + (f" and {len(plots)} plots" if plots else ""))
    if args.params:
        print(f"wrote {args.params}")
    return 0


def _record(args: argparse.Namespace) -> int:
    from calib.experiments import friction_plans, gravity_plans, sensitivity_plans, static_plan
    from calib.program import run_plan
    from calib.robot import robot_info

    info = robot_info(args.robot)
    joints = [int(j) for j in args.joints.split(",")] if args.joints else list(range(1, 7))
    if args.kind == "breakaway":
        from calib.breakaway_program import breakaway_plans, run_breakaway

        os.makedirs(args.out, exist_ok=True)
        static = info.nominal["friction"]["static_pos"]["values"]
        for bplan in breakaway_plans(static, info.drive.G, joints):
            path = os.path.join(args.out, bplan.name + ".rcilog")
            n = run_breakaway(args.url, bplan, path, args.robot)
            print(f"{bplan.name}: {n} records -> {path}")
        return 0
    if args.kind == "friction":
        plans = friction_plans(joints)
    elif args.kind == "sensitivity":
        plans = [p for p in sensitivity_plans(args.mass, args.radius, joints)
                 if (p.meta["load"]["mass_kg"] > 0) == args.loaded]
    elif args.kind == "gravity":
        plans = gravity_plans(info.regressor, info.lower, info.upper)
    else:
        plans = [static_plan(info.lower, info.upper, halts=args.halts)]
    os.makedirs(args.out, exist_ok=True)
    for plan in plans:
        path = os.path.join(args.out, plan.name + ".rcilog")
        run = run_plan(args.url, plan, path, args.robot, args.rate or plan.rate_hz)
        print(f"{plan.name}: {run.records} records -> {path}")
    return 0


def add_commands(sub: argparse._SubParsersAction) -> None:
    """Register record / regen-logs / report on the `calib` parser."""
    rec = sub.add_parser("record", help="run a measurement program against a robot or simula and log it")
    rec.add_argument("kind", choices=("sensitivity", "friction", "static", "gravity", "breakaway"))
    rec.add_argument("--url", required=True, help="robot link, e.g. socket://127.0.0.1:5555 or /dev/ttyUSB0")
    rec.add_argument("--out", default=".", help="folder for the logs")
    rec.add_argument("--robot", default="puma260")
    rec.add_argument("--rate", type=int, default=None,
                     help="sample rate (Hz); default the program's own (36, 72 or 1000 Hz)")
    rec.add_argument("--joints", help="comma-separated joints (default all)")
    rec.add_argument("--mass", type=float, default=None,
                     help="pulley mass (kg), sensitivity (default 4 kg on joints 1-3, 1 kg on 4-6)")
    rec.add_argument("--radius", type=float, default=0.05, help="pulley drum radius (m), sensitivity")
    rec.add_argument("--loaded", action="store_true",
                     help="sensitivity: the mass hangs on the pulley (else the unloaded runs)")
    rec.add_argument("--halts", type=int, default=275, help="static: number of random halts")
    rec.set_defaults(func=_record)
    rep = sub.add_parser("report", help="fit the shipped logs and write reports/calibration.md")
    rep.add_argument("--logs", default=LOG_DIR)
    rep.add_argument("--out", default=REPORT)
    rep.add_argument("--params", help="also keep the fitted parameter file here")
    rep.add_argument("-q", "--quiet", action="store_true")
    rep.set_defaults(func=_report)
    from calib.regen import add_regen
    add_regen(sub)
