"""Gravity loading coefficients (thesis 4.5.6, Tables 4.8 and 4.9): sweeps and their repeats."""
from __future__ import annotations

from typing import Any

import numpy as np

from rcci.calib.fitting import FitOutcome
from rcci.calib.gravity import fit_gravity, row_result
from rcci.calib.registry import FitKind, RecordRequest, RegenContext, ReportContext
from rcci.calib.tables import combination, table_4_8_4_9

THESIS_4_8 = {  # Table 4.8: (position, joint) -> (tau0 in c, (W_g2 - W_g1)/2), as printed but for j3A
    ("j5", 5): ("c15", -1.191), ("j4", 4): ("c15", -1.193), ("j3B", 3): ("c13", -1.744),
    ("j2", 2): ("c12", 5.509), ("j3B", 2): ("c12 - c13", 7.288),
    # printed -1.938: an OCR misreading of -2.938. The row's own result c15 = -1.194 with the
    # c13 = -1.744 of row j3B/3 needs c13 + c15 = -2.938 (-1.938 would give c15 = -0.194,
    # six times smaller than every other c15), and Table 4.9's c13 + c15 is -2.954
    ("j3A", 3): ("c13 + c15", -2.938),
}
J3A_NOTE = ("j3A/3's thesis value is -2.938, not the -1.938 of the OCR text: the row's own result "
            "c15 = -1.194 with row j3B/3's c13 = -1.744 needs c13 + c15 = -2.938 (-1.938 would give "
            "c15 = -0.194), and Table 4.9's c13 + c15 = -1.762 - 1.192 = -2.954.")


def thesis_4_9(info) -> dict[str, tuple[float, float, float]] | None:
    """Table 4.9 as the arm's data file holds it (value, uncertainty, friction error per
    coefficient), when every coefficient's source is the thesis's table; None for an arm
    the thesis did not measure (its report then has no thesis columns)."""
    coeffs = info.nominal.get("gravity_coeffs", {})
    fe = info.nominal.get("gravity_friction_error", {})
    friction = dict(zip(fe.get("names", []), fe.get("values", [])))
    if not coeffs or not all(str(c.get("source", "")).startswith("thesis Table 4.9") and "uncertainty" in c
                             and n in friction for n, c in coeffs.items()):
        return None
    return {n: (float(c["value"]), float(c["uncertainty"]), float(friction[n])) for n, c in coeffs.items()}


def fit(traces, info, params, inputs, notes) -> FitOutcome:
    joints = sorted({t.joint_index() for t in traces})
    drive = info.drive.with_sigma(inputs.sigma(joints))
    res = fit_gravity(traces, drive, inputs.regressor(), info.gravity_names, notes=notes)
    res = res.with_scale_error(inputs.sigma_scale_error(joints))
    sec: dict[str, Any] = {n: float(v) for n, v in zip(res.names, res.value)}
    sec.update({f"{n}_error": float(e) for n, e in zip(res.names, res.error)})
    sec.update({f"{n}_friction_error": float(e) for n, e in zip(res.names, res.friction_error)})
    sec["unit"] = "N*m"
    return FitOutcome("gravity", table_4_8_4_9(res), {"gravity_coeffs": sec}, res)


