"""Static friction coefficients from breakaway ramps (thesis 4.5.5, first method, Table 4.5)."""
from __future__ import annotations

import os

from rcci.calib.fitting import FitOutcome, merge_joint_values
from rcci.calib.registry import FitKind, RecordRequest, RegenContext, ReportContext
from rcci.calib.report import joint_truth
from rcci.calib.tables import table_4_5

KEYS = ("static_pos", "static_neg")


def fit(traces, info, params, inputs, notes) -> FitOutcome:
    from rcci.calib.breakaway import fit_breakaway

    joints = sorted({t.joint_index() for t in traces})
    drive = info.drive.with_sigma(inputs.sigma(joints))
    res, pts = fit_breakaway(traces, drive, inputs.gravity_model(), notes)
    js = [r.joint for r in res]
    old = dict(params.get("friction") or {})
    sec = dict(old)
    for key, get in zip(KEYS, (lambda r: r.plus, lambda r: r.minus)):
        sec[key] = merge_joint_values(old, key, js, [get(r) for r in res])
    return FitOutcome("breakaway", table_4_5(res), {"friction": sec}, res, {"points": pts})


def report(ctx: ReportContext, out: FitOutcome) -> list[str]:
    from rcci.calib.breakaway import TOLERANCE

    fr = ctx.info.nominal["friction"]
    L = ["## Table 4.5: static friction coefficients F_s (N m)", "",
         "The thesis tuned these by hand (4.5.5, first method: the current raised until the "
         "joint could just be moved). `calib record breakaway` does it without a hand: at "
         "the friction pose and 20 degrees either side, the joint is switched to current "
         "mode and its motor torque ramped up from the gravity balance until the encoder "
         "moves; the torque at that moment (the line through the ramp's last 0.4 s of "
         "readings, read 15.5 ms later for the filter) minus gravity is F_s. The thesis "
         "states no uncertainty for Table 4.5; the tolerance is this project's "
         "(`rcci.calib.breakaway.TOLERANCE`: 5 %, 10 % on joint 4, whose single ramps spread "
         "by 10 %). The truth is simula's breakaway threshold; where Table 4.4's variation lifts "
         "the kinetic friction above F_s (joint 4), a joint can only move once the torque also "
         "exceeds that.", "",
         "| joint | dir | thesis | truth | fit mean | sd of ramps | abs(fit - truth) | tolerance | within |",
         "|---|---|---|---|---|---|---|---|---|"]
    for r in out.results:
        j = r.joint - 1
        for name, fit_, sd, key in (("+", r.plus, r.plus_std, "static_pos"), ("-", r.minus, r.minus_std, "static_neg")):
            th = fr[key]["values"][j]
            ts, tv = joint_truth(ctx.truth, key, j, ".3f")
            d, tol = abs(fit_ - tv), TOLERANCE[r.joint]
            L.append(f"| {r.joint} | {name} | {th:.3f} | {ts} | {fit_:.3f} | {sd:.3f} | {d:.3f} | "
                     f"{100 * tol:.0f} % | "
                     + (f"{ctx.check('4.5', d <= tol * tv)} |" if ctx.truth is not None else "- |"))
    return L + [""]


def record(req: RecordRequest) -> None:
    from rcci.calib.breakaway_program import breakaway_plans, run_breakaway

    static = req.info.nominal["friction"]["static_pos"]["values"]
    for plan in breakaway_plans(static, req.info.drive.G, req.joints, req.info):
        path = os.path.join(req.out, plan.name + ".rcilog")
        n = run_breakaway(req.url, plan, path, req.robot, extra_meta=req.extra_meta)
        print(f"{plan.name}: {n} records -> {path}")


def regen(ctx: RegenContext) -> list:
    """The ramps, every joint whose torque calib measures, on a simula of their own (so that `--kinds breakaway` alone
    records the same logs); recorded here, nothing left for the shared simula."""
    from rcci.calib.breakaway_program import breakaway_plans
    from rcci.calib.fits.gravity import require_gravity
    from rcci.calib.regen import record_breakaway
    from rcci.calib.registry import OwnSimula

    require_gravity(ctx.info, "breakaway")

    static = ctx.info.nominal["friction"]["static_pos"]["values"]
    names = tuple(p.name for p in breakaway_plans(static, ctx.info.drive.G, ctx.measured_joints("breakaway"), ctx.info))
    return [(("own",), OwnSimula("breakaway", lambda: record_breakaway(ctx), names))]


KIND = FitKind(
    name="breakaway", title="static friction coefficients from breakaway ramps (Table 4.5)", section="friction",
    merge_keys=KEYS, order=5, record_order=1, report_order=2, fit=fit, report=report, record=record, regen=regen)
