"""`calib regen-logs`: record the shipped logs (calib/logs/) on simula, from scratch.

Starts its own simula processes in lockstep (deterministic for a seed, as fast as the
machine allows), runs every measurement program against them through the RCI session
API and the recorder, and stores each log xz-compressed.  The sensitivity runs with
the mass need a simula started with the pulley load (``--load pulley:...``), one per
joint; the breakaway ramps and the kinematic touches (with the fixture and the probe,
``--env``) run on simulas of their own; everything else runs on one simula that, like
the real arm, keeps its state (position, warmth) from one program to the next.

``--params FILE`` gives every simula that parameter file, so the logs are recorded
against another truth than the data file's; each log's ``meta.truth`` says which
(seed, the file's path and text), and ``calib report`` compares with it.
"""
from __future__ import annotations

import argparse
import lzma
import os
import shutil
import time

from typing import Any

from rcci.calib import registry
from rcci.calib.exceptions import CalibError
from rcci.calib.experiments import MeasurementPlan
from rcci.calib.logs import LOG_DIR
from rcci.calib.program import run_plan
from rcci.calib.registry import OwnSimula, RecordOptions, RegenContext
from rcci.calib.robot import robot_info
from rcci.calib.truth import truth_meta

KINEMATIC_TOUCHES = 16  # per face of the corner: 48 touches for 22 identifiable errors
# s a recording on a lockstep simula waits for the other side: the session for a HOW (R_TIMEOUT)
# and simula for a CHG (its --lockstep-watchdog, 3 s by default). Lockstep is never late, only
# slow: at a load of 19-21 on 2 cores the PUMA 260 campaign of docs/calib.md stopped once on each
# (5 s without a HOW, the run_plan default; 3 s without a CHG). A dead simula is seen by its exit
# and a dead client by its closed connection, not by these. simula's is kept shorter: on Ctrl-C,
# RCI's release of a control in the middle of a lockstep exchange waits for simula to end it,
# so the campaign stops that many seconds after the Ctrl-C (120 s made a user wait 2 minutes)
LOCKSTEP_TIMEOUT_S = 120.0
LOCKSTEP_WATCHDOG_S = 15.0


def _process_args(args: list[str]) -> list[str]:
    """The words a campaign's simula is started with: ``args`` (those the logs' truth metadata
    records) and the lockstep watchdog's patience (LOCKSTEP_WATCHDOG_S), which is not a truth."""
    return [*args, f"--lockstep-watchdog={LOCKSTEP_WATCHDOG_S:g}"]


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


def _report_log(name: str, records: int, final: str, t0: float) -> None:
    print(f"{name:28s} {records:6d} records  {os.path.getsize(final) / 1e3:7.0f} kB"
          f"  {time.monotonic() - t0:6.1f} s", flush=True)


def _simula_args(params: str | None, extra: list[str]) -> list[str]:
    return (["--params", params] if params else []) + list(extra)


def _run(url: str, plan: MeasurementPlan, out_dir: str, work: str, seed: int, params: str | None,
         robot: str, rate: int | None = None, on_cycle=None) -> None:
    t0 = time.monotonic()
    raw = os.path.join(work, plan.name + ".rcilog")
    info = run_plan(url, plan, raw, robot, rate_hz=rate or plan.rate_hz,
                    extra_meta={"truth": truth_meta(seed, params, _simula_args(params, plan.simula_args))},
                    on_cycle=on_cycle, timeout=LOCKSTEP_TIMEOUT_S)
    _report_log(plan.name, info.records, _store(raw, out_dir), t0)


def finished(out_dir: str, name: str) -> bool:
    """True when the log ``name`` is recorded in ``out_dir`` (its .xz is written last, by rename)."""
    return os.path.exists(os.path.join(out_dir, name + ".rcilog.xz"))


