"""The base parameters of the dynamics (4.6): the identifiable combinations of the 66 standard
parameters (ten per link in its joint frame, ``derive.dynamics``, plus six rotor inertias),
derived symbolically and named as the thesis names its gravity coefficients (4.24).

Two exact grouping rules, applied from the tip link to the base (a modified-DH step joins
the joint frames, so the rules are those of Khalil and Kleinfinger for that convention):

* revolute joint j: the part of link j that is symmetric about the joint axis (inertia
  diag(YYj, YYj, 0), first moment (0, 0, MZj), mass Mj) does not see q_j, so it moves to
  link j-1 (or to the fixed base, where it has no effect): XXj becomes XXj - YYj and YYj,
  MZj, Mj leave the list;
* prismatic joint j: the rotational inertia of link j (XXj ... ZZj, no mass) only turns
  with link j-1, so it moves there.

Then the torques' columns of the remaining parameters are evaluated numerically on random
states of the arm: a column that is zero everywhere (a parameter no torque depends on,
e.g. MX1 of a vertical first axis) is dropped, and a column that is a fixed combination of
earlier ones (found by rank, its weights checked to be small rationals) is folded into
them, as 4.24 folds a2 (m2 + ... + m6) into c12. A base parameter is named after the
standard parameter that leads it, with R appended when others were grouped into it.
"""
from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
from typing import Sequence

import numpy as np
import sympy as sp
from sympy.printing.numpy import NumPyPrinter

from derive.dh import Q, DHRobot
from derive.dynamics import (PARAM_KINDS, QD, QDD, ROTOR, STANDARD, Program, move_params,
                             rot_x, link_params, regressor, steps)
from derive.gravity import g0

#: inputs of the base-parameter kernel: the data file's inertials (DH frame k) and rotors
#: (up to 7 links; an n-joint arm uses the first n)
MASS = sp.symbols("m1:8", positive=True)
COMS = [sp.symbols(f"x{k} y{k} z{k}", real=True) for k in range(1, 8)]
INERTIA = [sp.symbols(f"ixx{k} iyy{k} izz{k} ixy{k} ixz{k} iyz{k}", real=True) for k in range(1, 8)]
RELATIVE_RANK_TOL = 1e-9


@dataclass(frozen=True)
class BaseParameters:
    """Names, meanings (in the standard parameters) and grouping record of one arm."""

    names: tuple[str, ...]
    leaders: tuple[sp.Symbol, ...]  # the standard parameter whose column each one uses
    meanings: tuple[sp.Expr, ...]
    rules: tuple[str, ...]  # the grouping as applied, for the report
    dropped: tuple[str, ...]  # standard parameters with no effect on any torque
    folded: tuple[str, ...]  # columns folded numerically, with their weights


def _regroup(robot: DHRobot) -> tuple[dict[sp.Symbol, sp.Expr], list[str]]:
    """The two grouping rules, tip to base: {kept standard parameter: its group}."""
    nj = len(robot.links)
    reg = [dict(link_params(j + 1)) for j in range(nj)]
    gone: set[str] = set()
    rules = []
    st = steps(robot)
    for j in range(nj - 1, -1, -1):
        par = reg[j]
        n = j + 1
        zero = {k: sp.Integer(0) for k in PARAM_KINDS}
        if robot.links[j].prismatic:
            delta = {**zero, **{k: par[k] for k in ("XX", "XY", "XZ", "YY", "YZ", "ZZ")}}
            gone |= {f"{k}{n}" for k in ("XX", "XY", "XZ", "YY", "YZ", "ZZ")}
            rules.append(f"joint {n} prismatic: XX{n} ... ZZ{n} (rotational inertia) move to link {n - 1}"
                         if j else f"joint 1 prismatic: XX1 ... ZZ1 turn with the base: no effect")
        else:
            yy = par["YY"]
            delta = {**zero, "XX": yy, "YY": yy, "MZ": par["MZ"], "M": par["M"]}
            par["XX"] = par["XX"] - yy
            gone |= {f"YY{n}", f"MZ{n}", f"M{n}"}
            rules.append(f"joint {n} revolute: XX{n} - YY{n} replaces XX{n}; YY{n}, MZ{n}, M{n} "
                         + (f"(symmetric about the axis) move to link {n - 1}" if j else
                            "(symmetric about the fixed axis) have no effect"))
        if j == 0:
            continue
        r0 = st[j].R.subs(Q[j], 0)
        p0 = [sp.sympify(x).subs(Q[j], 0) for x in st[j].p]
        moved = move_params(r0, p0, delta)
        for k in PARAM_KINDS:
            reg[j - 1][k] = sp.expand(reg[j - 1][k] + moved[k])
    kept = {}
    for j in range(nj):
        for k, s in link_params(j + 1).items():
            if s.name not in gone:
                kept[s] = sp.expand(reg[j][k])
    for r in ROTOR[:nj]:
        kept[r] = r
    return kept, rules


