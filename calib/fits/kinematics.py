"""Kinematic errors of the DH table (thesis 3.83-3.84): probe touches on a fixture, or
end poses measured by an external instrument (CSV)."""
from __future__ import annotations

import os
import tempfile

import numpy as np

from rcci.calib.exceptions import FitError
from rcci.calib.fitting import FitOutcome
from rcci.calib.registry import FitKind, RecordRequest, RegenContext, ReportContext
from rcci.calib.touch import SLOW

ACCURACY_TARGETS = 20   # target poses of the before/after positioning run


def fit(traces, info, params, inputs, notes) -> FitOutcome:
    from rcci.calib.kinematics import Touches, fit_touches, nominal_dh, section, table, touches_from_trace

    parts = [touches_from_trace(tr, info.drive) for tr in traces]
    if len({tuple(p.tip) for p in parts}) > 1:
        raise FitError("the kinematics logs were made with different probe tips: fit them separately")
    t = Touches(np.vstack([p.q for p in parts]), np.vstack([p.normals for p in parts]),
                np.concatenate([p.offsets for p in parts]), parts[0].tip,
                np.concatenate([p.index for p in parts]))
    if len(t.q) < 4 * len(nominal_dh(info.name)):
        notes.append(f"{len(t.q)} touches for {4 * len(nominal_dh(info.name))} error parameters: "
                     "parameters beyond what they determine are left at their minimum-norm values")
    fit_ = fit_touches(nominal_dh(info.name), t, kinds=info.kinds)
    sec = section(fit_)
    sec["tip"] = [float(x) for x in t.tip]
    return FitOutcome("kinematics", table(fit_), {"kinematics": sec}, fit_, {"touches": t})


def fit_poses(paths: list[str], robot: str):
    """The fit of end poses of ``robot`` measured by an instrument (CSV files of q and T6), with
    its section: ``(fit, table text, {"kinematics": section})``."""
    from rcci.calib.kinematics import fit_kinematics, nominal_dh, read_poses, section, table

    Q, T = zip(*(read_poses(p) for p in paths))
    fit_ = fit_kinematics(nominal_dh(robot), np.vstack(Q), np.concatenate(T))
    return fit_, table(fit_), {"kinematics": section(fit_)}


def _accuracy(ctx: ReportContext) -> dict:
    """RCCL's positioning error before/after on a simula of the logs' truth, and the cost."""
    from rcci.calib.accuracy import cycle_cost, ik_cost, positioning_error
    from rcci.calib.truth import log_truth
    from rccl.calibrated import calibrated_kinematics, load_calibrated
    from rccl.kinematics import load
    from rccl.session import load_kinematics

    robot = ctx.info.name
    if any(k != "revolute" for k in ctx.info.kinds):
        return {"skipped": "calibrated kinematics at run time (rccl.calibrated) are for revolute arms; "
                           "this arm has a slide"}
    nominal = load(robot)
    t = log_truth(next(tr for tr in ctx.traces if tr.experiment == "kinematics"))
    with tempfile.TemporaryDirectory(prefix="calib-truth-") as tmp:
        truth_file = os.path.join(tmp, "truth.toml")
        with open(truth_file, "w", encoding="utf-8") as f:
            f.write(t.get("params_toml") or f"[calib]\nschema = \"rcci-calib-params/1\"\nrobot = \"{robot}\"\n")
        if "[kinematics]" not in (t.get("params_toml") or ""):
            return {"skipped": "the logs' truth has no DH errors: the nominal model is exact"}
        rows = positioning_error(truth_file, ctx.params_path, n=ACCURACY_TARGETS, seed=int(t["seed"]), robot=robot)
    load = os.getloadavg()
    cost = {"nominal": cycle_cost(load_kinematics(robot), robot=robot),
            "calibrated": cycle_cost(calibrated_kinematics(ctx.params_path, robot), robot=robot),
            "ik_nominal": ik_cost(nominal), "ik_calibrated": ik_cost(load_calibrated(ctx.params_path, robot)),
            "load": (load, os.getloadavg())}
    return {"rows": rows, "cost": cost, "targets": ACCURACY_TARGETS}


