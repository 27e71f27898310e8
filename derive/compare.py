"""Comparing a printed thesis equation with the derived one (the verdicts of
reports/thesis-equations.md, derive.report and derive.audit).

Agreement is tested by evaluating printed minus derived at random points in 40-digit
arithmetic (closed-form trigonometric and rational expressions: zero at five random
points means zero); "signs only" means that after full expansion the two sides have the
same terms with the same magnitudes, i.e. the print lost minus signs, the OCR's usual
damage. A report row is a :class:`Row`.
"""
from __future__ import annotations

import random
from dataclasses import dataclass

import sympy as sp

from derive import thesis_print as tp
from derive.dh import Q, a2, d3, d4
from derive.gravity import COM, MASSES, d_t, g0, m_t
from derive.inverse import POSE

_S = {f"S{i}": sp.sin(Q[i - 1]) for i in range(1, 7)}
_C = {f"C{i}": sp.cos(Q[i - 1]) for i in range(1, 7)}
_POSE = {str(s): s for s in POSE if isinstance(s, sp.Symbol)}


def _vars(prefix: str) -> dict[str, sp.Symbol]:
    return {f"{prefix}{i}": sp.Symbol(f"{prefix}{i}", real=True) for i in range(1, 7)}


DQ, DC, F, TAU = _vars("dq"), _vars("dc"), _vars("f"), _vars("tau")


def namespace(robot: str) -> dict[str, sp.Expr]:
    ns: dict[str, sp.Expr] = {**_S, **_C, **_POSE}
    ns["S23"], ns["C23"] = sp.sin(Q[1] + Q[2]), sp.cos(Q[1] + Q[2])
    if robot == "puma260":
        ns.update({"a2": a2, "d3": d3, "d4": d4})
    else:
        ns.update({"d2": Q[1], "d3": Q[2]})
    ns.update({f"dth{i}": DQ[f"dq{i}"] for i in range(1, 7)})
    ns.update(dict(zip(["dx", "dy", "dz", "dpsi", "drho", "dphi"], DC.values())))
    ns.update(dict(zip(["fx", "fy", "fz", "tx", "ty", "tz"], F.values())))
    ns.update({f"t{i}": TAU[f"tau{i}"] for i in range(1, 7)})
    ns.update({"g": g0, "m_t": m_t, "d_t": d_t})
    ns.update({f"m{k}": MASSES[k - 1] for k in range(1, 7)})
    for k in range(1, 7):
        for axis, sym in zip("xyz", COM[k - 1]):
            ns[f"{axis}{k}"] = sym
    ns["x3"] = sp.Symbol("x3", real=True)
    return ns


def parse(text: str, ns: dict[str, sp.Expr]) -> sp.Expr:
    for name, body in tp.FA.items():
        text = text.replace(name, body)
    return sp.sympify(text, locals=dict(ns))


# -- comparison ------------------------------------------------------------------------

def _random_point(symbols, rng: random.Random) -> dict:
    return {s: sp.Float(rng.uniform(-1.3, 1.3) + (0.2 if rng.random() < 0.5 else -0.2), 40) for s in symbols}


def equal(a: sp.Expr, b: sp.Expr, points: int = 6) -> bool:
    """printed == derived, tested at random points (double precision, 1e-10 relative)."""
    import math

    a, b = sp.sympify(a), sp.sympify(b)
    syms = sorted(a.free_symbols | b.free_symbols, key=sp.default_sort_key)
    fa = sp.lambdify(syms, a, "math")
    fb = sp.lambdify(syms, b, "math")
    rng = random.Random(7)
    for _ in range(points):
        pt = [rng.uniform(-1.3, 1.3) + (0.2 if rng.random() < 0.5 else -0.2) for _ in syms]
        try:
            va, vb = float(fa(*pt)), float(fb(*pt))
        except (ZeroDivisionError, ValueError):
            continue
        if not math.isclose(va, vb, rel_tol=1e-10, abs_tol=1e-10):
            return False
    return True


def _monomials(e: sp.Expr) -> dict:
    e = sp.expand(sp.expand_trig(e))
    out = {}
    for term in sp.Add.make_args(e):
        coeff, rest = term.as_coeff_Mul()
        out[rest] = out.get(rest, 0) + coeff
    return {k: abs(v) for k, v in out.items() if v != 0}


def signs_only(printed: sp.Expr, derived: sp.Expr) -> bool:
    """Same terms with the same magnitudes after expansion (fractions cross-multiplied)."""
    pn, pd = sp.fraction(sp.together(printed))
    dn, dd = sp.fraction(sp.together(derived))
    try:
        return _monomials(pn * dd) == _monomials(dn * pd) or (
            _monomials(pn) == _monomials(dn) and _monomials(pd) == _monomials(dd))
    except Exception:  # noqa: BLE001 - a heuristic; failure means "not signs only"
        return False


def verdict(printed: sp.Expr, derived: sp.Expr) -> str:
    if equal(printed, derived):
        return "confirmed"
    if equal(printed, -derived):
        return "sign"
    if signs_only(printed, derived):
        return "sign"
    return "differs"


_PRETTY_VEC = {
    **{DQ[f"dq{i}"]: sp.Symbol(f"dth{i}") for i in range(1, 7)},
    **dict(zip(DC.values(), sp.symbols("dx dy dz dpsi drho dphi"))),
    **dict(zip(F.values(), sp.symbols("fx fy fz tx ty tz"))),
    **{TAU[f"tau{i}"]: sp.Symbol(f"t{i}") for i in range(1, 7)},
}


def pretty(e, microbo: bool = False) -> str:
    """A derived expression in the thesis's S/C notation (d2, d3 for the Microbo's q2, q3)."""
    rep = dict(_PRETTY_VEC)
    for i in range(1, 7):
        rep[sp.sin(Q[i - 1])] = sp.Symbol(f"S{i}")
        rep[sp.cos(Q[i - 1])] = sp.Symbol(f"C{i}")
    rep[sp.sin(Q[1] + Q[2])] = sp.Symbol("S23")
    rep[sp.cos(Q[1] + Q[2])] = sp.Symbol("C23")
    if microbo:
        rep[Q[1]], rep[Q[2]] = sp.Symbol("d2"), sp.Symbol("d3")
    e = sp.Matrix(e).T if isinstance(e, (list, tuple)) else sp.sympify(e)
    text = sp.sstr(e.xreplace(rep))
    return text.replace("**", "^")


# -- rows ------------------------------------------------------------------------------

@dataclass
class Row:
    eq: str
    what: str
    printed: str
    status: str  # confirmed | OCR | erratum | checked
    note: str = ""
    corrected: str = ""


def status_of(v: str, erratum_note: str = "") -> tuple[str, str]:
    if v == "confirmed":
        return "confirmed", ""
    if v == "sign":
        return "OCR", "signs differ (minus signs lost or misplaced in the print); otherwise the same terms"
    if erratum_note:
        return "erratum", erratum_note
    return "differs", "see corrected form"
