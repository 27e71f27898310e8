"""`python -m derive` (= `make derive`): derive both arms, emit code for every back end,
write reports/thesis-equations.md.

Back ends are functions ``emit(kernels, robot, out_dir)``; add one to ``BACKENDS``.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from derive import emit_c, emit_casadi, emit_python
from derive.derivation import ROBOT_NAMES, derive_robot
from derive.kernels import build_kernels

ROOT = Path(__file__).resolve().parent.parent
OUT_DIR = ROOT / "rccl" / "kinematics"

#: (name, emit function); each writes its files for one robot into OUT_DIR
BACKENDS = [
    ("python", emit_python.emit),
    ("c", emit_c.emit),
    ("casadi", emit_casadi.emit),
]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m derive", description=__doc__.splitlines()[0])
    ap.add_argument("--robot", choices=ROBOT_NAMES, action="append",
                    help="derive only this robot (repeatable); default both")
    ap.add_argument("--no-report", action="store_true", help="skip reports/thesis-equations.md")
    args = ap.parse_args(argv)
    robots = args.robot or list(ROBOT_NAMES)
    derivations = {}
    for name in robots:
        t0 = time.perf_counter()
        d = derive_robot(name)
        kernels = build_kernels(d)
        derivations[name] = d
        for backend, emit in BACKENDS:
            files = emit(kernels, name, OUT_DIR)
            for f in files:
                print(f"derive: {name}: {backend}: {Path(f).relative_to(ROOT)}")
        print(f"derive: {name}: {len(kernels)} kernels in {time.perf_counter() - t0:.1f} s")
    if not args.no_report and set(robots) == set(ROBOT_NAMES):
        from derive.report import write_report

        path = write_report(derivations, ROOT / "reports" / "thesis-equations.md")
        print(f"derive: {path.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
