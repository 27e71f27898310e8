"""`calib record`, `calib regen-logs` and `calib report`: the commands around the fits."""
from __future__ import annotations

import argparse
import glob
import os
import shlex
import tempfile
from typing import Any

from rcci.calib import registry
from rcci.calib.exceptions import CalibError
from rcci.calib.logs import LOG_DIR

REPORT = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "reports", "calibration.md")


def fit_all(paths: list[str], params_path: str, quiet: bool = True, assume_datafile: bool = False) -> dict:
    """Fit every kind present among ``paths`` in the registry's ``order``, chaining through ``params_path``."""
    from rcci.calib.fitting import run_fit
    from rcci.calib.logs import load_traces
    from rcci.calib.params import read_params, update_params
    from rcci.calib.progress import progress
    from rcci.calib.robot import robot_info

    traces = load_traces([p for p in progress(paths, len(paths), "reading logs",
                                              enabled=False if quiet else None)])
    robots = sorted({t.robot for t in traces})
    if len(robots) > 1:
        raise CalibError(f"the logs are of different robots ({', '.join(robots)}): fit each arm's logs apart")
    info = robot_info(robots[0])
    outcomes = {}
    for kind in registry.names("order"):
        sel = [t for t in traces if t.experiment == kind]
        if not sel:
            continue
        params = read_params(params_path) if os.path.exists(params_path) else None
        out = run_fit(kind, sel, info, params, assume_datafile=assume_datafile, params_name=params_path)
        update_params(params_path, info.name, out.sections, f"calib fit {kind} ({len(sel)} logs)", kind,
                      out.assumed, out.truth, [t.path for t in sel])
        outcomes[kind] = out
    return {"info": info, "outcomes": outcomes, "traces": traces}


def _report(args: argparse.Namespace) -> int:
    from rcci.calib.params import atomic_write
    from rcci.calib.report import coverage_table, render
    from rcci.calib.truth import truth_of

    paths = sorted(glob.glob(os.path.join(args.logs, "*.rcilog*")))
    if not paths:
        raise CalibError(f"no logs (*.rcilog, *.rcilog.xz, *.rcilog.gz) in {args.logs}; run `calib regen-logs`")
    out_dir = os.path.dirname(os.path.abspath(args.out))
    if args.params:
        from rcci.calib.params import writable_params
        writable_params(args.params)
    with tempfile.TemporaryDirectory(prefix="calib-report-") as tmp:
        params = args.params or os.path.join(tmp, "fitted.toml")
        res = fit_all(paths, params, quiet=args.quiet, assume_datafile=args.assume_datafile)
        info, outcomes = res["info"], res["outcomes"]
        plots = {name: registry.kind(name).plot(out, out_dir, f"calib-{name}-j")
                 for name, out in outcomes.items() if registry.kind(name).plot}
        root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
        rel = [os.path.relpath(os.path.abspath(p), root) for p in paths]
        truth, rows = truth_of(res["traces"], info), {}
        text = render(info, truth, outcomes, "calib report", _regen_command(res["traces"]),
                      rel, {k: [os.path.relpath(p, out_dir) for p in v] for k, v in plots.items()},
                      res["traces"], params, quiet=args.quiet, no_accuracy=args.no_accuracy, rows=rows)
    atomic_write(args.out, text)
    for kind, out in outcomes.items():
        print(out.table + "\n")
        for note in out.notes:
            print(f"warning: {note}\n")
    if rows:      # the logs' truth is known (simula's): how many values lie inside their intervals
        table = coverage_table(rows)
        print("\n".join([table[0].lstrip("# ") + ":"] + table[2:]))
    else:
        print("coverage: not measured (the logs carry no truth to score against: recorded on a robot)\n")
    n_plots = sum(len(v) for v in plots.values())
    print(f"wrote {args.out}" + (f" and {n_plots} plots" if n_plots else ""))
    if args.params:
        print(f"wrote {args.params}")
    return 0