def report(ctx: ReportContext, out: FitOutcome) -> list[str]:
    g, truth = out.results, ctx.truth
    thesis = thesis_4_9(ctx.info)
    printed = THESIS_4_8 if thesis is not None else {}
    L = ["## Table 4.8: gravity loading measurements", "",
         "tau0 is the gravity torque at the start of a pass, d (W1 - W2) / 2 minus the same "
         "for the friction-cancelling repeat (4.51), in N m; the regressor row says which "
         "combination of coefficients it measures (from 4.24 at that pose). A pass in the "
         "- direction starts at the other end of the sweep, where the torque has the "
         "opposite sign. j2 has no repeat: joint 2's axis is always horizontal and a "
         "zero start torque would need theta2 = +-90 deg at one end of the sweep, outside "
         "its range (docs/calib.md). Result: the row solved for its leading coefficient "
         "with the others from the fit of Table 4.9." + (" " + J3A_NOTE if printed else ""), "",
         "| position | joint | dir | tau0 in c | thesis (W_g2 - W_g1)/2 | fit tau0 | uncompensated | result |",
         "|---|---|---|---|---|---|---|---|"]
    for r in g.rows:
        name, val = row_result(r, g)
        th = printed.get((r.position, r.joint))
        ths = f"{th[1]:.3f} ({th[0]})" if th else "-"
        L.append(f"| {r.position} | {r.joint} | {'+' if r.direction > 0 else '-'} | "
                 f"{combination(r.row, g.names)} | {ths} | {r.tau0:.3f} | {r.raw_tau0:.3f} | {name} = {val:.3f} |")
    L += ["", "## Table 4.9: gravity loading coefficients (N m)", "",
          f"fit +- error: sqrt(({g.factor:.2f} sd of the fit)^2 + (half the difference of the two "
          "directions' fits)^2), the thesis's combination (4.5.6) with the fit's part a 99.73 % "
          "interval (Student's t of the sweeps less the coefficients: a sweep's two directions are "
          "one observation, they share their errors; the thesis printed 2 sd).", "",
          "| coefficient | thesis | thesis friction error | truth | fit | fit friction error | abs(fit - truth) "
          "| within thesis bound | within fit error |",
          "|---|---|---|---|---|---|---|---|---|"]
    for k, n in enumerate(g.names):
        tv, te, tf = (thesis or {}).get(n, (float("nan"),) * 3)
        ts, tt = ("-", float("nan")) if truth is None else (f"{truth.gravity[k]:.3f}", float(truth.gravity[k]))
        d = abs(g.value[k] - tt)
        ths = f"{tv:.3f} +- {te:.3f} | {tf:.3f}" if np.isfinite(tv) else "- | -"
        L.append(f"| {n} | {ths} | {ts} | {g.value[k]:.3f} +- {g.error[k]:.3f} | "
                 f"{g.friction_error[k]:.3f} | {d:.4f} | "
                 + ((ctx.check('4.9', d <= te) if np.isfinite(te) else "-")
                    + f" | {ctx.check('4.9 fit', d <= g.error[k])} |" if truth is not None else "- | - |"))
    return L + [""]


# Sweeps beyond the fewest that identify the coefficients, on an arm Table 4.7 does not serve:
# the fit's degrees of freedom (a sweep is one observation, rcci.calib.gravity.sweep_observations),
# 8 for Student's t of 4.3 (2 would give 19: intervals ten times the scatter)
EXTRA_SWEEPS = 8


def plans(info, speed_deg: float = 20.0, extra: int = EXTRA_SWEEPS) -> list:
    """The gravity sweeps for the arm of ``info`` (rcci.calib.experiments.gravity_plans): Table 4.7's
    where they identify its coefficients, else sweeps chosen by its regressor (``extra``
    beyond the fewest), each joint's rows weighted by its data-file friction (what remains
    of it in W1 - W2)."""
    from rcci.calib.experiments import gravity_plans

    fr = info.nominal["friction"]
    noise = (np.asarray(fr["coulomb_pos"]["values"], float) + np.asarray(fr["coulomb_neg"]["values"], float)) / 2
    return gravity_plans(info.regressor, info.lower, info.upper, speed_deg, names=info.gravity_names,
                         kinds=info.kinds, noise=np.where(noise > 0, noise, 1.0), extra=extra)


def record(req: RecordRequest) -> None:
    from rcci.calib.program import record_plans

    record_plans(req, plans(req.info))


def regen(ctx: RegenContext) -> list:
    return [((), p) for p in plans(ctx.info)]


def require_gravity(info, kind: str) -> None:
    """CalibError before ``kind``'s programs are planned when its fit needs the fitted gravity
    coefficients and the arm's sweeps cannot identify them (the Microbo's c12)."""
    from rcci.calib.exceptions import CalibError

    try:
        plans(info)
    except CalibError as exc:
        raise CalibError(f"the {kind} fit subtracts gravity with the fitted coefficients, and {exc}") from None


KIND = FitKind(
    name="gravity", title="gravity loading coefficients (Tables 4.8, 4.9)", section="gravity_coeffs",
    merge_keys=(), order=2, record_order=3, report_order=4, fit=fit, report=report, record=record, regen=regen,
    missing_log="without the friction-cancelling repeat (4.49-4.51) the row keeps the friction "
                "difference between the segments")