def report(ctx: ReportContext, out: FitOutcome) -> list[str]:
    from rcci.calib.kinematics import PARAM_NAMES

    truth, check = ctx.truth, ctx.check
    accuracy = _accuracy(ctx) if truth is not None and not ctx.no_accuracy else None
    fit_ = out.results
    t = out.extra["touches"]
    conv = {"dtheta": (np.degrees(1) * 1e3, "mdeg"), "dd": (1e3, "mm"), "da": (1e3, "mm"),
            "dalpha": (np.degrees(1) * 1e3, "mdeg")}
    L = ["## Kinematic calibration (thesis 3.83-3.84)", "",
         f"`calib record kinematics` touches the three faces of a fixture (a floor and two walls, "
         f"known in the base frame) {fit_.measurements} times with a touch-trigger probe on the flange "
         f"(tip at ({', '.join(f'{1e3 * x:.0f}' for x in t.tip)}) mm in link 6, a cranked stylus), "
         f"approaching each face along its normal at {1e3 * SLOW:.1f} mm/s (rcci.calib.touch.SLOW) and stopping on "
         "the cycle the probe's "
         "switch (inport1) is seen closed; the joint angles between the last open and the first "
         "closed reading put the tip on the face: one equation n . p(q, e) = h per touch. The touches "
         "are made in both arm and both wrist configurations. Why touches and not the motor "
         "currents: thesis 4.7 concludes that friction makes currents inadequate for Cartesian "
         "force sensing. `calib fit kinematics` solves for the 24 DH errors e of 3.84 (Gauss-Newton "
         f"on the exact A-matrix product, steps by truncated SVD): {fit_.rank} are identifiable; the "
         "combinations the touches cannot separate are named below (d d2 and d d3 act along the "
         "same direction because joints 2 and 3 are parallel; a point measures no turn of link 6 "
         "about the line from the wrist centre to the tip). The result goes to the parameter "
         "file's `[kinematics]`, which RCCL uses through `rccl.calibrated` (nominal closed-form IK, "
         "then Newton steps on the calibrated arm) and simula takes as a truth.", "",
         f"RMS of the touch residuals: {1e3 * fit_.rms_position_before:.3f} mm with the nominal table, "
         f"{1e3 * fit_.rms_position_after:.4f} mm after the fit (the encoders' counts, 5 to 50 um of tip "
         "travel each, set this floor).", "",
         f"fit +- {fit_.factor:.2f} sd (99.73 %, Student's t for {fit_.measurements - fit_.rank} degrees of freedom).", "",
         "| parameter | truth | fit | abs(fit - truth) | within fit error |", "|---|---|---|---|---|"]
    E = None if truth is None else truth.dh_errors.ravel()
    k = fit_.factor
    for i, name in enumerate(fit_.names):
        key = PARAM_NAMES[i % 4]
        f, unit = conv[key]
        if not fit_.identifiable[i]:
            continue
        if E is None:
            L.append(f"| {name} ({unit}) | - | {f * fit_.e[i]:.3f} +- {f * k * fit_.std[i]:.3f} | - | - |")
            continue
        d = abs(fit_.e[i] - E[i])
        L.append(f"| {name} ({unit}) | {f * E[i]:.3f} | {f * fit_.e[i]:.3f} +- {f * k * fit_.std[i]:.3f} | "
                 f"{f * d:.3f} | {check('kinematic fit', d <= k * fit_.std[i])} |")
    for name, value, sd, unit, coef in fit_.combinations():
        f = 1e3 if unit == "m" else np.degrees(1) * 1e3
        u = "mm" if unit == "m" else "mdeg"
        if E is None:
            L.append(f"| {name} ({u}) | - | {f * value:.3f} +- {f * k * sd:.3f} | - | - |")
            continue
        tv = float(coef @ E)
        d = abs(value - tv)
        L.append(f"| {name} ({u}) | {f * tv:.3f} | {f * value:.3f} +- {f * k * sd:.3f} | {f * d:.3f} | "
                 f"{check('kinematic fit', d <= k * sd)} |")
    L.append("")
    return L + _accuracy_section(accuracy)


