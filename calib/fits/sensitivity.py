"""Motor torque sensitivities (thesis 4.5.2, Table 4.1): a pulley's mass lifted and not."""
from __future__ import annotations

import numpy as np

from rcci.calib.fitting import FitOutcome, merge_joint_values
from rcci.calib.registry import FitKind, RecordRequest, RegenContext, ReportContext
from rcci.calib.report import joint_truth, nominal_vector
from rcci.calib.sensitivity import fit_sensitivity
from rcci.calib.tables import slide_note, table_4_1

RADIUS_M = 0.05  # pulley drum radius (estimate: a 10 cm drum, Figure 4.2 is lost)
KEYS = ("torque_sensitivity", "torque_sensitivity_std", "torque_sensitivity_error", "torque_sensitivity_trials")


def fit(traces, info, params, inputs, notes) -> FitOutcome:
    res = fit_sensitivity(traces, info.drive, notes)
    joints = [r.joint for r in res]
    old = params.get("motors")
    values = (lambda r: r.mean, lambda r: r.std, lambda r: r.independent_error, lambda r: r.trials)
    sec = {key: merge_joint_values(old, key, joints, [get(r) for r in res]) for key, get in zip(KEYS, values)}
    sec["torque_sensitivity_trials"] = [int(x) if np.isfinite(x) else 0 for x in sec["torque_sensitivity_trials"]]
    sec["unit"] = "N*m/A"          # N/A on a prismatic joint (rcci.calib.tables.slide_note)
    text = "\n".join([table_4_1(res), *slide_note(info.kinds, joints, "sensitivity")])
    return FitOutcome("sensitivity", text, {"motors": sec}, res)


def report(ctx: ReportContext, out: FitOutcome) -> list[str]:
    thesis = nominal_vector(ctx.info, "motors", "torque_sensitivity")
    # the thesis's bound; an arm the thesis did not measure (the PUMA 560's data file) states none: "-"
    err = np.asarray(ctx.info.nominal["motors"]["torque_sensitivity"].get("uncertainty", [np.nan] * len(thesis)), float)
    L = ["## Table 4.1: motor torque sensitivity (N m / A)", "",
         "The fit's independent error is the thesis's kind (4.5.2): the relative uncertainties of "
         "the mass, the drum radius and the current scale V_g / R_i combined, an a priori bound, not "
         "a 99.73 % interval; the fit std is one standard deviation of the trials (the 99.73 % error "
         "of the mean that later fits inherit is Student's t x std / sqrt(trials)).",
         *slide_note(ctx.info.kinds, [r.joint for r in out.results], "sensitivity"), "",
         "| joint | thesis mean | thesis indep. error (a priori bound) | truth | fit mean | fit std (1 sd) | trials "
         "| fit indep. error (a priori bound) | abs(fit - truth) | within thesis bound | within fit error |",
         "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in out.results:
        j = r.joint - 1
        ts, tv = joint_truth(ctx.truth, "sigma", j, ".4f")
        d = abs(r.mean - tv)
        bound = f"{err[j]:.4f}" if np.isfinite(err[j]) else "-"
        L.append(f"| {r.joint} | {thesis[j]:.4f} | {bound} | {ts} | {r.mean:.4f} | {r.std:.4f} | "
                 f"{r.trials} | {r.independent_error:.4f} | {d:.4f} | "
                 + (f"{ctx.check('4.1', d <= err[j]) if np.isfinite(err[j]) else '-'} | "
                    f"{ctx.check('4.1 fit', d <= r.independent_error)} |" if ctx.truth is not None else "- | - |"))
    return L + [""]


def record(req: RecordRequest) -> None:
    from rcci.calib.experiments import sensitivity_plans
    from rcci.calib.program import record_plans

    notes: list[str] = []
    plans = sensitivity_plans(req.args.mass, req.args.radius or RADIUS_M, req.joints, robot=req.info, notes=notes)
    for note in notes:
        print(f"note: {note}")
    record_plans(req, [p for p in plans if (p.meta["load"]["mass_kg"] > 0) == req.args.loaded])


def regen(ctx: RegenContext) -> list:
    """Without the mass on the shared simula; with it, a simula with the pulley load per joint."""
    from rcci.calib.experiments import sensitivity_plans

    o = ctx.options
    plans = ctx.per_joint("sensitivity", lambda j: sensitivity_plans(o.mass, o.radius or RADIUS_M, [j], robot=ctx.info,
                                                                      notes=ctx.notes))
    return ([((), p) for p in plans if not p.simula_args]
            + [(tuple(p.simula_args), p) for p in plans if p.simula_args])


KIND = FitKind(
    name="sensitivity", title="motor torque sensitivities (Table 4.1)", section="motors", merge_keys=KEYS,
    order=0, record_order=5, report_order=0, fit=fit, report=report, record=record, regen=regen,
    missing_log="the loaded and unloaded runs cancel friction only together (4.43)")
