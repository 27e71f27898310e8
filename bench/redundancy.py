"""Benchmark: what a redundant arm's free-parameter rule costs the RCCL control cycle (the Panda).

Runs each generator alone (no link, no simulator, as bench/rccl_cycle.py does) on the Panda's
generated kinematics (rccl.kinematics.panda: the closed-form IK with q7 given) over a tour of
Cartesian straight lines out and back (10 cm, with a quarter turn of rotation), once per
free-parameter rule of rccl.redundancy (``setfree``): q7 held (the default), q7 a function
of time, the optimising rule 'far' (each sample FAR_CANDIDATES inverse kinematics, 6x7
Jacobians and singular value decompositions); and a self-motion. Writes
``reports/bench-redundancy.md``: mean, median, p99 and max per cycle (CPU time of the
calling thread, garbage collector off), the load average before and after, and the share of
the cycle period at 36 Hz (the thesis's rate) and at 1 kHz (the Panda's own controller).

    .venv/bin/python bench/redundancy.py                 # writes reports/bench-redundancy.md
    .venv/bin/python bench/redundancy.py --cycles 2000 --out -    # print only
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

from bench.output import emit  # noqa: E402
from rccl.jerk import JerkLimitedGenerator  # noqa: E402
from rccl.limits import load_limits  # noqa: E402
from rccl.planner import Planner  # noqa: E402
from rccl.position import EQ, TL, joint_position, makeposition  # noqa: E402
from rccl.redundancy import FAR_CANDIDATES  # noqa: E402
from rccl.session import load_kinematics  # noqa: E402
from rccl.trajectory import TrajectoryGenerator  # noqa: E402
from rccl.transform import T6, Trsf, rot_matrix  # noqa: E402

COMMAND = ".venv/bin/python bench/redundancy.py"
ROBOT = "panda"
RATE_HZ = 36
GENERATORS = {"quartic": TrajectoryGenerator, "ruckig": JerkLimitedGenerator}
RULES = ("hold", "time", "far", "selfmove")


def targets(t0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The tour's two ends: the start pose and 10 cm away turned 0.25 rad about the tool's z."""
    t1 = t0.copy()
    t1[:3, 3] += [0.06, 0.05, -0.06]
    t1[:3, :3] = t1[:3, :3] @ rot_matrix("z", 0.25)
    return t0, t1


def program(pl: Planner, rule: str, ready: np.ndarray) -> None:
    """Queue one leg of the tour under ``rule``: back to the ready joints (joint mode, q7 too),
    then the line out under the rule (or a self-motion)."""
    t0, t1 = targets(pl.kin.fk(ready))
    pl.setfree("hold")
    pl.setmod("j")
    pl.setvel(0.1, 0.5)
    pl.move(joint_position("ready", pl.kin, ready))
    pl.setmod("c")
    if rule == "selfmove":
        pl.selfmove(q7=float(ready[6]) - 0.3, duration=1.0)
        return
    if rule == "time":
        start = float(ready[6])
        pl.setfree(q7=lambda t: start + 0.2 * math.sin(2.0 * t))
    elif rule == "far":
        pl.setfree("far")
    pl.move(makeposition("B", T6, EQ, Trsf("B", t1), TL, T6))


def run(kind: str, rule: str, cycles: int) -> dict:
    """Per-cycle CPU times (us) of ``cycles`` generator steps on the tour under ``rule``."""
    from rcci.models import load_robot
    kin, limits = load_kinematics(ROBOT), load_limits(ROBOT)
    q0 = np.array(load_robot(ROBOT).poses["ready"], dtype=float)
    gen = GENERATORS[kind](kin, limits, 1.0 / RATE_HZ, q0)
    pl = Planner(kin, limits, gen)
    times = np.empty(cycles)
    gc.disable()
    try:
        for i in range(cycles):
            if not gen.busy:
                program(pl, rule, q0)
            t = time.thread_time_ns()
            gen.step()
            times[i] = (time.thread_time_ns() - t) / 1e3
            if gen.faulted is not None:
                raise RuntimeError(f"{kind}/{rule}: {gen.faulted}")
    finally:
        gc.enable()
    return {"kind": kind, "rule": rule, "mean": float(times.mean()), "median": float(np.median(times)),
            "p99": float(np.percentile(times, 99)), "max": float(times.max())}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cycles", type=int, default=3000, help="cycles per row")
    ap.add_argument("--out", default=str(ROOT / "reports" / "bench-redundancy.md"), help="'-' to print only")
    args = ap.parse_args(argv)
    from rccl.kinematics import backend as kb
    compiled = ", ".join(f"{r} {'compiled C' if kb.c_module(r) is not None else 'Python (C NOT built)'}"
                         for r in ("panda",))
    load_before = os.getloadavg()
    rows = [run(kind, rule, args.cycles) for kind in GENERATORS for rule in RULES]
    load_after = os.getloadavg()
    lines = [
        "# Redundancy: the free parameter's rules in the RCCL control cycle (Panda)",
        "",
        f"Rebuilt by `{COMMAND}` on {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}: each generator's "
        "`step()` alone",
        f"(`time.thread_time_ns` around each call, garbage collector off) at {RATE_HZ} Hz, {args.cycles} cycles "
        "per row, on a tour",
        "of joint-mode moves to the ready joints, each followed by a Cartesian line out (10 cm, 0.25 rad) under the",
        f"rule; *selfmove* by a 1 s self-motion of 0.3 rad instead. Kinematics: the generated "
        f"`rccl.kinematics.panda` (closed-form IK with q7 given), {compiled}.",
        f"Machine: {platform.processor() or platform.machine()}, Python {platform.python_version()}, "
        f"{os.cpu_count()} cores. **Load average** (1, 5, 15 min) before: "
        f"{load_before[0]:.2f}, {load_before[1]:.2f}, {load_before[2]:.2f}; after: "
        f"{load_after[0]:.2f}, {load_after[1]:.2f}, {load_after[2]:.2f}"
        + (" (quiet)." if load_before[0] < 1.0 else
           " (**not quiet**: other work shared the cores; the p99 and max above all are indicative)."),
        "",
        f"The optimising rule ('far') solves {FAR_CANDIDATES} inverse kinematics per sample and takes the",
        "6x7 Jacobian's singular values of each; the others one inverse kinematics per sample.",
        "",
        "| generator | rule | mean (us) | median (us) | p99 (us) | max (us) | p99 / 36 Hz period | p99 / 1 kHz period |",
        "|---|---|---:|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        lines.append(f"| {r['kind']} | {r['rule']} | {r['mean']:.1f} | {r['median']:.1f} | {r['p99']:.1f} | "
                     f"{r['max']:.1f} | {100 * r['p99'] * RATE_HZ / 1e6:.2f}% | {100 * r['p99'] / 1e3:.1f}% |")
    emit("\n".join(lines) + "\n", args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