def numeric_columns(robot: DHRobot, names: Sequence[sp.Symbol], values: dict[sp.Symbol, float],
                     n: int = 24, seed: int = 3) -> np.ndarray:
    """The regressor columns of ``names`` at n random states, stacked: (nj n, len(names))."""
    nj = len(robot.links)
    prog = Program("w")
    cols = regressor(prog, robot, QD, QDD, keep=list(names))
    subs = {k: float(v) for k, v in values.items()}
    pr = NumPyPrinter({"fully_qualified_modules": False})
    args = [f"{v}{j}" for v in ("q", "qd", "qdd") for j in range(1, nj + 1)]
    lines = [f"def f({', '.join(args)}):"]
    for s, e in prog.defs:
        lines.append(f"    {s} = {pr.doprint(sp.sympify(e).xreplace(subs))}")
    outs = ", ".join(pr.doprint(sp.sympify(t).xreplace(subs)) for col in cols.torque for t in col)
    lines.append(f"    return [{outs}]")
    env = {"numpy": np, "sin": np.sin, "cos": np.cos}
    exec("\n".join(lines).replace("numpy.", ""), env)
    rng = np.random.default_rng(seed)
    x = rng.uniform(-2.0, 2.0, size=(3 * nj, n))
    vals = env["f"](*x)
    flat = np.array([np.broadcast_to(np.asarray(v, dtype=float), (n,)) for v in vals])  # (nj K, n)
    k = len(names)
    return flat.reshape(k, nj, n).transpose(2, 1, 0).reshape(nj * n, k)


def _small_rational(x: float) -> Fraction | None:
    f = Fraction(x).limit_denominator(64)
    return f if abs(float(f) - x) <= 1e-8 * max(1.0, abs(x)) else None


def base_parameters(robot: DHRobot, values: dict[sp.Symbol, float]) -> BaseParameters:
    """The base parameters of ``robot`` (``values``: its DH lengths and g, for the rank tests)."""
    kept, rules = _regroup(robot)
    syms = list(kept)
    y = numeric_columns(robot, syms, values)
    scale = np.abs(y).max()
    norms = np.abs(y).max(axis=0)
    dropped = [s for s, nrm in zip(syms, norms) if nrm <= RELATIVE_RANK_TOL * scale]
    live = [i for i, nrm in enumerate(norms) if nrm > RELATIVE_RANK_TOL * scale]
    chosen: list[int] = []
    folded = []
    meaning = {s: kept[s] for s in syms}
    for i in live:
        trial = chosen + [i]
        if np.linalg.matrix_rank(y[:, trial], tol=RELATIVE_RANK_TOL * scale) == len(trial):
            chosen = trial
            continue
        w, *_ = np.linalg.lstsq(y[:, chosen], y[:, i], rcond=None)
        weights = [_small_rational(float(x)) for x in w]
        if any(f is None for f in weights) or np.abs(y[:, chosen] @ w - y[:, i]).max() > 1e-8 * scale:
            raise ValueError(f"{robot.name}: regressor column {syms[i]} depends on the others with weights "
                             f"{w} that are not fixed small rationals: extend the grouping rules")
        text = []
        for c, f in zip(chosen, weights):
            if f != 0:
                meaning[syms[c]] = sp.expand(meaning[syms[c]] + sp.Rational(f.numerator, f.denominator) * meaning[syms[i]])
                text.append(f"{f} x {syms[c]}")
        folded.append(f"{syms[i]}: its column is " + " + ".join(text) + f"; {syms[i]} joins " +
                      ", ".join(str(syms[c]) for c, f in zip(chosen, weights) if f != 0))
    leaders = tuple(syms[i] for i in chosen)
    names = tuple(f"{s.name}R" if meaning[s] != s else s.name for s in leaders)
    return BaseParameters(names, leaders, tuple(meaning[s] for s in leaders), tuple(rules),
                          tuple(str(s) for s in dropped), tuple(folded))


def standard_from_links(robot: DHRobot) -> dict[sp.Symbol, sp.Expr]:
    """The 60 standard parameters (joint frames) in the data file's terms: mass m_k, centre
    of mass (x_k, y_k, z_k) and inertia about it (ixx_k ...), both in DH frame k."""
    out: dict[sp.Symbol, sp.Expr] = {}
    for k in range(len(robot.links)):
        m, c = MASS[k], COMS[k]
        ixx, iyy, izz, ixy, ixz, iyz = INERTIA[k]
        ic = sp.Matrix([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
        ch = sp.Matrix([[0, -c[2], c[1]], [c[2], 0, -c[0]], [-c[1], c[0], 0]])
        io = ic - m * ch * ch  # about the origin of frame k
        own = {"XX": io[0, 0], "XY": io[0, 1], "XZ": io[0, 2], "YY": io[1, 1], "YZ": io[1, 2],
               "ZZ": io[2, 2], "MX": m * c[0], "MY": m * c[1], "MZ": m * c[2], "M": m}
        link = robot.links[k]
        moved = move_params(rot_x(link.alpha), [link.a, 0, 0], own)
        for kind, s in link_params(k + 1).items():
            out[s] = sp.expand(moved[kind])
    return out


def numeric_standard(robot: DHRobot, values: dict[sp.Symbol, float], links) -> dict[sp.Symbol, float]:
    """The standard parameters of a model's link inertials (``rcci.models.LinkInertial``), numbers."""
    sub: dict[sp.Symbol, float] = dict(values)
    for k, li in enumerate(links):
        sub[MASS[k]] = float(li.mass)
        for s, v in zip(COMS[k], li.com):
            sub[s] = float(v)
        i = np.asarray(li.inertia, dtype=float)
        for s, v in zip(INERTIA[k], (i[0, 0], i[1, 1], i[2, 2], i[0, 1], i[0, 2], i[1, 2])):
            sub[s] = float(v)
    out = {}
    for s, e in standard_from_links(robot).items():
        v = float(sp.sympify(e).xreplace(sub))
        out[s] = 0.0 if abs(v) < 1e-15 else v
    return out
