"""The dynamics identification end to end on simula with a hidden truth (issue 27 item 5):
excitation design, recording in current mode, fit, held-out validation, scored.

    python -m bench.identification                   # -> reports/identification.md + PNG
    python -m bench.identification --robot puma560 --out -
    python -m bench.identification --robot puma260 --coverage 5,6,7 --out -   # several truths
    python -m bench.identification --coverage 5 --ablate dh,variation --out -  # what moves a miss
    python -m bench.identification --robot microbo --all-equations --out -    # with the slides' equations

Steps: ``calib hidden-truth --inertials`` (masses, inertias, rotors, friction, sensitivities,
gravity, DH table away from the data file); ``calib record dynamics --simula "--params TRUTH
--seed N"`` (two excitations designed with CasADi + IPOPT, recorded on a lockstep simula
--dynamic); ``calib fit dynamics`` with a parameter file whose torque sensitivities and joint offsets are
the truth's (standing for `calib fit sensitivity` and `calib fit kinematics` on logs of the same
truth: the dynamics fit is scaled by the first and evaluated at the angles the second corrects;
their own fits are scored in reports/calibration.md); the section that
``calib report`` writes for these logs. Wall times are measured on this machine as it is
(shared, loaded: the load average is printed).
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from bench.output import emit

ROOT = Path(__file__).resolve().parent.parent
GOAL_COND, GOAL_SECONDS = 100.0, 60.0
#: effects of simula's truth a diagnostic run can take out of the hidden truth (``--ablate``)
ABLATIONS = {
    "dh": "the DH errors other than the joint offsets zero ([kinematics] dd, da, dalpha)",
    "variation": "no position-dependent Coulomb friction (Table 4.4: [friction] variation zero)",
}


def truth_file(path: str, robot: str, truth_seed: int, ablate: tuple[str, ...] = ()) -> dict:
    """Write the hidden truth of ``truth_seed`` (``calib hidden-truth --inertials``) to ``path``
    with the effects named in ``ablate`` (keys of ABLATIONS) taken out; returns its tables."""
    from rcci.calib.hidden_truth import write_hidden_truth
    from rcci.calib.params import atomic_write, dumps

    data = write_hidden_truth(path, robot, truth_seed, inertials=True)
    bad = set(ablate) - set(ABLATIONS)
    if bad:
        raise SystemExit(f"bench.identification: unknown --ablate {sorted(bad)} (known: {sorted(ABLATIONS)})")
    n = len(data["motors"]["torque_sensitivity"])
    if "dh" in ablate:
        for k in ("dd", "da", "dalpha"):
            data["kinematics"][k] = [0.0] * n
    if "variation" in ablate:
        data["friction"]["variation"] = [0.0] * n
    if ablate:
        atomic_write(path, f"# hidden truth seed {truth_seed} of {robot} without: {', '.join(ablate)}\n\n" + dumps(data))
    return data


def score(robot: str, truth_seed: int, sim_seed: int, ablate: tuple[str, ...] = ()) -> dict:
    """Record and fit one hidden truth (no plots, no report): coverage, the misses as
    (name, |error| / half-width), the fit's condition number, the held-out ratios, wall times."""
    from rcci.calib.dynamics import coverage, truth_vector
    from rcci.calib.fitting import run_fit
    from rcci.calib.logs import load_trace
    from rcci.calib.regen import regen
    from rcci.calib.robot import robot_info

    with tempfile.TemporaryDirectory(prefix="bench-ident-") as tmp:
        path = os.path.join(tmp, "truth.toml")
        data = truth_file(path, robot, truth_seed, ablate)
        regen(tmp, sim_seed, ("dynamics",), path, quiet=True, robot=robot)
        traces = [load_trace(os.path.join(tmp, f"dynamics-{r}.rcilog.xz")) for r in ("fit", "heldout")]
        params = {"motors": {"torque_sensitivity": data["motors"]["torque_sensitivity"]},
                  "kinematics": {"dtheta": data["kinematics"]["dtheta"]}}
        out = run_fit("dynamics", traces, robot_info(robot), params)
        res = out.results
        truth = truth_vector(traces, robot)
    n_in, n_all, inside = coverage(res, truth)
    z = np.abs(res.wls.value - truth) / res.wls.error
    return {"seed": truth_seed, "inside": n_in, "of": n_all,
            "misses": [(res.names[k], float(z[k])) for k in np.flatnonzero(~inside)],
            "worst": (res.names[int(np.argmax(z))], float(np.max(z))),
            "cond": float(res.wls.cond_scaled), "design": [float(c) for c in res.cond_design],
            "heldout": float(max(np.max(h.ratios()) for h in res.heldout)),
            "seconds": float(res.design_seconds + res.seconds_fit)}


