"""Benchmark: blending through queued positions, the quartic generator beside the jerk-limited one (Ruckig).

Queues a tour of four positions at once (the first three 5-7 cm apart, the last back at
the start) on the PUMA 260 and steps each generator alone (no link: the trajectory is
deterministic) at 36 Hz until the arm rests at the last one. For joint and Cartesian mode
it reports the tour's total time, the path's deviation at each blended corner (the
closest the tool point comes to the corner, mm), the lowest tool speed near a corner (0:
the arm stopped there), the peak tool speed and the peak joint acceleration over its
limit (finite differences of the commanded samples). Ruckig runs twice: blending (a queued
position becomes Ruckig's target while the arm still moves, ``rccl.jerk``) and with
``blend = False`` (every move from rest to rest, the behaviour before issue 25).

    .venv/bin/python bench/rccl_blend.py          # writes its section of reports/bench-rccl.md
    .venv/bin/python bench/rccl_blend.py --out -  # print only
"""
from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from rccl.jerk import JerkLimitedGenerator  # noqa: E402
from rccl.limits import load_limits  # noqa: E402
from rccl.planner import Planner  # noqa: E402
from rccl.position import EQ, TL, makeposition  # noqa: E402
from rccl.session import load_kinematics  # noqa: E402
from rccl.trajectory import TrajectoryGenerator  # noqa: E402
from rccl.transform import T6, Trsf, rot, trsl  # noqa: E402

COMMAND = ".venv/bin/python bench/rccl_blend.py"
HEADING = "## Blending through queued positions: quartic vs Ruckig"
ROBOT = "puma260"
START = np.radians([0.0, 80.0, -170.0, 10.0, -60.0, 0.0])
RATE_HZ = 36
SPEED = (0.1, 1.0)      # setvel: m/s, rad/s


def tour(kin):
    """Three corners around the start pose and back (the rccl_cycle tour's offsets)."""
    base = kin.fk(START)
    offsets = [trsl(0.05, 0.0, 0.0), trsl(0.05, 0.05, 0.02) @ rot("z", 0.2), trsl(0.0, 0.05, 0.0) @ rot("x", 0.1),
               trsl(0.0, 0.0, 0.0)]
    return [makeposition(f"p{i}", T6, EQ, Trsf(f"P{i}", o @ base), TL, T6) for i, o in enumerate(offsets)]


def run(kind: str, mode: str, blend: bool = True) -> dict:
    kin, limits = load_kinematics(ROBOT), load_limits(ROBOT)
    dt = 1.0 / RATE_HZ
    gen = (TrajectoryGenerator if kind == "quartic" else JerkLimitedGenerator)(kin, limits, dt, START)
    if kind == "ruckig":
        gen.blend = blend
    arm = Planner(kin, limits, gen)
    arm.setmod(mode)
    arm.setvel(*SPEED)
    positions = tour(kin)
    reqs = [arm.move(p) for p in positions]
    qs = [gen.q.copy()]
    while gen.busy and len(qs) < 60 * RATE_HZ:
        qs.append(gen.step().copy())
    if gen.errors or any(r.status != "done" for r in reqs):
        raise SystemExit(f"{kind} {mode}: {gen.errors[:2]} {[r.status for r in reqs]}")
    q = np.array(qs)
    pts = np.array([kin.fk(x)[:3, 3] for x in q])
    speed = np.linalg.norm(np.diff(pts, axis=0), axis=1) / dt
    moving = np.nonzero(speed > 1e-5)[0]
    total = (moving[-1] + 1 - moving[0]) * dt
    acc = np.abs(np.diff(q, n=2, axis=0)) / dt ** 2 / limits.joint_acceleration
    corners = [p.solve()[:3, 3] for p in positions[:-1]]
    dev, slow = [], []
    for c in corners:
        d = np.linalg.norm(pts - c, axis=1)
        k = int(np.argmin(d))
        dev.append(float(d[k]))
        lo, hi = max(k - 3, 0), min(k + 3, len(speed))
        slow.append(float(speed[lo:hi].min()))
    return {"kind": kind if blend or kind == "quartic" else "ruckig, from rest", "mode": mode, "total": total,
            "dev": dev, "slow": slow, "vmax": float(speed.max()), "acc": float(acc.max())}


def section(rows: list[dict]) -> str:
    lines = [HEADING, "",
             f"Rebuilt by `{COMMAND}`: a tour of four positions queued at once (three corners 5-7 cm apart with "
             f"small rotations, then back to the start) on the {ROBOT}, setvel {SPEED[0]} m/s and {SPEED[1]} rad/s, "
             f"each generator stepped alone at {RATE_HZ} Hz until the arm rests at the last position. *deviation*: "
             "the closest the tool point comes to each corner (mm); *corner speed*: the lowest tool speed within "
             "3 samples of it (mm/s; 0 = it stopped); *acc*: peak joint acceleration over its limit (finite "
             "differences of the commands).", "",
             "| generator | mode | total time (s) | deviation at corners 1, 2, 3 (mm) | corner speed (mm/s) | peak tool speed (m/s) | peak acc / limit |",
             "|---|---|---:|---|---|---:|---:|"]
    for r in rows:
        dev = ", ".join(f"{d * 1e3:.1f}" for d in r["dev"])
        slow = ", ".join(f"{s * 1e3:.0f}" for s in r["slow"])
        lines.append(f"| {r['kind']} | {r['mode']} | {r['total']:.2f} | {dev} | {slow} | {r['vmax']:.3f} | {r['acc']:.2f} |")
    by = {(r["kind"], r["mode"]): r for r in rows}
    for mode in ("joint", "cartesian"):
        q, b, s = by[("quartic", mode)], by[("ruckig", mode)], by[("ruckig, from rest", mode)]
        lines.append("")
        lines.append(f"{mode.capitalize()} mode: Ruckig blending takes {b['total']:.2f} s for the tour against "
                     f"{s['total']:.2f} s from rest to rest ({100 * (1 - b['total'] / s['total']):.0f}% less) and "
                     f"{q['total']:.2f} s for the quartic; its largest corner deviation is "
                     f"{max(b['dev']) * 1e3:.1f} mm (quartic {max(q['dev']) * 1e3:.1f} mm).")
    lines.append("")
    lines.append("Ruckig's Cartesian limits are per coordinate (the norm's limit over sqrt(3), `rccl.jerk`), so its "
                 "tool goes slower than setvel on a line that is not diagonal; a blended Cartesian move starts "
                 "moving and so falls back from phase to time synchronisation: its path curves through the corner.")
    return "\n".join(lines) + "\n"


def merge(path: Path, text: str, heading: str = HEADING) -> None:
    """Put ``text`` (a section starting with ``heading``) into ``path``, replacing an older one."""
    old = path.read_text() if path.exists() else ""
    pattern = re.compile(re.escape(heading) + r".*?(?=^## |\Z)", re.S | re.M)
    new = pattern.sub(lambda m: text + "\n", old) if pattern.search(old) else old.rstrip("\n") + "\n\n" + text
    path.write_text(new)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "reports" / "bench-rccl.md"), help="'-' to print only")
    a = ap.parse_args(argv)
    rows = []
    for mode in ("joint", "cartesian"):
        rows += [run("quartic", mode), run("ruckig", mode), run("ruckig", mode, blend=False)]
    text = section(rows)
    print(text)
    if a.out != "-":
        merge(Path(a.out), text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
