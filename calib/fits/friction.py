"""Coulomb and viscous friction and its variation along the path (thesis 4.5.4, Tables 4.2-4.4)."""
from __future__ import annotations

from typing import Any

import numpy as np

from rcci.calib.fitting import FitOutcome, merge_joint_values
from rcci.calib.friction import fit_friction
from rcci.calib.registry import FitKind, RecordRequest, RegenContext, ReportContext
from rcci.calib.report import SD
from rcci.calib.tables import slide_note, table_4_2_4_3

#: the per-joint keys this fit writes to [friction], and how each comes from a joint's result
FITTED = (("coulomb_pos", lambda r: r.plus.coulomb), ("coulomb_neg", lambda r: r.minus.coulomb),
          ("viscous_pos", lambda r: r.plus.viscous), ("viscous_neg", lambda r: r.minus.viscous),
          ("coulomb_pos_error", lambda r: r.plus.coulomb_err), ("coulomb_neg_error", lambda r: r.minus.coulomb_err),
          ("viscous_pos_error", lambda r: r.plus.viscous_err), ("viscous_neg_error", lambda r: r.minus.viscous_err),
          ("variation", lambda r: r.variation))


def fit(traces, info, params, inputs, notes) -> FitOutcome:
    joints = sorted({t.joint_index() for t in traces})
    drive = info.drive.with_sigma(inputs.sigma(joints))
    res, points = fit_friction(traces, drive, notes)
    res = [r.with_scale_error(inputs.sigma_scale_error([r.joint - 1])) for r in res]
    res = _window_gravity(res, traces, info, params, notes)
    js = [r.joint for r in res]
    old = params.get("friction")
    sec: dict[str, Any] = dict(old or {})   # breakaway's static_pos/neg stay; none are invented
    for key, get in FITTED:
        sec[key] = merge_joint_values(old, key, js, [get(r) for r in res])
    sec["error_is"] = "99.73 % (3 sd; Student's t for few passes; F_c with the position pattern's window mean)"
    text = "\n".join([table_4_2_4_3(res), *slide_note(info.kinds, js, "friction")])
    return FitOutcome("friction", text, {"friction": sec}, res, {"points": points})


def _window_gravity(res, traces, info, params, notes) -> list:
    """Each joint's Coulomb values corrected for gravity's mean over its window on the arm
    the parameter file describes (rcci.calib.window_gravity)."""
    from rcci.calib.friction import TAPER
    from rcci.calib.window_gravity import window_gravity

    out, sources = [], set()
    for r in res:
        tr = next(t for t in traces if t.joint_index() == r.joint - 1)
        lo, hi = (float(x) for x in tr.need("window", (list, tuple)))
        if "pose" not in tr.meta:
            notes.append(f"{tr.path}: no metadata 'pose' (the arm's pose during the sweeps): gravity's "
                         f"mean over joint {r.joint}'s window is neither corrected nor in its error")
            out.append(r)
            continue
        pose = np.asarray(tr.need("pose", (list, tuple)), dtype=float)
        loaded = bool(tr.meta.get("gravity_loaded", False))
        g, sd, source = window_gravity(info.name, params, r.joint, pose, (lo, hi), min(TAPER, 0.25 * (hi - lo)),
                                       loaded=loaded)
        sources.add(source.split("; ")[0])      # the coefficients' share is named per joint below
        if loaded:
            notes.append(f"joint {r.joint}: gravity works over its friction window (its centres of mass lie off "
                         f"the link's line): its mean there, {g:+.4f} +- {3 * sd:.4f} N m, is taken off F_c+- "
                         f"({source})")
        out.append(r.with_window_gravity(g, sd))
    if any(not s.startswith("the fitted kinematics") or "data file" in s for s in sources):
        notes.append("gravity's mean over the friction windows (their axes lean by the DH errors) from "
                     + "; ".join(sorted(sources)) + ": fit kinematics and gravity first to correct for it")
    return out


def plot(out: FitOutcome, folder: str, prefix: str) -> list[str]:
    from rcci.calib.plots import friction_plots

    return friction_plots(out.results, out.extra["points"], folder, prefix=prefix)


def _variation_truth(ctx: ReportContext) -> dict[int, tuple[float, float]]:
    """Per joint, the peak and sqrt(2) RMS of simula's Table 4.4 pattern over the log's window."""
    import tomllib

    from rcci.calib.truth import log_truth, simula_variation

    vt = {}
    for tr in ctx.traces:
        t = log_truth(tr)
        if tr.experiment == "friction" and t["kind"] == "simula":
            data = tomllib.loads(t["params_toml"]) if t.get("params_toml") else None
            vt[tr.meta["joint"]] = simula_variation(ctx.info.name, int(t["seed"]), tr.meta["joint"],
                                                    tuple(tr.meta["window"]), data)
    return vt