def design_report(robot: str, seeds: list[int], spread: float) -> str:
    """The designs of ``seeds`` (rcci.calib.excitation.design, start offsets moved by ``spread``):
    condition number, each joint's swing, the two weakest directions of the regressor."""
    from rcci.calib.excitation import design, weakest_directions

    t0 = time.monotonic()
    L = [f"### Excitation designs of the {robot}: what limits the condition number", "",
         f"`python -m bench.identification --robot {robot} --designs {','.join(map(str, seeds))} --spread {spread:g}` "
         f"({time.strftime('%H:%M', time.gmtime())} UTC, load average {os.getloadavg()[0]:.1f} on 2 cores)", "",
         "| seed | condition number (unit columns) | joint swing, min..max (rad; m on a slide) | weakest directions "
         "(singular value / largest: vector) | design: wall, CPU (s) |", "|---|---|---|---|---|"]
    for seed in seeds:
        c0 = time.process_time()
        exc = design(robot, seed=seed, spread=spread)
        cpu = time.process_time() - c0
        q = exc.state(np.linspace(0, exc.period, 400, endpoint=False))[0]
        swing = ", ".join(f"{a:.2f}..{b:.2f}" for a, b in zip(q.min(axis=0), q.max(axis=0)))
        weak = "; ".join(f"{v:.4f}: {d}" for v, d in weakest_directions(exc))
        L.append(f"| {seed} | {exc.cond_scaled:.1f} | {swing} | {weak} | {exc.seconds:.0f}, {cpu:.0f} |")
    L += ["", f"({time.monotonic() - t0:.0f} s)", ""]
    return "\n".join(L)


def columns_report(robot: str, names: list[str]) -> str:
    """The named columns of the generated base regressor (``rccl.kinematics`` BASE_PARAMETERS) as
    the CasADi kernel writes them: per joint torque, 0-based q_k, qd_k, qdd_k (joint k + 1)."""
    import casadi as ca

    import rccl.kinematics as kin
    from rcci.calib.excitation import casadi_kernel

    base = kin.load(robot).BASE_PARAMETERS
    unknown = [x for x in names if x not in base]
    if unknown:
        raise SystemExit(f"bench.identification --columns: {unknown} are not base parameters of {robot} ({base})")
    f = casadi_kernel(robot, "base_regressor")
    n = f.size1_in(0)
    q, qd, qdd = (ca.SX.sym(s, n) for s in ("q", "qd", "qdd"))
    Y = f(q, qd, qdd)
    L = [f"### Columns of the {robot}'s base regressor", "",
         f"`python -m bench.identification --robot {robot} --columns {','.join(names)}` (CasADi's print of the "
         "generated kernel; q_k, qd_k, qdd_k are joint k + 1's; 0.154 m is d2, 9.81 g)", ""]
    for name in names:
        k = base.index(name)
        L += [f"- {name}, torque of joint {i + 1}: `{Y[i, k]}`" for i in range(n) if not Y[i, k].is_zero()]
    return "\n".join(L + [""])


