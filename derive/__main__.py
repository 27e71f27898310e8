"""`python -m derive` (= `make derive`): derive every arm under models/, emit code for every
back end, write reports/thesis-equations.md (the thesis's arms against the print) and
reports/derivation-<robot>.md for every other arm.

Back ends are functions ``emit(kernels, programs, robot, out_dir)``; add one to
``BACKENDS``. ``programs`` is the C back end's lowering of the kernels (and of
``ik_all``), made once per robot and printed by both compiled back ends.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from derive import emit_c, emit_casadi, emit_python
from derive.derivation import derive_robot, robot_names
from derive.kernels import build_kernels
from derive.robots import load_spec
from rcci.models import load_robot

ROOT = Path(__file__).resolve().parent.parent
OUT_DIR = ROOT / "rccl" / "kinematics"

#: (name, emit function); each writes its files for one robot into OUT_DIR
BACKENDS = [
    ("python", emit_python.emit),
    ("c", emit_c.emit),
    ("casadi", emit_casadi.emit),
]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m derive", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog=f"Generated files go to {OUT_DIR.relative_to(ROOT)}/ "
                                        f"(python, C, CasADi per robot); inputs are derive/*.py and models/.")
    names = robot_names()
    ap.add_argument("--robot", choices=names, action="append",
                    help="derive only this robot (repeatable); default every robot under models/")
    ap.add_argument("--no-report", action="store_true", help="skip the reports")
    ap.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    args = ap.parse_args(argv)
    robots = args.robot or list(names)
    report = not args.no_report
    derivations = {}
    with _progress(args.quiet) as bar:
        task = bar.add_task("derive", total=len(robots) * (2 + len(BACKENDS)) + report)
        for name in robots:
            t0 = time.perf_counter()
            bar.update(task, description=f"derive {name}: SymPy")
            d = derive_robot(name)
            bar.advance(task)
            bar.update(task, description=f"derive {name}: kernels, lowering")
            kernels = build_kernels(d)
            programs = emit_c.lower_all(kernels)
            bar.advance(task)
            derivations[name] = d
            for backend, emit in BACKENDS:
                bar.update(task, description=f"derive {name}: {backend}")
                files = emit(kernels, programs, name, OUT_DIR)
                for f in files:
                    print(f"derive: {name}: {backend}: {Path(f).relative_to(ROOT)}")
                bar.advance(task)
            print(f"derive: {name}: {len(kernels)} kernels in {time.perf_counter() - t0:.1f} s")
        if report:
            from derive.arm_report import write_arm_report
            from derive.report import write_report

            bar.update(task, description="derive: reports")
            # in the thesis's order: by the table the DH values come from (3.1 PUMA, 3.2 Microbo)
            thesis = dict(sorted(((n, d) for n, d in derivations.items() if d.spec.thesis),
                                 key=lambda nd: load_robot(nd[0]).source("joints.1.a").tag))
            if set(thesis) == {n for n in names if load_spec(n).thesis}:
                path = write_report(thesis, ROOT / "reports" / "thesis-equations.md")
                print(f"derive: {path.relative_to(ROOT)}")
            for n, d in derivations.items():
                if not d.spec.thesis:
                    path = write_arm_report(d, ROOT / "reports" / f"derivation-{n}.md")
                    print(f"derive: {path.relative_to(ROOT)}")
            bar.advance(task)
    return 0


def _progress(quiet: bool) -> Progress:
    """A rich progress bar on stderr, drawn only for a person at a terminal (not -q, not CI)."""
    shown = not quiet and sys.stderr.isatty() and not os.environ.get("CI")
    return Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                    console=Console(stderr=True), transient=True, disable=not shown)


if __name__ == "__main__":
    sys.exit(main())
