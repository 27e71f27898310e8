"""The `calib` console command: fit recorded logs, record new ones, rebuild the report."""
from __future__ import annotations

import argparse
import os
import shlex
import sys

from calib.cli_extra import add_commands
from calib.errors import CalibError
from calib.fitting import KINDS, run_fit
from calib.logs import load_trace
from calib.params import read_params, update_params
from calib.progress import progress
from calib.robot import robot_info


def _fit_kinematics(args: argparse.Namespace) -> int:
    import numpy as np

    from calib.kinematics import fit_kinematics, read_poses, table
    from rci.robot_model import load_robot

    if args.params:
        raise CalibError("kinematic error parameters are not part of the runtime parameter "
                         "file (simula and RCCL use the DH table); drop --params")
    Q, T = zip(*(read_poses(p) for p in args.logs))
    model = load_robot("puma260")
    dh = np.array([[j.theta, j.d, j.a, j.alpha] for j in model.joints])
    fit = fit_kinematics(dh, np.vstack(Q), np.concatenate(T))
    print(f"calib fit kinematics: {sum(len(q) for q in Q)} poses of robot puma260\n")
    print(table(fit))
    return 0


def _fit(args: argparse.Namespace) -> int:
    if args.kind == "kinematics":
        return _fit_kinematics(args)
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
    info = robot_info(robot)
    params = None
    if args.params and os.path.exists(args.params):
        params = read_params(args.params)
        if params["calib"].get("robot") != robot:
            raise CalibError(f"{args.params}: holds parameters of robot "
                             f"{params['calib'].get('robot')!r}, these logs are of {robot!r}")
    outcome = run_fit(args.kind, traces, info, params)
    print(f"calib fit {args.kind}: {len(traces)} log(s) of robot {robot}\n")
    print(outcome.table)
    if args.params:
        command = "calib " + " ".join(shlex.quote(a) for a in sys.argv[1:])
        update_params(args.params, robot, outcome.sections, command)
        print(f"\nwrote {args.params}")
    if args.plots and args.kind == "friction":
        from calib.plots import friction_plots
        for path in friction_plots(outcome.results, outcome.extra["points"], args.plots):
            print(f"wrote {path}")
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="calib", description=(
        "Calibrate the PUMA 260's torque sensitivities, friction and gravity loading from "
        "recorded logs (thesis chapter 4). See docs/calib.md."))
    sub = parser.add_subparsers(dest="command", required=True)
    fit = sub.add_parser("fit", help="fit one kind of parameter from logs and print the thesis table")
    fit.add_argument("kind", choices=KINDS + ("kinematics",))
    fit.add_argument("logs", nargs="+", metavar="LOG",
                     help="recorder logs (.rcilog[.xz|.gz]); for kinematics, CSV files of measured poses")
    fit.add_argument("-p", "--params", metavar="FILE",
                     help="parameter file (TOML): fitted inputs are read from it and the "
                          "results merged into it, atomically")
    fit.add_argument("--plots", metavar="DIR", help="write friction-against-speed PNGs here (friction)")
    fit.add_argument("--allow-truncated", action="store_true",
                     help="fit the records before the cut of a log that was not closed")
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