def _regen_command(traces) -> str:
    """The command that recorded the logs, from their truth metadata."""
    from rcci.calib.truth import log_truth

    metas = [log_truth(t) for t in traces]
    if any(m["kind"] != "simula" for m in metas):
        return "calib record (against a robot)"
    seeds = sorted({int(m["seed"]) for m in metas})
    files = sorted({m.get("params_file") or "" for m in metas})
    cmd = "calib regen-logs" + (f" --seed {seeds[0]}" if seeds != [1985] and len(seeds) == 1 else "")
    if files != [""]:
        cmd += " " + " ".join(f"--params {f}" for f in files if f)
    return cmd


#: which kinds take each option of `calib record` (any other kind refuses it: never ignored)
OPTIONS = {"joints": ("friction", "sensitivity", "breakaway"), "mass": ("sensitivity",),
           "radius": ("sensitivity",), "loaded": ("sensitivity",),
           "rate": ("friction", "sensitivity", "gravity", "static"), "halts": ("static",),
           "touches": ("kinematics",)}
WHY_NOT = {"rate": "its rate is part of the program's design (kinematics: 250 Hz, 6 um of approach per "
                   "cycle; breakaway: the ramp's readings; dynamics: 200 Hz, its controller's gains and "
                   "the fit's filters)",
           "joints": "its programs move every joint (static halts, kinematic touches) or are chosen to "
                     "identify every coefficient together (gravity sweeps)"}


def record_options(args: argparse.Namespace, kinds: tuple[str, ...]) -> "RecordOptions":
    """The options given to `calib record` for ``kinds``, each checked: refused (CalibError) when
    no kind of ``kinds`` takes it, or when a single kind does not; bad values named."""
    from rcci.calib.registry import RecordOptions

    given = {k: getattr(args, k) for k in OPTIONS if getattr(args, k) not in (None, False)}
    for key, value in given.items():
        takers = [k for k in kinds if k in OPTIONS[key]]
        if not takers or (len(kinds) == 1 and kinds[0] not in OPTIONS[key]):
            why = WHY_NOT.get(key, f"only {', '.join(OPTIONS[key])} take(s) it")
            raise CalibError(f"calib record {args.kind}: --{key} does not apply: {why}")
    if args.simula is not None and args.loaded:
        raise CalibError("calib record sensitivity --simula: records the runs with and without the mass "
                         "(on simulas with and without the pulley); --loaded is for --url, where you hang it")
    joints = None
    if args.joints:
        try:
            joints = tuple(int(j) for j in args.joints.split(","))
        except ValueError:
            raise CalibError(f"--joints {args.joints!r}: not comma-separated joint numbers") from None
        n = len(robot_joints(args.robot))
        bad = [j for j in joints if not 1 <= j <= n]
        if bad:
            raise CalibError(f"--joints {args.joints}: robot {args.robot} has joints 1..{n}, not {bad}")
    for key in ("mass", "radius", "rate", "halts", "touches"):
        v = given.get(key)
        if v is not None and not v > 0:
            raise CalibError(f"--{key} {v}: must be positive")
    return RecordOptions(joints, args.mass, args.radius, args.rate, args.halts, args.touches)


def robot_joints(robot: str) -> list[int]:
    from rcci.calib.robot import robot_info

    return list(range(1, len(robot_info(robot).lower) + 1))