class _Simula:
    """A lockstep simula that is started again if it dies (a program on it is then
    run once more from the arm's ready position; its warm-up makes up for the lost
    warmth)."""

    def __init__(self, args: tuple[str, ...], seed: int, params: str | None, robot: str) -> None:
        from rci.simula.process import SimulaProcess

        self.robot = robot
        self.make = lambda: SimulaProcess("-p", *_process_args(_simula_args(params, list(args))), robot=robot,
                                          lockstep=True, seed=seed)
        self.sim = self.make().start()

    def run(self, plan: MeasurementPlan, out_dir: str, work: str, seed: int, params: str | None,
            rate: int | None = None, on_cycle=None) -> None:
        try:
            _run(self.sim.url, plan, out_dir, work, seed, params, self.robot, rate, on_cycle)
        except CalibError as exc:
            if self.sim.proc is None or self.sim.proc.poll() is None:
                raise                                    # simula is alive: a real error
            print(f"{plan.name}: simula exited ({exc}); starting it again", flush=True)
            self.sim.stop()
            self.sim = self.make().start()
            _run(self.sim.url, plan, out_dir, work, seed, params, self.robot, rate, on_cycle)

    def stop(self) -> None:
        self.sim.stop()


def record_breakaway(ctx: RegenContext) -> None:
    """Table 4.5's breakaway ramps of the context's joints on a fresh lockstep simula (the
    ramps already recorded in its folder are not recorded again)."""
    from rcci.calib.breakaway_program import breakaway_plans, run_breakaway
    from rci.simula.process import SimulaProcess

    static = ctx.info.nominal["friction"]["static_pos"]["values"]
    args = _simula_args(ctx.params, [])
    todo = [p for p in breakaway_plans(static, ctx.info.drive.G, ctx.measured_joints("breakaway"), ctx.info)
            if not (ctx.resume and finished(ctx.out_dir, p.name))]
    if not todo:
        return
    with SimulaProcess("-p", *_process_args(args), robot=ctx.info.name, lockstep=True, seed=ctx.seed) as sim:
        for plan in todo:
            t0 = time.monotonic()
            raw = os.path.join(ctx.work, plan.name + ".rcilog")
            n = run_breakaway(sim.url, plan, raw, ctx.info.name, extra_meta={"truth": truth_meta(ctx.seed, ctx.params, args)})
            _report_log(plan.name, n, _store(raw, ctx.out_dir), t0)


def record_dynamics(ctx: RegenContext) -> None:
    """The excitation logs (rcci.calib.excitation_program) not yet in the context's folder, on a fresh
    lockstep simula started with --dynamic (current mode with the full dynamics) and --warm."""
    from rcci.calib.excitation_program import excitation_plans, run_excitation
    from rcci.calib.truth import truth_meta
    from rci.simula.process import SimulaProcess

    args = _simula_args(ctx.params, ["--dynamic", "--warm"])
    plans = [p for p in excitation_plans(ctx.info.name) if not (ctx.resume and finished(ctx.out_dir, p.name))]
    if not plans:
        return
    with SimulaProcess("-p", *_process_args(args), robot=ctx.info.name, lockstep=True, seed=ctx.seed) as sim:
        for plan in plans:
            t0 = time.monotonic()
            raw = os.path.join(ctx.work, plan.name + ".rcilog")
            n = run_excitation(sim.url, plan, raw, ctx.info.name,
                               extra_meta={"truth": truth_meta(ctx.seed, ctx.params, args)})
            _report_log(plan.name, n, _store(raw, ctx.out_dir), t0)


