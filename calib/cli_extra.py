"""`calib record`, `calib regen-logs` and `calib report`: the commands around the fits."""
from __future__ import annotations

import argparse
import glob
import os
import shlex
import tempfile

from calib.errors import CalibError

LOG_DIR = os.path.join(os.path.dirname(os.path.abspath(__file__)), "logs")
REPORT = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "reports", "calibration.md")
RECORD_KINDS = ("sensitivity", "friction", "static", "gravity", "breakaway", "kinematics")
ACCURACY_TARGETS = 20   # target poses of the before/after positioning run


def fit_all(paths: list[str], params_path: str, quiet: bool = True, assume_datafile: bool = False) -> dict:
    """Fit every kind present among ``paths`` in calib.fitting.ORDER, chaining through ``params_path``."""
    from calib.fitting import ORDER, run_fit
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
        out = run_fit(kind, sel, info, params, assume_datafile=assume_datafile, params_name=params_path)
        update_params(params_path, info.name, out.sections, f"calib fit {kind} ({len(sel)} logs)", kind, out.assumed)
        outcomes[kind] = out
    return {"info": info, "outcomes": outcomes, "traces": traces}


def _report(args: argparse.Namespace) -> int:
    from calib.params import _atomic_write
    from calib.plots import friction_plots
    from calib.report import render
    from calib.truth import log_truth, simula_variation, truth_of

    paths = sorted(glob.glob(os.path.join(args.logs, "*.rcilog*")))
    if not paths:
        raise CalibError(f"no logs (*.rcilog, *.rcilog.xz, *.rcilog.gz) in {args.logs}; run `calib regen-logs`")
    out_dir = os.path.dirname(os.path.abspath(args.out))
    with tempfile.TemporaryDirectory(prefix="calib-report-") as tmp:
        params = args.params or os.path.join(tmp, "fitted.toml")
        res = fit_all(paths, params, quiet=args.quiet, assume_datafile=args.assume_datafile)
        info, outcomes = res["info"], res["outcomes"]
        truth = truth_of(res["traces"], info)
        plots = []
        if "friction" in outcomes:
            plots = friction_plots(outcomes["friction"].results, outcomes["friction"].extra["points"],
                                   out_dir, prefix="calib-friction-j")
        vt = {}
        for tr in res["traces"]:
            t = log_truth(tr)
            if tr.experiment == "friction" and t["kind"] == "simula":
                import tomllib
                data = tomllib.loads(t["params_toml"]) if t.get("params_toml") else None
                vt[tr.meta["joint"]] = simula_variation(info.name, int(t["seed"]), tr.meta["joint"],
                                                        tuple(tr.meta["window"]), data)
        accuracy = None
        if "kinematics" in outcomes and truth is not None and not args.no_accuracy:
            accuracy = _accuracy(res["traces"], params, args.quiet)
        root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
        rel = [os.path.relpath(os.path.abspath(p), root) for p in paths]
        regen = _regen_command(res["traces"])
        text = render(info, truth, outcomes, "calib report", regen, rel,
                      [os.path.relpath(p, out_dir) for p in plots], vt, accuracy)
    _atomic_write(args.out, text)
    for kind, out in outcomes.items():
        print(out.table + "\n")
        for note in out.notes:
            print(f"warning: {note}\n")
    print(f"wrote {args.out}" + (f" and {len(plots)} plots" if plots else ""))
    if args.params:
        print(f"wrote {args.params}")
    return 0


def _regen_command(traces) -> str:
    """The command that recorded the logs, from their truth metadata."""
    from calib.truth import log_truth

    metas = [log_truth(t) for t in traces]
    if any(m["kind"] != "simula" for m in metas):
        return "calib record (against a robot)"
    seeds = sorted({int(m["seed"]) for m in metas})
    files = sorted({m.get("params_file") or "" for m in metas})
    cmd = "calib regen-logs" + (f" --seed {seeds[0]}" if seeds != [1985] and len(seeds) == 1 else "")
    if files != [""]:
        cmd += " " + " ".join(f"--params {f}" for f in files if f)
    return cmd


def _accuracy(traces, fitted: str, quiet: bool) -> dict:
    """RCCL's positioning error before/after on a simula of the logs' truth, and the cost."""
    from calib.accuracy import cycle_cost, ik_cost, positioning_error
    from calib.truth import log_truth
    from rccl.calibrated import calibrated_kinematics, load_calibrated
    from rccl.session import load_kinematics
    import rccl.kinematics.puma260 as nominal

    t = log_truth(next(tr for tr in traces if tr.experiment == "kinematics"))
    with tempfile.TemporaryDirectory(prefix="calib-truth-") as tmp:
        truth_file = os.path.join(tmp, "truth.toml")
        with open(truth_file, "w", encoding="utf-8") as f:
            f.write(t.get("params_toml") or "[calib]\nschema = \"rcci-calib-params/1\"\nrobot = \"puma260\"\n")
        if "[kinematics]" not in (t.get("params_toml") or ""):
            return {"skipped": "the logs' truth has no DH errors: the nominal model is exact"}
        rows = positioning_error(truth_file, fitted, n=ACCURACY_TARGETS, seed=int(t["seed"]))
    load = os.getloadavg()
    cost = {"nominal": cycle_cost(load_kinematics("puma260")), "calibrated": cycle_cost(calibrated_kinematics(fitted)),
            "ik_nominal": ik_cost(nominal), "ik_calibrated": ik_cost(load_calibrated(fitted)),
            "load": (load, os.getloadavg())}
    return {"rows": rows, "cost": cost, "targets": ACCURACY_TARGETS}


