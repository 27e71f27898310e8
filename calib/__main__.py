"""The `calib` console command: fit recorded logs, record new ones, rebuild the report."""
from __future__ import annotations

import argparse
import os
import shlex
import sys

from rcci.calib import registry
from rcci.calib.cli_extra import add_commands
from rcci.calib.exceptions import CalibError
from rcci.calib.fitting import run_fit
from rcci.calib.logs import load_trace
from rcci.calib.params import read_params, update_params, writable_params
from rcci.calib.progress import progress
from rcci.calib.robot import robot_info

DEFAULT_ROBOT = "puma260"   # the thesis's arm: the default where the input does not name one


def _fit_files(args: argparse.Namespace, kind) -> int:
    """``calib fit KIND FILES``: a kind's inputs that are not logs (kinematics: CSV files of
    end poses measured by an external instrument), which do not say their arm: ``--robot``,
    by default the thesis's PUMA 260, said in the output."""
    robot = args.robot or DEFAULT_ROBOT
    robot_info(robot)            # a robot calib cannot model is refused before the fit
    if args.params:              # and a parameter file it could not write (the result is kept)
        writable_params(args.params)
        _existing_params(args.params, robot)
    _, table, sections = kind.fit_files(args.logs, robot)
    how = "--robot" if args.robot else "the default; --robot names another arm"
    print(f"calib fit {kind.name}: {len(args.logs)} file(s) of robot {robot} ({how})\n")
    print(table)
    if args.params:
        update_params(args.params, robot, sections, _command(), kind.name, [])
        print(f"\nwrote {args.params}")
    return 0


def _command() -> str:
    return "calib " + " ".join(shlex.quote(a) for a in sys.argv[1:])


def _existing_params(path: str | None, robot: str) -> dict | None:
    """The parameter file at ``path`` if it exists (it must be of ``robot``)."""
    if not path or not os.path.exists(path):
        return None
    params = read_params(path)
    if params["calib"].get("robot") != robot:
        raise CalibError(f"{path}: holds parameters of robot {params['calib'].get('robot')!r}, "
                         f"these logs are of {robot!r}")
    return params


def _is_log(path: str) -> bool:
    return ".rcilog" in os.path.basename(path)


def print_outcome(outcome) -> None:
    """A fit's table, then its warnings and assumptions (never only in a file)."""
    print(outcome.table)
    for note in outcome.notes:
        print(f"\nwarning: {note}")
    if outcome.assumed:
        print("\nASSUMED, not fitted (--assume-datafile):")
        for a in outcome.assumed:
            print(f"  {a}")


def _fit(args: argparse.Namespace) -> int:
    kind = registry.kind(args.kind)
    if kind.fit_files and not any(_is_log(p) for p in args.logs):
        return _fit_files(args, kind)
    if args.plots and kind.plot is None:
        print(f"calib fit {kind.name}: makes no plots; --plots {args.plots} ignored", file=sys.stderr)
    elif args.plots:
        try:   # before the fit: a folder that cannot be made must not cost the fit
            os.makedirs(args.plots, exist_ok=True)
        except OSError as exc:
            raise CalibError(f"--plots {args.plots}: cannot create the folder: {exc.strerror}") from None
    if args.params:
        writable_params(args.params)       # before the fit: its result must not be lost
    paths = list(args.logs)
    traces = [load_trace(p, args.allow_truncated)
              for p in progress(paths, len(paths), f"reading {args.kind} logs",
                                enabled=False if args.quiet else None)]
    robots = {tr.robot for tr in traces}
    if len(robots) > 1:
        raise CalibError("logs from different robots cannot be fitted together: "
                         + "; ".join(f"{tr.path} is {tr.robot!r}" for tr in traces))
    for tr in traces:
        if tr.experiment != args.kind:
            raise CalibError(f"{tr.path}: is a '{tr.experiment}' log, not a '{args.kind}' one")
    robot = traces[0].robot
    if args.robot and args.robot != robot:
        raise CalibError(f"--robot {args.robot}: the logs are of robot {robot!r} ({traces[0].path})")
    info = robot_info(robot)
    params = _existing_params(args.params, robot)
    outcome = run_fit(args.kind, traces, info, params, assume_datafile=args.assume_datafile,
                      params_name=args.params)
    print(f"calib fit {args.kind}: {len(traces)} log(s) of robot {robot}\n")
    print_outcome(outcome)
    if args.params:
        update_params(args.params, robot, outcome.sections, _command(), args.kind, outcome.assumed,
                      outcome.truth, [tr.path for tr in traces])
        print(f"\nwrote {args.params}" + (" (with [calib] assumed)" if outcome.assumed else ""))
    if args.plots and kind.plot:
        for path in kind.plot(outcome, args.plots, f"calib-{kind.name}-j"):
            print(f"wrote {path}")
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="calib", description=(
        "Calibrate an arm's torque sensitivities, friction and gravity loading (thesis chapter 4, "
        "the PUMA 260's by default) and its kinematic errors (3.84) from recorded logs; the logs "
        "name their arm. See docs/calib.md."))
    sub = parser.add_subparsers(dest="command", required=True)
    fit = sub.add_parser("fit", help="fit one kind of parameter from logs and print the thesis table")
    fit.add_argument("kind", choices=registry.names(),
                     help="; ".join(f"{k.name}: {k.title}" for k in registry.kinds()))
    fit.add_argument("logs", nargs="+", metavar="LOG",
                     help="recorder logs (.rcilog[.xz|.gz]); for kinematics also CSV files of measured poses")
    fit.add_argument("-p", "--params", metavar="FILE",
                     help="parameter file (TOML): fitted inputs are read from it and the "
                          "results merged into it, atomically")
    fit.add_argument("--plots", metavar="DIR", help="write the fit's plots here (friction: friction against speed)")
    fit.add_argument("--assume-datafile", action="store_true",
                     help="where the fit needs an earlier fit's values (torque sensitivities, gravity "
                          "coefficients) that -p does not hold, use the robot data file's (the thesis's "
                          "tables) and say so in the output and in the parameter file; without it such "
                          "a fit is refused")
    fit.add_argument("--allow-truncated", action="store_true",
                     help="fit the records before the cut of a log that was not closed")
    fit.add_argument("--robot", metavar="ROBOT",
                     help="the arm (models/ROBOT.toml): logs name their own, and a different one here is "
                          f"refused; inputs that do not (pose CSV files) default to {DEFAULT_ROBOT}")
    fit.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    fit.set_defaults(func=_fit)
    add_commands(sub)
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except CalibError as exc:
        print(f"calib: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("calib: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
