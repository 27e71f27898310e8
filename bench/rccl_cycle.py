"""Benchmark: the RCCL trajectory generator's cost per control cycle, beside thesis Table 5.1.

Runs the generator alone (no link, no simulator: what Table 5.1 measures is the CPU time
of the trajectory computation per cycle) on the generated PUMA 260 kinematics, in joint
mode and in Cartesian mode, over a tour of moves with transitions and holds, and writes
``reports/bench-rccl.md``.

    .venv/bin/python bench/rccl_cycle.py            # writes reports/bench-rccl.md
    .venv/bin/python bench/rccl_cycle.py --cycles 20000 --out -   # print only
"""
from __future__ import annotations

import argparse
import gc
import math
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from rccl.limits import load_limits  # noqa: E402
from rccl.planner import Planner  # noqa: E402
from rccl.position import EQ, TL, makeposition  # noqa: E402
from rccl.session import load_kinematics  # noqa: E402
from rccl.trajectory import TrajectoryGenerator  # noqa: E402
from rccl.transform import T6, Trsf, rot, trsl  # noqa: E402

VAX_MS = {"joint": 12.0, "cartesian": 15.5}   # thesis Table 5.1, VAX 750 with FPA, ms per cycle
TARGET_US = 100.0                              # issue 5: a Cartesian-mode cycle <= 100 us
Q_START = np.radians([0.0, 80.0, -170.0, 10.0, -60.0, 0.0])
RATE_HZ = 36


def tour(kin, variable: bool):
    """Four positions around the start pose (5-6 cm apart, with small rotations)."""
    base = kin.fk(Q_START)
    offsets = [trsl(0.05, 0.0, 0.0), trsl(0.05, 0.05, 0.02) @ rot("z", 0.2), trsl(0.0, 0.05, 0.0) @ rot("x", 0.1),
               trsl(0.0, 0.0, 0.0)]
    kind = "variable" if variable else "const"
    return [makeposition(f"p{i}", T6, EQ, Trsf(f"P{i}", o @ base, kind), TL, T6) for i, o in enumerate(offsets)]


def run(mode: str, cycles: int, variable: bool) -> dict:
    kin = load_kinematics("puma260")
    limits = load_limits("puma260")
    gen = TrajectoryGenerator(kin, limits, 1.0 / RATE_HZ, Q_START)
    arm = Planner(kin, limits, gen)
    arm.setmod(mode)
    arm.setvel(0.1, 1.0)
    positions = tour(kin, variable)
    times = np.empty(cycles)
    clock = time.perf_counter_ns
    k = 0
    gc.disable()
    try:
        while k < cycles:
            if len(arm.queue) < 2:
                for p in positions:
                    arm.move(p)
            t0 = clock()
            gen.step()
            times[k] = clock() - t0
            k += 1
    finally:
        gc.enable()
    if gen.errors:
        raise SystemExit(f"generator reported errors: {gen.errors[:3]}")
    us = times / 1e3
    return {"mode": mode, "variable": variable, "cycles": cycles, "mean": float(us.mean()),
            "median": float(np.median(us)), "p99": float(np.percentile(us, 99)), "max": float(us.max())}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cycles", type=int, default=20000)
    ap.add_argument("--out", default=str(ROOT / "reports" / "bench-rccl.md"), help="'-' to print only")
    args = ap.parse_args(argv)
    kin = load_kinematics("puma260")
    backend = "C kernels" if getattr(kin.module, "_ROBOT", None) is not None and os.environ.get(
        "RCCL_KINEMATICS", "c") != "python" else "Python"
    rows = [run("joint", args.cycles, False), run("joint", args.cycles, True),
            run("cartesian", args.cycles, False), run("cartesian", args.cycles, True)]
    lines = [
        "# RCCL trajectory generator: cost per control cycle",
        "",
        "Rebuilt by `.venv/bin/python bench/rccl_cycle.py` (also `make bench`). The generator alone is timed",
        "(`TrajectoryGenerator.step()`, `time.perf_counter_ns` around each call, garbage collector off),",
        f"at {RATE_HZ} Hz over a tour of four positions 5-6 cm apart with rotations, transitions and holds,",
        f"{args.cycles} cycles per row; kinematics `rccl.kinematics.puma260` "
        f"(RCCL_KINEMATICS={os.environ.get('RCCL_KINEMATICS', 'c')}).",
        f"Machine: {platform.processor() or platform.machine()}, Python {platform.python_version()}, "
        f"{os.cpu_count()} cores shared with other work (numbers are indicative).",
        "",
        "'const' targets are solved once per segment; 'variable' targets re-solve the position equation",
        "every cycle (and, in joint mode, the inverse kinematics of the moving target too), which is what",
        "RCCL on the VAX always did.",
        "",
        "| mode | targets | mean (us) | median (us) | p99 (us) | max (us) | VAX 750 (Table 5.1) | speed-up (mean) |",
        "|---|---|---:|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        vax = VAX_MS[r["mode"]]
        lines.append(f"| {r['mode']} | {'variable' if r['variable'] else 'const'} | {r['mean']:.1f} | "
                     f"{r['median']:.1f} | {r['p99']:.1f} | {r['max']:.1f} | {vax:.1f} ms | "
                     f"{vax * 1e3 / r['mean']:.0f}x |")
    cart = max(r["mean"] for r in rows if r["mode"] == "cartesian")
    verdict = "met" if cart <= TARGET_US else "NOT met"
    lines += ["", f"Target (issue 5): a Cartesian-mode cycle <= {TARGET_US:.0f} us (mean): **{verdict}** "
              f"(worst Cartesian mean {cart:.1f} us).", ""]
    text = "\n".join(lines)
    print(text)
    if args.out != "-":
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