def record_kinematics(out_path: str, seed: int, params: str | None,
                      touches_per_face: int = KINEMATIC_TOUCHES, plan_seed: int = 1985,
                      robot: str = "puma260") -> int:
    """The kinematic touches of ``robot`` (default the thesis's arm) on a fresh lockstep simula
    with the fixture and the probe (``--env``, rcci.calib.touch.simula_words); returns the records logged."""
    from rcci.calib.touch import simula_words, touch_plan
    from rcci.calib.touch_program import run_touches
    from rci.simula.process import SimulaProcess

    plan = touch_plan(touches_per_face, seed=plan_seed, robot=robot)
    env = [w for word in simula_words(plan.fixture, plan.tip) for w in ("--env", word)]
    args = _simula_args(params, env)
    with SimulaProcess("-p", *_process_args(args), robot=robot, lockstep=True, seed=seed) as sim:
        return run_touches(sim.url, plan, out_path, robot, extra_meta={"truth": truth_meta(seed, params, args)})


def record_kinematics_log(ctx: RegenContext) -> None:
    """The shipped kinematics log: :func:`record_kinematics`, compressed into ``ctx.out_dir``
    (``ctx.options.touches`` in all, spread over the fixture's three faces)."""
    t0 = time.monotonic()
    raw = os.path.join(ctx.work, "kinematics.rcilog")
    touches = ctx.options.touches
    n = record_kinematics(raw, ctx.seed, ctx.params, robot=ctx.info.name,
                          touches_per_face=KINEMATIC_TOUCHES if touches is None else max(1, touches // 3))
    _report_log("kinematics", n, _store(raw, ctx.out_dir), t0)


def campaign_plans(ctx: RegenContext, kinds: tuple[str, ...], skip_refused: bool = False
                   ) -> tuple[list[tuple[tuple[str, ...], Any]], dict[str, str]]:
    """Every program of ``kinds`` in record_order, as (simula args, plan or OwnSimula), and the
    kinds refused with the reason (only with ``skip_refused``: else the refusal is raised).
    ``ctx.options.rate`` (--rate) is set on every MeasurementPlan (the kinds that take it: the
    others, whose programs are OwnSimula, were refused it by rcci.calib.cli_extra.record_options)."""
    plans: list[tuple[tuple[str, ...], Any]] = []
    refused: dict[str, str] = {}
    for kind in registry.kinds("record_order"):
        if kind.name not in kinds:
            continue
        try:
            mine = kind.regen(ctx)
        except CalibError as exc:
            if not skip_refused:
                raise
            refused[kind.name] = str(exc)
            continue
        if ctx.options.rate is not None:      # --rate: the kinds that take it (cli_extra.OPTIONS)
            for _, plan in mine:
                if isinstance(plan, MeasurementPlan):
                    plan.rate_hz = ctx.options.rate
        plans += mine
    return plans, refused


def regen(out_dir: str, seed: int, kinds: tuple[str, ...], params: str | None = None,
          quiet: bool = False, robot: str = "puma260", options: RecordOptions | None = None,
          skip_refused: bool = False, resume: bool = False) -> dict[str, Any]:
    """Record every log of ``kinds`` of ``robot`` (default the thesis's arm) into ``out_dir``
    (against simula with ``params``), with its progress unless ``quiet`` (rcci.calib.progress.Steps:
    a bar naming the program in hand on a terminal, lines on stderr elsewhere). With ``resume``, logs already in ``out_dir`` are not recorded
    again (a campaign resumes after an interruption). Every program is planned before the first is recorded, so a
    refusal costs no recording; with ``skip_refused`` a kind the arm cannot support is left out
    and its reason returned. On an error the raw logs of ``out_dir/.work`` are kept (the error
    names the partial log). Returns {"recorded": names, "skipped": names, "refused": {kind:
    reason}, "notes": [...], "seconds": wall time}."""
    from rcci.calib.progress import Steps

    t0 = time.monotonic()
    info = robot_info(robot)
    os.makedirs(out_dir, exist_ok=True)
    work = os.path.join(out_dir, ".work")
    os.makedirs(work, exist_ok=True)
    ctx = RegenContext(out_dir, work, seed, params, info, options or RecordOptions(), resume=resume)
    plans, refused = campaign_plans(ctx, kinds, skip_refused)
    for kind, why in refused.items():
        print(f"{kind}: not recorded on {robot}: {why}", flush=True)
    for note in ctx.notes:
        print(f"note: {note}", flush=True)
    def recorded(plan) -> bool:
        names = plan.log_names() if isinstance(plan, OwnSimula) else (plan.name,)
        return resume and all(finished(out_dir, n) for n in names)

    done = [p.name for _, p in plans if recorded(p)]
    todo = [(a, p) for a, p in plans if not recorded(p)]
    if done:
        print(f"{len(done)} log(s) already in {out_dir}, not recorded again: {', '.join(done)}", flush=True)
    sims: dict[tuple[str, ...], _Simula] = {}
    ok = False
    try:
        with Steps(len(todo), "recording", enabled=False if quiet else None) as steps:
            # in record_order: programs that share a simula keep its state (position, warmth)
            for args, plan in todo:
                steps.start(plan.name)
                if isinstance(plan, OwnSimula):
                    plan.run()
                else:
                    if args not in sims:
                        if args:           # a pulley simula lives for its one program
                            for key in [k for k in sims if k]:
                                sims.pop(key).stop()
                        sims[args] = _Simula(args, seed, params, robot)
                    sims[args].run(plan, out_dir, work, seed, params, ctx.options.rate, steps.within)
                steps.finish()
        ok = True
    finally:
        for sim in sims.values():
            sim.stop()
        if ok:
            shutil.rmtree(work, ignore_errors=True)
        else:
            print(f"stopped after {(time.monotonic() - t0) / 60:.1f} min; partial logs kept in {work} (a rerun "
                  "of the same command resumes: finished logs are not recorded again)", flush=True)
    seconds = time.monotonic() - t0
    print(f"recorded {len(todo)} log(s) in {seconds / 60:.1f} min"
          + (f" ({len(done)} already there)" if done else ""), flush=True)
    return {"recorded": [p.name for _, p in todo], "skipped": done, "refused": refused,
            "notes": list(ctx.notes), "seconds": seconds}


def check_truth_file(params: str, robot: str) -> None:
    """Refuse a simula parameter file simula would refuse, before hours of recording."""
    from rcci.models import load_robot
    from rci.simula.exceptions import ParamsError
    from rci.simula.params import load_params, truth_from_model

    try:
        load_params(params, robot, truth_from_model(load_robot(robot)))
    except ParamsError as exc:
        raise CalibError(str(exc)) from None


def _main(args: argparse.Namespace) -> int:
    known = registry.names("record_order")
    kinds = tuple(args.kinds.split(",")) if args.kinds else known
    bad = set(kinds) - set(known)
    if bad:
        raise SystemExit(f"calib regen-logs: unknown kind(s) {sorted(bad)}; known: {', '.join(known)}")
    if args.params:
        check_truth_file(args.params, args.robot)
    regen(args.out, args.seed, kinds, args.params, quiet=args.quiet, robot=args.robot, resume=args.resume)
    return 0


def add_regen(sub: Any) -> None:
    """Register `regen-logs` on the `calib` parser (``sub``: its subparsers)."""
    p = sub.add_parser("regen-logs", help="record the shipped logs on simula (lockstep) from scratch")
    p.add_argument("--out", default=LOG_DIR, metavar="DIR",
                   help=f"folder the logs are written to (created if missing; default {LOG_DIR})")
    p.add_argument("--seed", type=int, default=1985, help="simula's seed (reproducible logs)")
    p.add_argument("--kinds", help=f"comma-separated subset of {','.join(registry.names('record_order'))}")
    p.add_argument("--params", metavar="FILE",
                   help="simula parameter file: the truth to record against (default: the robot data file)")
    p.add_argument("--robot", default="puma260",
                   help="the arm's model (models/ROBOT.toml), default puma260 (the shipped logs' arm)")
    p.add_argument("--resume", action="store_true",
                   help="do not record again the logs already in --out (after an interruption)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_main)
