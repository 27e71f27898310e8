"""`calib regen-logs`: record the shipped logs (calib/logs/) on simula, from scratch.

Starts its own simula processes in lockstep (deterministic for a seed, as fast as the
machine allows), runs every measurement program against them through the RCI session
API and the recorder, and stores each log xz-compressed.  The sensitivity runs with
the mass need a simula started with the pulley load (``--load pulley:...``), one per
joint; everything else runs on one simula that, like the real arm, keeps its state
(position, warmth) from one program to the next.
"""
from __future__ import annotations

import argparse
import lzma
import os
import shutil
import time

from calib.errors import CalibError
from calib.experiments import (Plan, friction_plans, gravity_plans, sensitivity_plans,
                               static_plan)
from calib.program import run_plan
from calib.robot import robot_info

KINDS = ("friction", "gravity", "static", "sensitivity", "breakaway")
RADIUS_M = 0.05  # pulley drum radius (estimate: a 10 cm drum, Figure 4.2 is lost)


def _store(raw: str, out_dir: str) -> str:
    """Compress ``raw`` into ``out_dir`` as xz (no time stamp inside, so the same log
    gives the same bytes), atomically: temp name, then rename."""
    final = os.path.join(out_dir, os.path.basename(raw) + ".xz")
    tmp = final + ".tmp"
    with open(raw, "rb") as f, lzma.open(tmp, "wb", preset=9 | lzma.PRESET_EXTREME) as g:
        shutil.copyfileobj(f, g)
    os.replace(tmp, final)
    os.unlink(raw)
    return final


def _run(url: str, plan: Plan, out_dir: str, work: str, seed: int) -> None:
    t0 = time.monotonic()
    raw = os.path.join(work, plan.name + ".rcilog")
    info = run_plan(url, plan, raw, rate_hz=plan.rate_hz,
                    extra_meta={"simula_seed": seed, "simula_args": plan.simula_args})
    final = _store(raw, out_dir)
    print(f"{plan.name:28s} {info.records:6d} records  {os.path.getsize(final) / 1e3:7.0f} kB"
          f"  {time.monotonic() - t0:6.1f} s", flush=True)


class _Simula:
    """A lockstep simula that is started again if it dies (a program on it is then
    run once more from the arm's ready position; its warm-up makes up for the lost
    warmth)."""

    def __init__(self, args: tuple[str, ...], seed: int) -> None:
        from rci.simula.process import SimulaProcess

        self.make = lambda: SimulaProcess("-p", *args, lockstep=True, seed=seed)
        self.sim = self.make().start()

    def run(self, plan: Plan, out_dir: str, work: str, seed: int) -> None:
        try:
            _run(self.sim.url, plan, out_dir, work, seed)
        except CalibError as exc:
            if self.sim.proc is None or self.sim.proc.poll() is None:
                raise                                    # simula is alive: a real error
            print(f"{plan.name}: simula exited ({exc}); starting it again", flush=True)
            self.sim.stop()
            self.sim = self.make().start()
            _run(self.sim.url, plan, out_dir, work, seed)

    def stop(self) -> None:
        self.sim.stop()


def _breakaway(out_dir: str, work: str, seed: int, info) -> None:
    """Table 4.5's breakaway ramps, every joint, on a fresh lockstep simula."""
    from calib.breakaway_program import breakaway_plans, run_breakaway
    from rci.simula.process import SimulaProcess

    static = info.nominal["friction"]["static_pos"]["values"]
    with SimulaProcess("-p", lockstep=True, seed=seed) as sim:
        for plan in breakaway_plans(static, info.drive.G):
            t0 = time.monotonic()
            raw = os.path.join(work, plan.name + ".rcilog")
            n = run_breakaway(sim.url, plan, raw, extra_meta={"simula_seed": seed, "simula_args": []})
            final = _store(raw, out_dir)
            print(f"{plan.name:28s} {n:6d} records  {os.path.getsize(final) / 1e3:7.0f} kB"
                  f"  {time.monotonic() - t0:6.1f} s", flush=True)


def regen(out_dir: str, seed: int, kinds: tuple[str, ...]) -> None:
    """Record every log of ``kinds`` into ``out_dir``."""
    info = robot_info("puma260")
    os.makedirs(out_dir, exist_ok=True)
    work = os.path.join(out_dir, ".work")
    os.makedirs(work, exist_ok=True)
    plans: list[tuple[tuple[str, ...], Plan]] = []
    if "friction" in kinds:
        plans += [((), p) for p in friction_plans()]
    if "gravity" in kinds:
        plans += [((), p) for p in gravity_plans(info.regressor, info.lower, info.upper)]
    if "static" in kinds:
        plans.append(((), static_plan(info.lower, info.upper)))
    if "sensitivity" in kinds:
        sens = sensitivity_plans(None, RADIUS_M)
        plans += [((), p) for p in sens if not p.simula_args]        # without the mass
        plans += [(tuple(p.simula_args), p) for p in sens if p.simula_args]
    sims: dict[tuple[str, ...], _Simula] = {}
    try:
        if "breakaway" in kinds:
            # on a simula of its own, so that `--kinds breakaway` alone records the same logs
            _breakaway(out_dir, work, seed, info)
        for args, plan in plans:
            if args not in sims:
                if args:           # a pulley simula lives for its one program
                    for key in [k for k in sims if k]:
                        sims.pop(key).stop()
                sims[args] = _Simula(args, seed)
            sims[args].run(plan, out_dir, work, seed)
    finally:
        for sim in sims.values():
            sim.stop()
        shutil.rmtree(work, ignore_errors=True)


def _main(args: argparse.Namespace) -> int:
    kinds = tuple(args.kinds.split(",")) if args.kinds else KINDS
    bad = set(kinds) - set(KINDS)
    if bad:
        raise SystemExit(f"calib regen-logs: unknown kind(s) {sorted(bad)}; known: {', '.join(KINDS)}")
    regen(args.out, args.seed, kinds)
    return 0


def add_regen(sub: argparse._SubParsersAction) -> None:
    """Register `regen-logs` on the `calib` parser."""
    from calib.cli_extra import LOG_DIR

    p = sub.add_parser("regen-logs", help="record the shipped logs on simula (lockstep) from scratch")
    p.add_argument("--out", default=LOG_DIR)
    p.add_argument("--seed", type=int, default=1985, help="simula's seed (reproducible logs)")
    p.add_argument("--kinds", help=f"comma-separated subset of {','.join(KINDS)}")
    p.set_defaults(func=_main)