def _accuracy_section(accuracy: dict | None) -> list[str]:
    if accuracy and "skipped" in accuracy:
        return [f"Positioning run skipped: {accuracy['skipped']}.", ""]
    if not accuracy or "rows" not in accuracy:
        return []
    c = accuracy["cost"]
    L = ["### RCCL's positioning error before and after", "",
         f"`calib report` runs RCCL (`rccl.open`, joint-mode moves) on a lockstep simula built from "
         f"the logs' truth to {accuracy['targets']} target poses of link 6 around the arm's front "
         "(right arm, elbow up: a region and configuration the touches share only in part), reads "
         "the encoders after each move and puts them through the truth's exact forward "
         "kinematics (equal to simula's Pinocchio model to 1e-15 m): the error is how far the "
         "arm's true T6 (and the probe tip on it) ends from where RCCL was told to put it. The "
         "floor is the same run with the truth's own DH table: what the joints' commands, whole "
         "encoder counts, leave.", "",
         "| kinematics RCCL uses | T6 RMS (mm) | T6 max (mm) | tip RMS (mm) | tip max (mm) | orientation RMS (mrad) |",
         "|---|---|---|---|---|---|"]
    for a in accuracy["rows"]:
        r = a.row()
        L.append(f"| {a.name} | {1e3 * r[0]:.4f} | {1e3 * r[1]:.4f} | {1e3 * r[2]:.4f} | {1e3 * r[3]:.4f} | "
                 f"{1e3 * r[4]:.3f} |")
    (l0, l1) = c["load"]
    return L + [
        "", "The orientation improves little: the turn of link 6 about the wrist-tip line "
        "(mostly d theta6) is what point touches cannot measure; a second stylus tip, or "
        "an instrument that measures orientation (`calib fit kinematics POSES.csv`), would.", "",
        "Per-cycle cost (CPU time of the trajectory generator's step, Cartesian mode, the tour of "
        "bench/rccl_cycle.py, best of 3 runs of 3000 cycles; load average "
        f"{l0[0]:.1f} before, {l1[0]:.1f} after, 2 cores shared):", "",
        "| kinematics | step mean (us) | step median (us) | step p99 (us) | one ik call on a path (us) |",
        "|---|---|---|---|---|",
        f"| nominal (generated, compiled) | {c['nominal']['mean']:.1f} | {c['nominal']['median']:.1f} | "
        f"{c['nominal']['p99']:.1f} | {c['ik_nominal']:.2f} |",
        f"| calibrated (rccl.calibrated) | {c['calibrated']['mean']:.1f} | {c['calibrated']['median']:.1f} | "
        f"{c['calibrated']['p99']:.1f} | {c['ik_calibrated']:.2f} |", ""]


def record(req: RecordRequest) -> None:
    from rcci.calib.touch import touch_plan
    from rcci.calib.touch_program import run_touches

    plan = touch_plan(max(1, (req.args.touches or 48) // 3), robot=req.robot)
    path = os.path.join(req.out, plan.name + ".rcilog")
    n = run_touches(req.url, plan, path, req.robot, extra_meta=req.extra_meta)
    print(f"{plan.name}: {n} records -> {path}")


def regen(ctx: RegenContext) -> list:
    """The touches on a simula of their own (the fixture and the probe are its environment)."""
    from rcci.calib.regen import record_kinematics_log
    from rcci.calib.registry import OwnSimula
    from rcci.calib.touch import touch_plan

    touch_plan(1, robot=ctx.info.name)     # refused here, before any recording, if the arm cannot
    return [(("own",), OwnSimula("kinematics", lambda: record_kinematics_log(ctx)))]


KIND = FitKind(
    name="kinematics", title="DH errors from probe touches or measured poses (3.84)", section="kinematics",
    merge_keys=(), order=1, record_order=0, report_order=5, fit=fit, report=report, record=record, regen=regen,
    fit_files=fit_poses)
