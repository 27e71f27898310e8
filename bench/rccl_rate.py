"""Benchmark: a rate change in the middle of a Cartesian move, on a lockstep simula, for both generators.

Issue 25, defect 1: ``chg.rate`` 36 -> 250 -> 1000 Hz during a 0.1 m Cartesian line at setvel
20 mm/s (1 s and 2 s after its start). Each generator runs the line twice, without and with
the changes, on one ``simula --lockstep`` process; speeds are measured against the robot's
clock (``how.time_ns``): the commanded tool speed (each command over the period the robot
runs it), the measured tool speed over 0.1 s windows (the joints simula reports, through
the forward kinematics), the commanded tool acceleration, and the line's duration.

    .venv/bin/python bench/rccl_rate.py          # writes its section of reports/bench-rccl.md
    .venv/bin/python bench/rccl_rate.py --out -  # print only
"""
from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import rccl  # noqa: E402
from bench.rccl_blend import merge  # noqa: E402
from rccl import EQ, T6, TL, Trsf, makeposition  # noqa: E402

COMMAND = ".venv/bin/python bench/rccl_rate.py"
HEADING = "## Rate change in the middle of a move (simula, lockstep)"
START = np.radians([10.0, 80.0, -170.0, 10.0, -60.0, 5.0])
SPEED, LENGTH = 0.02, 0.1          # m/s, m
CHANGES = ((1.0, 250), (2.0, 1000))


def line(url: str, kind: str, change: bool) -> dict:
    with rccl.open(url, "puma260", rate_hz=36, record=True, on_error="raise", timeout=5.0, trajectory=kind) as arm:
        arm.setmod("joint")
        arm.setvel(0.1, 2.0)
        s = makeposition("start", T6, EQ, Trsf("S", arm.kinematics.fk(START)), TL, T6)
        arm.move(s)
        arm.waitfor(s.end)
        t6 = arm.t6
        arm.setmod("cartesian")
        arm.setvel(SPEED, 0.5)
        goal = t6.copy()
        goal[0, 3] += LENGTH
        p = makeposition("goal", T6, EQ, Trsf("G", goal), TL, T6)
        n0 = len(arm.clock_trace)
        t0 = arm.gen.t
        arm.move(p)
        for at, rate in CHANGES if change else ():
            while arm.gen.t < t0 + at:
                time.sleep(0.0005)
            with arm.rci.chg.lock:
                arm.rci.chg.rate.issue(1, rate)
        arm.waitfor(p.end)
        arm.rci.wait(0.3)
        n1 = len(arm.clock_trace)
        fk = arm.kinematics.fk
        clock = np.array(arm.clock_trace[n0:n1])
        pc = np.array([fk(x[1])[:3, 3] for x in arm.trace[n0:n1]])
        pm = np.array([fk(x[2])[:3, 3] for x in arm.trace[n0:n1]])
        rates = [r for _, r in arm.rate_changes]
    period = np.diff(clock)
    v = np.diff(pc, axis=0)[:-1] / period[1:, None]
    speed = np.linalg.norm(v, axis=1)
    acc = np.linalg.norm(np.diff(v, axis=0), axis=1) / period[2:]
    moving = np.nonzero(speed > 1e-4)[0]
    window = [np.linalg.norm(pm[j] - pm[i]) / (clock[j] - clock[i])
              for i, j in ((i, int(np.searchsorted(clock, clock[i] + 0.1))) for i in range(len(clock))) if j < len(clock)]
    return {"kind": kind, "change": change, "rates": rates, "speed": float(speed.max()), "window": float(max(window)),
            "acc": float(acc.max()), "duration": float(clock[moving[-1] + 1] - clock[moving[0]])}


def section(rows: list[dict]) -> str:
    lines = [HEADING, "",
             f"Rebuilt by `{COMMAND}`: a {LENGTH * 1e3:.0f} mm Cartesian line at setvel {SPEED * 1e3:.0f} mm/s on "
             "a lockstep `simula --robot puma260`, without and with `chg.rate` 36 -> 250 -> 1000 Hz issued "
             f"{CHANGES[0][0]:.0f} s and {CHANGES[1][0]:.0f} s after its start. Against the robot's clock: the commanded "
             "tool speed (each command over the period the robot runs it), the measured one over 0.1 s windows, "
             "the commanded tool acceleration, the line's duration. Before the fix (issue 25's measurement) the generator kept its "
             "start-up period: 139 mm/s (quartic) and 331 mm/s (Ruckig) after the change, a 5 s move over in 1.65 s.", "",
             "| generator | rates | commanded speed max (mm/s) | measured speed max, 0.1 s (mm/s) | acceleration max (m/s^2) | duration (s) |",
             "|---|---|---:|---:|---:|---:|"]
    for r in rows:
        rates = "36 -> " + " -> ".join(map(str, r["rates"])) if r["rates"] else "36"
        lines.append(f"| {r['kind']} | {rates} | {r['speed'] * 1e3:.2f} | {r['window'] * 1e3:.2f} | {r['acc']:.3f} | "
                     f"{r['duration']:.3f} |")
    lines += ["", "Ruckig's tool runs at setvel / sqrt(3) on this line along x: its Cartesian limits are per "
              "coordinate (`rccl.jerk`)."]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    from rci.simula.process import SimulaProcess
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "reports" / "bench-rccl.md"), help="'-' to print only")
    a = ap.parse_args(argv)
    rows = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        with SimulaProcess("-p", "--power-on", robot="puma260", lockstep=True) as sim:
            for kind in ("quartic", "ruckig"):
                rows += [line(sim.url, kind, False), line(sim.url, kind, True)]
    text = section(rows)
    print(text)
    if a.out != "-":
        merge(Path(a.out), text, HEADING)
    return 0


if __name__ == "__main__":
    sys.exit(main())
