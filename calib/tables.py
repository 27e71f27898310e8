"""Fit results laid out like the thesis's tables (4.1-4.6, 4.8, 4.9)."""
from __future__ import annotations

import numpy as np

from rcci.calib.breakaway import BreakawayResult
from rcci.calib.friction import FrictionResult
from rcci.calib.gravity import GravityResult, row_result
from rcci.calib.sensitivity import SensitivityResult
from rcci.calib.static import StaticResult


SLIDE_UNITS = {"sensitivity": "N / A (force per ampere)",
               "friction": "N (Coulomb) and N s / m x 1000 (viscous)"}


def slide_note(kinds: tuple[str, ...], joints: list[int], what: str) -> list[str]:
    """The sentence that gives a prismatic joint's units in the tables of ``what`` (a key of
    SLIDE_UNITS), whose headings name the revolute joints' (N m ...); [] when none is prismatic."""
    slides = [j for j in joints if kinds[j - 1] == "prismatic"]
    if not slides:
        return []
    which = ", ".join(str(j) for j in slides)
    return [f"Joint {which} is prismatic (a slide): its values are in {SLIDE_UNITS[what]}, not the "
            "revolute joints' units of the headings."]


def table_4_1(res: list[SensitivityResult]) -> str:
    out = ["Table 4.1  Motor torque sensitivity (Newton-meters/ampere)",
           f"{'Joint':>5}  {'trials':>6}  {'Mean':>7}  {'Std dev':>7}  {'Indep. error':>12}"]
    for r in res:
        out.append(f"{r.joint:>5}  {r.trials:>6}  {r.mean:7.4f}  {r.std:7.4f}  {r.independent_error:12.4f}")
    out += ["Std dev: one standard deviation of the trials (not an interval). Indep. error: the thesis's",
            "a priori bound from the mass, drum radius and current scale V_g/R_i (4.5.2), not a 99.73 %",
            "interval; later fits add t x std / sqrt(trials) (99.73 %) of it to their errors."]
    return "\n".join(out)


def table_4_2_4_3(res: list[FrictionResult]) -> str:
    out = ["Table 4.2  Joint Coulomb friction (Newton-meters)",
           f"{'Joint':>5}  {'F_C+':>16}  {'F_C-':>16}"]
    for r in res:
        out.append(f"{r.joint:>5}  {r.plus.coulomb:7.3f} +- {r.plus.coulomb_err:5.3f}"
                   f"  {r.minus.coulomb:7.3f} +- {r.minus.coulomb_err:5.3f}")
    out += ["", "Table 4.3  Joint viscous friction (Newton-meter-seconds/radian, x 1000)",
            f"{'Joint':>5}  {'F_v+':>16}  {'F_v-':>16}"]
    for r in res:
        out.append(f"{r.joint:>5}  {1e3 * r.plus.viscous:7.2f} +- {1e3 * r.plus.viscous_err:5.2f}"
                   f"  {1e3 * r.minus.viscous:7.2f} +- {1e3 * r.minus.viscous_err:5.2f}")
    out += ["", "Table 4.4  Variation of the friction about its mean along the path",
            f"{'Joint':>5}  {'Variation':>9}"]
    for r in res:
        out.append(f"{r.joint:>5}  {100 * r.variation:8.0f}%")
    return "\n".join(out)


def table_4_5(res: list[BreakawayResult]) -> str:
    out = ["Table 4.5  Static friction coefficients F_s, from breakaway ramps (Newton-meters)",
           f"{'Joint':>5}  {'positive direction':>20}  {'negative direction':>20}  {'ramps':>5}"]
    for r in res:
        out.append(f"{r.joint:>5}  {r.plus:9.3f} (sd {r.plus_std:5.3f})  "
                   f"{r.minus:9.3f} (sd {r.minus_std:5.3f})  {r.ramps:>5}")
    return "\n".join(out)


def table_4_6(res: list[StaticResult]) -> str:
    n = res[0].samples if res else 0
    out = [f"Table 4.6  Typical static friction, {n} samples (Newton-meters)",
           f"{'Joint':>5}  {'Maximum':>8}  {'Minimum':>8}  {'Mean':>7}  {'Std dev':>7}"]
    for r in res:
        out.append(f"{r.joint:>5}  {r.maximum:8.3f}  {r.minimum:8.3f}  {r.mean:7.3f}  {r.std:7.3f}")
    return "\n".join(out)


def combination(row: np.ndarray, names: tuple[str, ...]) -> str:
    terms = []
    for v, n in zip(row, names):
        if abs(v) < 1e-6:
            continue
        coef = "" if abs(abs(v) - 1) < 1e-6 else f"{abs(v):.3g} "
        terms.append(("- " if v < 0 else "+ ") + coef + n)
    s = " ".join(terms) or "0"
    return s[2:] if s.startswith("+ ") else s


def table_4_8_4_9(res: GravityResult) -> str:
    out = ["Table 4.8  Gravity loading measurements",
           f"{'Position':>8}  {'Joint':>5}  {'dir':>3}  {'tau0 (in c)':>18}  {'tau0 (N m)':>10}  {'Result':>18}"]
    for r in res.rows:
        name, val = row_result(r, res)
        out.append(f"{r.position:>8}  {r.joint:>5}  {'+' if r.direction > 0 else '-':>3}  "
                   f"{combination(r.row, res.names):>18}  {r.tau0:10.3f}  {name + f' = {val:.3f}':>18}")
    out += ["", "Table 4.9  Final results for the gravity loading coefficients (N m)",
            f"{'Coefficient':>11}  {'Value':>16}  {'Friction error':>14}"]
    for n, v, e, fe in zip(res.names, res.value, res.error, res.friction_error):
        out.append(f"{n:>11}  {v:7.3f} +- {e:5.3f}  {fe:14.3f}")
    return "\n".join(out)
