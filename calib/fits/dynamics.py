"""Identification of the dynamics' base parameters (thesis 4.6 with friction 4.27): excitation
logs in current mode, weighted least squares with 99.73 % intervals, a physically consistent
variant, measured against predicted torque on a held-out trajectory."""
from __future__ import annotations

import os

import numpy as np

from rcci.calib.fitting import FitOutcome
from rcci.calib.registry import FitKind, RecordRequest, RegenContext, ReportContext
from rcci.calib.report import SD

SECTION = "dynamics"


def fit(traces, info, params, inputs, notes) -> FitOutcome:
    from rcci.calib.dynamics import fit_dynamics
    from rcci.calib.grouping import grouping

    from rcci.calib.regressor import fitted_joints

    joints = fitted_joints(info.name)          # the equations the fit uses (rcci.calib.unmeasured)
    drive = info.drive.with_sigma(inputs.sigma(joints))
    kin = params.get("kinematics", {})
    offset = None
    if "dtheta" in kin:
        offset = np.nan_to_num(np.asarray(kin["dtheta"], dtype=float))
    else:
        notes.append("no fitted joint offsets ([kinematics] dtheta) in the parameter file: the regressor is "
                     "evaluated at the encoder angles (fit kinematics first: an offset turns the links' "
                     "first moments into each other)")
    res = fit_dynamics(traces, drive, info.name, offset=offset)
    scale = inputs.sigma_scale_error(joints)
    if scale > 0:     # every torque scales with the sensitivities: so does every parameter
        res.wls.error = np.sqrt(res.wls.error ** 2 + (scale * res.wls.value) ** 2)
    notes += res.notes
    sec: dict = {"names": list(res.names), "values": [float(v) for v in res.wls.value],
                 "errors": [float(e) for e in res.wls.error],
                 "error_is": f"99.73 %: the larger of Student's t x sd (dof {res.wls.dof}; sd from the weighted "
                             "residuals, each joint's share inflated by its residuals' autocorrelation) and "
                             "the jackknife over 10 spans of time; with the fitted sensitivities' scale "
                             "error; docs/calib.md",
                 "unit": "SI: kg m^2, kg m, N m, N m s/rad (names: rcci.calib.identification.column_names)"}
    sec.update(grouping(info.name).as_section())     # columns folded into others (rcci.calib.grouping)
    if res.consistent is not None:
        sec["consistent_values"] = [float(v) for v in res.consistent.value]
        sec["consistent_masses"] = [float(v) for v in res.consistent.masses]
        sec["consistent_rotor"] = [float(v) for v in res.consistent.rotor]
    return FitOutcome("dynamics", table(res), {SECTION: sec}, res)


def table(res, truth: np.ndarray | None = None) -> str:
    """The fit's table: each parameter with its interval (and the truth's value when known)."""
    w = res.wls
    head = f"| parameter | fit (+- {SD}) | consistent |" + (" truth | inside |" if truth is not None else "")
    L = [f"Dynamics identification of {res.robot}: {w.rows} equations, {len(w.value)} parameters, "
         f"condition number {w.cond_scaled:.1f} (weighted, unit columns)", "", head,
         "|---|---|---|" + ("---|---|" if truth is not None else "")]
    for k, name in enumerate(res.names):
        c = f"{res.consistent.value[k]:.5g}" if res.consistent is not None else "-"
        row = f"| {name} | {w.value[k]:.5g} +- {w.error[k]:.2g} | {c} |"
        if truth is not None:
            row += f" {truth[k]:.5g} | {'yes' if abs(w.value[k] - truth[k]) <= w.error[k] else '**no**'} |"
        L.append(row)
    if res.heldout:
        L += ["", "| held-out joint | RMS moving (N m) | RMS all (N m) | noise (N m) | RMS moving / noise |",
              "|---|---|---|---|---|"]
        for h in res.heldout:
            for j in range(len(h.noise)):
                if j not in h.fitted:
                    L.append(f"| {j + 1} | - | - | {h.noise[j]:.4f} | not fitted |")
                    continue
                L.append(f"| {j + 1} | {h.rms_moving[j]:.4f} | {h.rms_all[j]:.4f} | {h.noise[j]:.4f} | "
                         f"{h.rms_moving[j] / h.noise[j]:.2f} |")
    return "\n".join(L)