def _record(args: argparse.Namespace) -> int:
    from calib.experiments import friction_plans, gravity_plans, sensitivity_plans, static_plan
    from calib.program import run_plan
    from calib.robot import robot_info
    from calib.truth import parse_against

    if bool(args.url) == bool(args.simula):
        raise CalibError("calib record: give --url (a robot, or a simula you started) or --simula ARGS "
                         "(calib starts a lockstep simula with those options), not both")
    info = robot_info(args.robot)
    joints = [int(j) for j in args.joints.split(",")] if args.joints else list(range(1, 7))
    os.makedirs(args.out, exist_ok=True)
    if args.simula is not None:
        return _record_on_own_simula(args)
    truth = parse_against(args.against)
    extra = {"truth": truth}
    if args.kind == "kinematics":
        from calib.touch import touch_plan
        from calib.touch_program import run_touches

        plan = touch_plan(max(1, args.touches // 3))
        path = os.path.join(args.out, plan.name + ".rcilog")
        n = run_touches(args.url, plan, path, args.robot, extra_meta=extra)
        print(f"{plan.name}: {n} records -> {path}")
        return 0
    if args.kind == "breakaway":
        from calib.breakaway_program import breakaway_plans, run_breakaway

        static = info.nominal["friction"]["static_pos"]["values"]
        for bplan in breakaway_plans(static, info.drive.G, joints):
            path = os.path.join(args.out, bplan.name + ".rcilog")
            n = run_breakaway(args.url, bplan, path, args.robot, extra_meta=extra)
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
    for plan in plans:
        path = os.path.join(args.out, plan.name + ".rcilog")
        run = run_plan(args.url, plan, path, args.robot, args.rate or plan.rate_hz, extra_meta=extra)
        print(f"{plan.name}: {run.records} records -> {path}")
    return 0


def _record_on_own_simula(args: argparse.Namespace) -> int:
    """``calib record KIND --simula "ARGS"``: the logs of regen-logs' programs for KIND, on
    lockstep simulas calib starts with ARGS (which may hold --seed and --params)."""
    from calib.regen import record_kinematics, regen

    words = shlex.split(args.simula)
    seed, params, rest = 0, None, []
    it = iter(words)
    for w in it:
        if w == "--seed":
            seed = int(next(it, "0"))
        elif w.startswith("--seed="):
            seed = int(w.split("=", 1)[1])
        elif w == "--params":
            params = next(it, None)
        elif w.startswith("--params="):
            params = w.split("=", 1)[1]
        else:
            rest.append(w)
    if rest:
        raise CalibError(f"calib record --simula: only --seed and --params are passed on (the "
                         f"programs start the simulas they need); not {' '.join(rest)!r}")
    if args.kind == "kinematics":
        path = os.path.join(args.out, "kinematics.rcilog")
        n = record_kinematics(path, seed, params, touches_per_face=max(1, args.touches // 3))
        print(f"kinematics: {n} records -> {path}")
        return 0
    regen(args.out, seed, (args.kind,), params)
    return 0


def add_commands(sub: argparse._SubParsersAction) -> None:
    """Register record / regen-logs / report on the `calib` parser."""
    rec = sub.add_parser("record", help="run a measurement program against a robot or simula and log it")
    rec.add_argument("kind", choices=RECORD_KINDS)
    rec.add_argument("--url", help="robot link, e.g. socket://127.0.0.1:7600 (simula's default) or /dev/ttyUSB0")
    rec.add_argument("--against", default="robot", metavar="TRUTH",
                     help="with --url, what the log says it was recorded against: 'robot' (default: no "
                          "ground truth) or 'simula:seed=N[,params=FILE]' for a simula you started so")
    rec.add_argument("--simula", metavar="ARGS",
                     help="instead of --url: start lockstep simulas with these options (--seed N, "
                          "--params FILE) and record against them; the logs carry that truth")
    rec.add_argument("--out", default=".", help="folder for the logs")
    rec.add_argument("--robot", default="puma260",
                     help="the arm's model (models/ROBOT.toml), default puma260")
    rec.add_argument("--rate", type=int, default=None,
                     help="sample rate (Hz); default the program's own (36, 72 or 1000 Hz)")
    rec.add_argument("--joints", help="comma-separated joints (default all)")
    rec.add_argument("--mass", type=float, default=None,
                     help="pulley mass (kg), sensitivity (default 4 kg on joints 1-3, 1 kg on 4-6)")
    rec.add_argument("--radius", type=float, default=0.05, help="pulley drum radius (m), sensitivity")
    rec.add_argument("--loaded", action="store_true",
                     help="sensitivity: the mass hangs on the pulley (else the unloaded runs)")
    rec.add_argument("--halts", type=int, default=275, help="static: number of random halts")
    rec.add_argument("--touches", type=int, default=48,
                     help="kinematics: touches in all (spread over the fixture's three faces)")
    rec.set_defaults(func=_record)
    rep = sub.add_parser("report", help="fit the shipped logs and write reports/calibration.md")
    rep.add_argument("--logs", default=LOG_DIR, metavar="DIR", help=f"folder of the logs to fit (default {LOG_DIR})")
    rep.add_argument("--out", default=REPORT, metavar="FILE", help=f"report to write (default {REPORT})")
    rep.add_argument("--params", help="also keep the fitted parameter file here")
    rep.add_argument("--assume-datafile", action="store_true",
                     help="let fits whose inputs the logs do not provide use the data file's (announced)")
    rep.add_argument("--no-accuracy", action="store_true",
                     help="skip RCCL's positioning run on simula (the kinematic section's before/after)")
    rep.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    rep.set_defaults(func=_report)
    from calib.regen import add_regen
    add_regen(sub)