def report(ctx: ReportContext, out: FitOutcome) -> list[str]:
    res, truth = out.results, ctx.truth
    fr = ctx.info.nominal["friction"]
    L = ["## Table 4.2: Coulomb friction (N m)", "",
         f"fit +- {SD}: the fit's standard deviation combined with that of the position pattern's "
         "mean over the window (the Table 4.4 variation is the same on every pass, so no fit of "
         "speeds tells its window mean from F_c; estimated from the measured profile as the mean "
         "a window placed at random along the pattern would carry, docs/calib.md).",
         *slide_note(ctx.info.kinds, [r.joint for r in res], "friction"), "",
         "| joint | dir | thesis | truth | fit (+- " + SD + ") | of which pattern (1 sd) | abs(fit - truth) "
         "| within thesis bound | within fit error |",
         "|---|---|---|---|---|---|---|---|---|"]
    L += _rows(res, fr, truth, ctx.check, "4.2", "coulomb", 1.0, ".3f",
               lambda fit: f" | {fit.coulomb_pattern_sd:.4f}")
    L += ["", "## Table 4.3: viscous friction (N m s / rad, x 1000)", "",
          "The viscous term is a few per cent of the Coulomb term, so it needs each pass's "
          "mean friction to a fraction of a per cent (4.5.3: repeatable to under 1 %). What makes "
          "that possible here (docs/calib.md, 'Viscous friction' and 'Joint 5'): simula's servo "
          "ripple is the PID's noise-shaped quantisation error, which the 15 ms filter of Appendix "
          "C averages out; the friction logs are read at 72 Hz over windows as long as each joint's "
          "range allows, at speeds up to 90 % of its velocity limit, after 200 s of warm-up and with "
          "no halts at the turns; each reading is paired with the angle 15.5 ms earlier (the "
          "filter's time constant plus half a servo tick); each pass's mean is taken with Hann "
          "edges of 0.3 rad; the fast passes of joints 2-6 are read at every servo tick (1 kHz, "
          "`friction-jN-servo`), where the ripple cancels. The fit weights each pass by the inverse "
          f"of a variance model per log (a |omega| / rate + b) estimated from the residuals; fit +- {SD}.", "",
          f"| joint | dir | thesis | truth | fit (+- {SD}) | abs(fit - truth) | within thesis bound | within fit error |",
          "|---|---|---|---|---|---|---|---|"]
    L += _rows(res, fr, truth, ctx.check, "4.3", "viscous", 1e3, ".2f", lambda fit: "")
    L += ["", "## Table 4.4: variation of the friction along the path", "",
          "simula multiplies the Coulomb friction by 1 + v p(q), with v the Table 4.4 value "
          "(the truth's) and p a seeded pattern of spatial harmonics, |p| <= 1. The fit estimates "
          "the variation as sqrt(2) x the noise-corrected RMS of the friction's position profile "
          "(docs/calib.md); its truth is the same statistic of simula's pattern over the same "
          "window (read from simula with the logs' seed), shown with the pattern's peak.", "",
          "| joint | thesis | simula bound v | simula peak in window | truth sqrt(2) RMS | fit |",
          "|---|---|---|---|---|---|"]
    vt = _variation_truth(ctx)
    for r in res:
        j = r.joint - 1
        peak, rms = vt.get(r.joint, (float("nan"), float("nan")))
        vb = "-" if truth is None else f"{100 * truth.variation[j]:.0f} %"
        thesis = f"{100 * fr['variation']['values'][j]:.0f} %" if "variation" in fr else "-"   # a thesis arm's
        L.append(f"| {r.joint} | {thesis} | {vb} | {100 * peak:.1f} % | "
                 f"{100 * rms:.1f} % | {100 * r.variation:.1f} % |")
    L += ["", "Appendix B: friction against speed per direction (points: passes; line: the fit; "
          "band: the printed uncertainty of F_c)", ""]
    L += [f"![{p}]({p.split('/')[-1]})" for p in ctx.plots.get("friction", [])]
    return L + [""]


def _rows(res, fr, truth, check, table: str, what: str, scale: float, fmt: str, extra) -> list[str]:
    """Rows of Table 4.2 (``what`` coulomb) or 4.3 (viscous, shown x ``scale``): thesis,
    truth, fit +- error (``extra(fit)`` after it), |fit - truth|, the two checks."""
    L = []
    for r in res:
        j = r.joint - 1
        for name, fit, d_key in (("+", r.plus, "pos"), ("-", r.minus, "neg")):
            key = f"{what}_{d_key}"
            th = fr[key]["values"][j]
            te = fr[key].get("uncertainty", [float("nan")] * len(fr[key]["values"]))[j]   # none: not a thesis arm
            value, err = getattr(fit, what), getattr(fit, f"{what}_err")
            tv = float("nan") if truth is None else float(getattr(truth, key)[j])
            d = abs(value - tv)
            v = lambda x: format(scale * x, fmt)  # noqa: E731
            thesis = f"{v(th)} +- {v(te)}" if np.isfinite(te) else f"{v(th)} (no bound)"
            L.append(f"| {r.joint} | {name} | {thesis} | {'-' if truth is None else v(tv)} | "
                     f"{v(value)} +- {v(err)}{extra(fit)} | {v(d)} | "
                     + (f"{check(table, d <= te) if np.isfinite(te) else '-'} | {check(table + ' fit', d <= err)} |"
                        if truth is not None else "- | - |"))
    return L


def record(req: RecordRequest) -> None:
    from rcci.calib.experiments import friction_plans
    from rcci.calib.program import record_plans

    record_plans(req, friction_plans(req.joints, robot=req.info))


def regen(ctx: RegenContext) -> list:
    from rcci.calib.experiments import friction_plans

    return [((), p) for p in ctx.per_joint("friction", lambda j: friction_plans([j], robot=ctx.info))]


KIND = FitKind(
    name="friction", title="Coulomb and viscous friction, its variation (Tables 4.2-4.4)", section="friction",
    merge_keys=tuple(k for k, _ in FITTED), order=3, record_order=2, report_order=1,
    fit=fit, report=report, record=record, regen=regen, plot=plot,
    missing_log="the speeds it holds are missing from the fit, so the viscous coefficient "
                "(and its error) rests on the speeds that are left")