def report(ctx: ReportContext, out: FitOutcome) -> list[str]:
    from rcci.calib.dynamics import GOAL_RMS_NOISE, coverage, truth_vector
    from rcci.calib.grouping import grouping
    from rcci.calib.regressor import fitted_joints, left_out

    res = out.results
    logs = [t for t in ctx.traces if t.experiment == "dynamics"]
    truth = truth_vector(logs, res.robot)
    ex = logs[0].meta.get("excitation", {}) if logs else {}
    L = ["## Dynamics: base parameters (thesis 4.6) and friction, from excitation logs", "",
         f"The excitation (rcci.calib.excitation): a Fourier series of {len(ex.get('a', [[]])[0])} harmonics of "
         f"{ex.get('base_hz', float('nan')):g} Hz per joint, designed with CasADi + IPOPT for the condition number of the stacked regressor with its "
         "columns scaled to unit length, recorded in current mode on simula --dynamic "
         "(rcci.calib.excitation_program). The fit (rcci.calib.identification): zero-phase low-pass of the "
         "encoder angles, the model side through the current-sense filter, weighted least squares, "
         f"intervals 99.73 % (the larger of Student's t x sd, the sd inflated by the residuals' "
         "autocorrelation, and a jackknife over 10 spans of time). "
         "What the generated base regressor lacks (the wrist motors' rotor coupling, friction) is "
         "computed in rcci.calib.identification.", ""]
    why = left_out(res.robot)
    if why:
        L += [f"The equations of joints {', '.join(str(j + 1) for j in range(len(res.noise)) if j not in fitted_joints(res.robot))} "
              f"are left out of the fit: {why}. The parameters only they depend on are not identified "
              f"({', '.join(grouping(res.robot).eliminated)}).", ""]
    formulas = grouping(res.robot).formulas()
    if formulas:
        L += ["Columns no motion separates, folded into others (rcci.calib.grouping; the interval and the "
              "truth are of the grouped value): " + "; ".join(formulas) + ".", ""]
    L += [
         "- condition number of the designed excitations (unit columns): "
         + ", ".join(f"{c:.1f}" for c in res.cond_design),
         f"- condition number of the weighted fit's regressor (unit columns): {res.wls.cond_scaled:.1f}",
         f"- wall time: design {res.design_seconds:.1f} s (both trajectories), fit {res.seconds_fit:.1f} s",
         ]
    if truth is not None:
        n_in, n_all, inside = coverage(res, truth)
        nb = len(res.names) - 4 * len(res.noise)
        L.append(f"- truth inside the printed interval: {n_in} of {n_all} "
                 f"({int(inside[:nb].sum())} of {nb} base parameters and rotor couplings)")
        ctx.check("dynamics coverage", n_in == n_all)
    for h in res.heldout:
        ratio = h.ratios()
        L.append(f"- held-out {os.path.basename(h.path)}: RMS / noise per fitted joint "
                 + ", ".join(f"{j + 1}: {r:.2f}" for j, r in zip(h.fitted, ratio))
                 + f" (goal <= {GOAL_RMS_NOISE:g}: {ctx.check('dynamics held-out', bool(np.all(ratio <= GOAL_RMS_NOISE)))})")
    plots = ctx.plots.get("dynamics", [])
    L += [""] + [f"![{p}]({p})" for p in plots] + ["", table(res, truth), ""]
    return L


def plot(out: FitOutcome, folder: str, prefix: str) -> list[str]:
    from rcci.calib.dynamics_plots import heldout_plot

    stem = prefix[:-2] if prefix.endswith("-j") else prefix     # the per-joint kinds' "-j"
    return [heldout_plot(h, folder, f"{stem}-heldout-{k}") for k, h in enumerate(out.results.heldout)]


def _supported(robot: str) -> None:
    """CalibError (before any design or recording) for an arm whose columns no motion separates."""
    from rcci.calib.exceptions import CalibError
    from rcci.calib.identification import identifiable

    why = identifiable(robot)
    if why is not None:
        raise CalibError(f"robot {robot}: the dynamics fit cannot identify its parameters: {why}")


def record(req: RecordRequest) -> None:
    from rcci.calib.excitation_program import excitation_plans, run_excitation

    _supported(req.robot)
    for plan in excitation_plans(req.robot):
        path = os.path.join(req.out, plan.name + ".rcilog")
        n = run_excitation(req.url, plan, path, req.robot, extra_meta=req.extra_meta)
        print(f"{plan.name}: {n} records -> {path}")


def regen(ctx: RegenContext) -> list:
    """Both excitations on a simula of their own, started with --dynamic (and --warm)."""
    from rcci.calib.regen import record_dynamics
    from rcci.calib.registry import OwnSimula

    _supported(ctx.info.name)

    return [(("own",), OwnSimula("dynamics", lambda: record_dynamics(ctx), ("dynamics-fit", "dynamics-heldout")))]


KIND = FitKind(
    name="dynamics", title="base parameters of the dynamics and friction from excitation logs (4.6)",
    section=SECTION, merge_keys=(), order=6, record_order=6, report_order=6,
    fit=fit, report=report, record=record, regen=regen, plot=plot,
    missing_log="without the held-out log the fit is not validated on another trajectory")