def coverage_report(robot: str, seeds: list[int], sim_seed: int, ablate: tuple[str, ...]) -> str:
    """Coverage of the printed 99.73 % intervals over several hidden truths, as a markdown table."""
    t0 = time.monotonic()
    rows = [score(robot, s, sim_seed, ablate) for s in seeds]
    inside, total = sum(r["inside"] for r in rows), sum(r["of"] for r in rows)
    cmd = (f"python -m bench.identification --robot {robot} --coverage {','.join(map(str, seeds))} --seed {sim_seed}"
           + (f" --ablate {','.join(ablate)}" if ablate else ""))
    L = [f"### Coverage of the 99.73 % intervals over {len(seeds)} hidden truths of the {robot}", "",
         f"`{cmd}` ({time.strftime('%H:%M', time.gmtime())} UTC, {time.monotonic() - t0:.0f} s, load average "
         f"{os.getloadavg()[0]:.1f} on 2 cores)" + (": the truth with " + "; ".join(ABLATIONS[a] for a in ablate)
                                                     if ablate else "") + ".", "",
         "| truth seed | inside | outside (|error| / half-width) | largest |error| / half-width | condition number "
         "(fit, unit columns) | held-out RMS / noise, worst joint | design + fit |", "|---|---|---|---|---|---|---|"]
    for r in rows:
        miss = ", ".join(f"{n} ({z:.2f})" for n, z in r["misses"]) or "none"
        L.append(f"| {r['seed']} | {r['inside']} of {r['of']} | {miss} | {r['worst'][0]} {r['worst'][1]:.2f} | "
                 f"{r['cond']:.1f} | {r['heldout']:.2f} | {r['seconds']:.1f} s |")
    L += ["", f"Overall {inside} of {total} truths inside their interval ({100 * inside / total:.1f} %; a 99.73 % "
          f"interval lets {0.0027 * total:.2f} of {total} fall outside by chance).", ""]
    return "\n".join(L)