def _record(args: argparse.Namespace) -> int:
    from rcci.calib.registry import RecordRequest
    from rcci.calib.robot import robot_info
    from rcci.calib.truth import parse_against

    if bool(args.url) == bool(args.simula):
        raise CalibError("calib record: give --url (a robot, or a simula you started) or --simula ARGS "
                         "(calib starts a lockstep simula with those options), not both")
    kinds = registry.names("record_order") if args.kind == "all" else (args.kind,)
    options = record_options(args, kinds)
    if args.simula is not None:
        if args.against is not None:
            raise CalibError("calib record --simula: --against does not apply: the logs say the truth of "
                             "the simulas calib starts (their --seed and --params); --against is for --url")
        return _record_on_own_simula(args, kinds, options)
    if args.fresh:
        raise CalibError("calib record --url: --fresh does not apply: it records again the logs of a "
                         "--simula campaign; on a robot every run is recorded (choose another --out)")
    if args.kind == "all":
        raise CalibError("calib record all: only with --simula (on a robot, hang the pulley's mass and "
                         "mount the touch fixture for each kind: record the kinds one by one)")
    info = robot_info(args.robot)
    os.makedirs(args.out, exist_ok=True)
    joints = list(options.joints or range(1, len(info.lower) + 1))
    request = RecordRequest(args.url, args.out, args.robot, info, joints, args,
                            {"truth": parse_against(args.against or "robot")})
    registry.kind(args.kind).record(request)
    return 0


def simula_words(spec: str) -> tuple[int, str | None]:
    """(seed, parameter file) of ``--simula "ARGS"``; any other simula option is refused (the
    programs start the simulas they need, with the loads and fixtures they need)."""
    words = shlex.split(spec)
    seed, params, rest = 0, None, []
    it = iter(words)
    for w in it:
        key, eq, val = w.partition("=")
        if key in ("--seed", "--params"):
            val = val if eq else next(it, None)
            if val is None:
                raise CalibError(f"calib record --simula: {key} needs a value")
            if key == "--seed":
                try:
                    seed = int(val)
                except ValueError:
                    raise CalibError(f"calib record --simula: --seed {val!r} is not an integer") from None
            else:
                params = val
        else:
            rest.append(w)
    if rest:
        raise CalibError(f"calib record --simula: only --seed and --params are passed on (the "
                         f"programs start the simulas they need); not {' '.join(rest)!r}")
    return seed, params


def _record_on_own_simula(args: argparse.Namespace, kinds: tuple[str, ...], options) -> int:
    """``calib record KIND|all --simula "ARGS"``: regen-logs' programs for the kinds, on lockstep
    simulas calib starts with ARGS (--seed, --params), into --out as .rcilog.xz; logs already
    there are not recorded again unless --fresh; ``all`` leaves out, with the reason, a kind
    the arm cannot support."""
    from rcci.calib.regen import check_truth_file, regen

    seed, params = simula_words(args.simula)
    if params:
        check_truth_file(params, args.robot)
    regen(args.out, seed, kinds, params, quiet=args.quiet, robot=args.robot, options=options,
          skip_refused=args.kind == "all", resume=not args.fresh)
    return 0


def add_commands(sub: Any) -> None:
    """Register record / regen-logs / report on the `calib` parser (``sub``: its subparsers)."""
    rec = sub.add_parser("record", help="run a measurement program against a robot or simula and log it")
    rec.add_argument("kind", choices=registry.names() + ("all",),
                     help="one kind, or all (with --simula: the whole campaign, resumable)")
    rec.add_argument("--url", help="robot link, e.g. socket://127.0.0.1:7600 (simula's default) or /dev/ttyUSB0")
    rec.add_argument("--against", default=None, metavar="TRUTH",
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
    rec.add_argument("--radius", type=float, default=None, help="pulley drum radius (m), sensitivity (default 0.05)")
    rec.add_argument("--loaded", action="store_true",
                     help="sensitivity: the mass hangs on the pulley (else the unloaded runs)")
    rec.add_argument("--halts", type=int, default=None, help="static: number of random halts (default 275)")
    rec.add_argument("--touches", type=int, default=None,
                     help="kinematics: touches in all, spread over the fixture's three faces (default 48)")
    rec.add_argument("--fresh", action="store_true",
                     help="with --simula: record every log again, even those already in --out")
    rec.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
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
    from rcci.calib.regen import add_regen
    add_regen(sub)
    from rcci.calib.coverage import add_coverage
    add_coverage(sub)
    from rcci.calib.hidden_truth import add_hidden_truth
    add_hidden_truth(sub)
