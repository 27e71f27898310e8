"""Typical static friction at random halts (thesis 4.5.5, second method, Table 4.6)."""
from __future__ import annotations

from rcci.calib.fitting import FitOutcome
from rcci.calib.registry import FitKind, RecordRequest, RegenContext, ReportContext
from rcci.calib.report import joint_truth
from rcci.calib.static import fit_static
from rcci.calib.tables import table_4_6


def fit(traces, info, params, inputs, notes) -> FitOutcome:
    from rcci.calib.unmeasured import unmeasured_joints, why_unmeasured

    left = unmeasured_joints(info.name)
    joints = [j for j in range(len(info.lower)) if j + 1 not in left]
    drive = info.drive.with_sigma(inputs.sigma(joints))
    res, samples = fit_static(traces, drive, inputs.gravity_model(), notes)
    if left:            # halted with the others, but their torque is not measured
        res = [r for r in res if r.joint not in left]
        notes.append(f"static: joint(s) {', '.join(map(str, left))} not fitted: {why_unmeasured(info.name)}")
    sec = {"samples": int(res[0].samples),
           "maximum": [r.maximum for r in res], "minimum": [r.minimum for r in res],
           "mean": [r.mean for r in res], "std": [r.std for r in res], "unit": "N*m"}
    return FitOutcome("static", table_4_6(res), {"static_friction": sec}, res, {"samples": samples})


def report(ctx: ReportContext, out: FitOutcome) -> list[str]:
    res = out.results
    fr = ctx.info.nominal["friction"]
    L = [f"## Table 4.6: typical static friction over {res[0].samples} random halts (N m)", "",
         "simula leaves a servoed joint that halts holding a residual static friction drawn "
         "from the truth's Table 4.6 mean and standard deviation (clipped to Table 4.5); the "
         "extremes depend on the draws.", "",
         "| joint | thesis max | fit max | thesis min | fit min | thesis mean | truth mean | fit mean "
         "| thesis std | truth std | fit std |",
         "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in res:
        j = r.joint - 1
        # the thesis's Table 4.6; "-" where the data file has none (an arm the thesis did not measure)
        t = [f"{fr[k]['values'][j]:.3f}" if k in fr else "-"
             for k in ("static_typical_max", "static_typical_min", "static_typical_mean", "static_typical_std")]
        tm, _ = joint_truth(ctx.truth, "hold_mean", j, ".3f")
        ts, _ = joint_truth(ctx.truth, "hold_std", j, ".3f")
        L.append(f"| {r.joint} | {t[0]} | {r.maximum:.3f} | {t[1]} | {r.minimum:.3f} | "
                 f"{t[2]} | {tm} | {r.mean:.3f} | {t[3]} | {ts} | {r.std:.3f} |")
    return L + [""]


def record(req: RecordRequest) -> None:
    from rcci.calib.experiments import static_plan
    from rcci.calib.program import record_plans

    record_plans(req, [static_plan(req.info.lower, req.info.upper, halts=req.args.halts or 275,
                                   vmax=_vmax(req.info.name))])


def regen(ctx: RegenContext) -> list:
    from rcci.calib.experiments import static_plan
    from rcci.calib.fits.gravity import require_gravity

    require_gravity(ctx.info, "static")

    halts = ctx.options.halts
    return [((), static_plan(ctx.info.lower, ctx.info.upper, vmax=_vmax(ctx.info.name),
                             **({} if halts is None else {"halts": halts})))]


def _vmax(robot: str):
    """The arm's joint velocity limits (rad/s, m/s on a slide): the halts' moves stay within them."""
    from rcci.models import load_robot

    return load_robot(robot).max_velocity


KIND = FitKind(
    name="static", title="typical static friction at random halts (Table 4.6)", section="static_friction",
    merge_keys=(), order=4, record_order=4, report_order=3, fit=fit, report=report, record=record, regen=regen)