def run(robot: str, truth_seed: int, sim_seed: int, plots: str) -> str:
    import tomllib

    from rcci.calib.fitting import run_fit
    from rcci.calib.hidden_truth import write_hidden_truth
    from rcci.calib.logs import load_trace
    from rcci.calib.regen import regen
    from rcci.calib.registry import ReportContext, kind
    from rcci.calib.report import _Checks
    from rcci.calib.robot import robot_info

    info = robot_info(robot)
    with tempfile.TemporaryDirectory(prefix="bench-ident-") as tmp:
        truth_file = os.path.join(tmp, "truth.toml")
        write_hidden_truth(truth_file, robot, truth_seed, inertials=True)
        t0 = time.monotonic()
        regen(tmp, sim_seed, ("dynamics",), truth_file, quiet=True, robot=robot)
        record_s = time.monotonic() - t0
        traces = [load_trace(os.path.join(tmp, f"dynamics-{r}.rcilog.xz")) for r in ("fit", "heldout")]
        with open(truth_file, "rb") as f:
            data = tomllib.load(f)
        params = {"motors": {"torque_sensitivity": data["motors"]["torque_sensitivity"]},
                  "kinematics": {"dtheta": data["kinematics"]["dtheta"]}}
        t1 = time.monotonic()
        out = run_fit("dynamics", traces, info, params)
        fit_s = time.monotonic() - t1
        os.makedirs(plots, exist_ok=True)
        pngs = kind("dynamics").plot(out, plots, f"identification-{robot}")
        ctx = ReportContext(info, None, _Checks(), traces, {"dynamics": [os.path.relpath(p, plots) for p in pngs]},
                            "", True, True)
        section = kind("dynamics").report(ctx, out)
    res = out.results
    design_s = res.design_seconds
    from rcci.calib.dynamics import coverage, truth_vector

    truth = truth_vector(traces, robot)
    n_in, n_all, inside = coverage(res, truth)
    ratios = np.concatenate([h.ratios() for h in res.heldout])
    per_joint = ", ".join(f"{j + 1}: {r:.2f}" for h in res.heldout for j, r in zip(h.fitted, h.ratios()))
    total = design_s + fit_s
    load = os.getloadavg()[0]
    raw = [float(tr.meta["excitation"]["cond_raw"]) for tr in traces]
    rows = [("condition number of the designed excitations (unit columns; in SI units)",
             ", ".join(f"{c:.1f}" for c in res.cond_design) + "; " + ", ".join(f"{c:.0f}" for c in raw),
             f"<= {GOAL_COND:g} (unit columns)", all(c <= GOAL_COND for c in res.cond_design)),
            ("parameters whose truth is inside the printed 99.73 % interval", f"{n_in} of {n_all}", "all",
             n_in == n_all),
            ("held-out RMS error / current noise, per fitted joint", per_joint, "<= 2",
             bool(np.all(ratios <= 2))),
            ("design (two excitations) + fit wall time", f"{design_s:.1f} + {fit_s:.1f} = {total:.1f} s",
             f"<= {GOAL_SECONDS:g} s", total <= GOAL_SECONDS)]
    L = [f"# Dynamics identification of the {robot} on simula against a hidden truth", "",
         f"Generated by `python -m bench.identification --robot {robot} --truth-seed {truth_seed} "
         f"--seed {sim_seed}`; do not edit by hand. Truth: `calib hidden-truth --seed {truth_seed} --inertials` "
         f"(not the data file's values); simula seed {sim_seed}, lockstep, `--dynamic --warm`. The torque "
         "sensitivities and joint offsets the fit takes from its parameter file are the truth's (standing "
         "for `calib fit sensitivity` and `calib fit kinematics` on logs of the same truth). Run at {} UTC; recording took {:.0f} s of wall "
         "time (designs included); the machine's load average was {:.1f} on its 2 cores.".format(
             time.strftime("%Y-%m-%d %H:%M", time.gmtime()), record_s, load), "",
         "| figure | measured | goal | met |", "|---|---|---|---|"]
    L += [f"| {a} | {b} | {c} | {'yes' if d else '**no**'} |" for a, b, c, d in rows]
    L += ["", "Where the truth falls outside: " + (", ".join(n for n, ok in zip(res.names, inside) if not ok) or "nowhere")
          + ".", ""] + section
    return "\n".join(L)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--robot", default="puma260")
    p.add_argument("--truth-seed", type=int, default=5)
    p.add_argument("--seed", type=int, default=7, help="simula's seed")
    p.add_argument("--out", default=str(ROOT / "reports" / "identification.md"))
    p.add_argument("--coverage", metavar="SEEDS", help="comma-separated truth seeds: the coverage table only")
    p.add_argument("--ablate", default="", help=f"with --coverage: take out of the truth {', '.join(ABLATIONS)}")
    p.add_argument("--designs", metavar="SEEDS", help="comma-separated design seeds: the design diagnosis only")
    p.add_argument("--spread", type=float, default=0.0, help="with --designs: move the start offsets (share of "
                   "half the range)")
    p.add_argument("--columns", metavar="NAMES", help="comma-separated base parameters: their regressor columns")
    p.add_argument("--all-equations", action="store_true", help="fit every joint's equation, those of "
                   "rcci.calib.unmeasured too (what leaving them out changes)")
    args = p.parse_args(argv)
    if args.all_equations:
        import rcci.calib.unmeasured as unmeasured
        from rcci.calib.grouping import grouping

        unmeasured.TORQUE_UNMEASURED = {}
        grouping.cache_clear()
    if args.columns:
        emit(columns_report(args.robot, [x for x in args.columns.split(",") if x.strip()]), args.out)
        return 0
    if args.designs:
        emit(design_report(args.robot, [int(x) for x in args.designs.split(",") if x.strip()], args.spread), args.out)
        return 0
    if args.coverage:
        seeds = [int(x) for x in args.coverage.split(",") if x.strip()]
        ablate = tuple(a for a in args.ablate.split(",") if a)
        emit(coverage_report(args.robot, seeds, args.seed, ablate), args.out)
        return 0
    plots = str(Path(args.out).parent) if args.out != "-" else tempfile.mkdtemp(prefix="ident-plots-")
    emit(run(args.robot, args.truth_seed, args.seed, plots), args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
