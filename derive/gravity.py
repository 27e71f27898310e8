"""The gravity loading vector (thesis 4.8-4.26), derived from the general formula 4.20.

tau_g_i = -h_i sum_{k>=i} m_k U_k r_k, with h_i = (g.o_{i-1}, -g.n_{i-1}, 0, 0) for a
revolute joint and (0, 0, 0, g.a_{i-1}) for a prismatic one, U_k the transform from
frame i-1 to frame k and r_k the centre of mass of link k in frame k. tau_g is the
torque (force) each joint must exert to hold the arm against gravity (N m, N).
The base is mounted upright: g = (0, 0, -g0) in the base frame with g0 > 0 (4.22 prints
g^T = (0 0 g 0) with the sign of g lost; the measured coefficients of Table 4.9 fix it).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import sympy as sp

from derive.dh import Q, DHRobot
from derive.forward import base_to_link, link_to_link, simplifier, tidy

g0 = sp.Symbol("g", positive=True)
#: link masses and centres of mass of up to 7 links (a 6-joint arm uses the first six)
MASSES = sp.symbols("m1:8", positive=True)
COM = [sp.symbols(f"x{k} y{k} z{k}", real=True) for k in range(1, 8)]
#: tool load of 4.26: mass m_t at distance d_t along z6
m_t, d_t = sp.symbols("m_t d_t", real=True)


def gravity_general(robot: DHRobot, com: list[tuple[sp.Expr, sp.Expr, sp.Expr]],
                    masses=MASSES) -> sp.Matrix:
    """Thesis 4.20 for arbitrary centres of mass ``com[k-1]`` in frame k."""
    gvec = sp.Matrix([0, 0, -g0])
    n_links = len(robot.links)
    tau = []
    for i in range(1, n_links + 1):
        t_prev = base_to_link(robot, i - 1)
        n, o, a = t_prev[:3, 0], t_prev[:3, 1], t_prev[:3, 2]
        if robot.links[i - 1].prismatic:
            h = sp.Matrix([[0, 0, 0, (gvec.T * a)[0]]])
        else:
            h = sp.Matrix([[(gvec.T * o)[0], -(gvec.T * n)[0], 0, 0]])
        total = sp.zeros(4, 1)
        for k in range(i, n_links + 1):
            r = sp.Matrix([*com[k - 1], 1])
            total += masses[k - 1] * link_to_link(robot, i - 1, k) * r
        tau.append(simplifier(robot)(-(h * total)[0]))
    return sp.Matrix(tau)


@dataclass(frozen=True)
class GravityModel:
    """tau_g(q) = regressor(q) * coeffs, with each coefficient's physical meaning."""

    robot: DHRobot
    general: sp.Matrix  # 4.20 with the centre-of-mass assumptions substituted
    coeff_names: tuple[str, ...]
    coeff_symbols: tuple[sp.Symbol, ...]
    coeff_meaning: tuple[sp.Expr, ...]  # each coefficient in masses and centres of mass
    regressor: sp.Matrix  # 6 x k
    tool_update: tuple[sp.Expr, ...]  # 4.26: coefficient increments for a tool load
    com: tuple  # the centre-of-mass assumptions used


def _group(robot: DHRobot, general: sp.Matrix, meanings: dict[str, sp.Expr],
           com, tool_com) -> GravityModel:
    """Rewrite ``general`` as regressor * coefficients and prove the rewrite exact."""
    lengths = {g0, *robot.params}
    names = tuple(meanings)
    syms = tuple(sp.Symbol(n, real=True) for n in names)
    # eliminate one mass-moment combination per coefficient: solve meaning_j = c_j for
    # one inertial symbol each, substitute, and the remainder must vanish identically
    rows = []
    for e in general:
        rows.append(sp.expand(e))
    unknowns = []
    for name, expr in meanings.items():
        free = sorted((s for s in sp.expand(expr).free_symbols if s not in lengths),
                      key=sp.default_sort_key)
        unknowns.append(free)
    elim = {}
    used = set()
    for (name, expr), sym, free in zip(meanings.items(), syms, unknowns):
        target = next(s for s in free if s not in used and s not in elim)
        used.add(target)
        sol = sp.solve(sp.Eq(expr.subs(elim), sym), target)
        assert len(sol) == 1, (name, sol)
        elim = {k: v.subs(target, sol[0]) for k, v in elim.items()}
        elim[target] = sol[0]
    grouped = [sp.expand(sp.expand(r).subs(elim)) for r in rows]
    regressor = sp.Matrix([[tidy(g.coeff(s)) for s in syms] for g in grouped])
    residual = [sp.simplify(sp.expand(g - sum(regressor[i, j] * syms[j] for j in range(len(syms)))))
                for i, g in enumerate(grouped)]
    if not all(r == 0 for r in residual):
        raise ValueError(f"{robot.name}: gravity_grouping: eq. 4.20 does not group into the "
                         f"model file's coefficients; remainder {residual}")
    # 4.26: a point mass m_t at d_t along z6 joins link 6 (mass and first moment add)
    shifted = {}
    for name, expr in meanings.items():
        bumped = expr.subs(tool_com, simultaneous=True)
        shifted[name] = sp.simplify(sp.expand(bumped - expr))
    return GravityModel(robot, general, names, syms, tuple(meanings.values()), regressor,
                        tuple(shifted[n] for n in names), tuple(com))



def tool_substitution(n: int) -> dict[sp.Symbol, sp.Expr]:
    """The tool load of 4.26 as a substitution: a point mass m_t at d_t along the last
    link's z axis (z6 of the thesis arms) joins link n (mass and first moment add)."""
    m, (x, y, z) = MASSES[n - 1], COM[n - 1]
    return {m: m + m_t, x: m * x / (m + m_t), y: m * y / (m + m_t), z: (m * z + m_t * d_t) / (m + m_t)}


#: the thesis arms' tool substitution (link 6)
TOOL = tool_substitution(6)


def _symbols(robot: DHRobot) -> dict[str, sp.Symbol]:
    """The names a model file's grouping may use: masses, centres of mass, g, DH lengths."""
    n = len(robot.links)
    out = {s.name: s for s in (*MASSES[:n], *(c for r in COM[:n] for c in r), g0, *robot.params)}
    return out


def grouped_gravity(robot: DHRobot, com_form, meanings) -> GravityModel:
    """4.20 with the model file's centre-of-mass form, grouped into its named coefficients
    (thesis 4.21 and 4.24 for the PUMA 260)."""
    names = _symbols(robot)

    def parse(text: str, where: str) -> sp.Expr:
        try:
            e = sp.sympify(text, locals=names)
        except (sp.SympifyError, SyntaxError, TypeError) as exc:
            raise ValueError(f"{robot.name}: gravity_grouping.{where}: {text!r} is not an expression: {exc}") from None
        unknown = e.free_symbols - set(names.values())
        if unknown:
            raise ValueError(f"{robot.name}: gravity_grouping.{where}: unknown symbol(s) "
                             f"{sorted(map(str, unknown))} (use m1..m6, x1..z6, g and the DH lengths)")
        return e

    com = [tuple(parse(x, f"com_form[{k}]") for x in row) for k, row in enumerate(com_form)]
    general = gravity_general(robot, com)
    return _group(robot, general, {n: parse(t, f"meanings.{n}") for n, t in meanings}, com,
                  tool_substitution(len(robot.links)))


def minimal_gravity(robot: DHRobot, values: dict[sp.Symbol, float]) -> GravityModel:
    """The minimal identifiable set of gravity coefficients of an arm, found from its table.

    tau_g is linear in the 24 inertial parameters m_k and m_k r_k; expanded in sines and
    cosines of the joint variables, its columns (one per parameter) span a space whose
    dimension is the number of identifiable combinations. The first moments are kept in
    the order x1, y1, z1, x2, ... and the masses last, each where it adds to the rank (at
    the model's lengths ``values``); every other column is solved exactly as a combination
    of the kept ones, which folds its parameter into theirs (as 4.24 folds a2 (m2+..+m6)
    into c12). Coefficient ``c<axis><k>`` is g times the group led by m_k <axis>_k (N m or N).
    """
    n_links = len(robot.links)
    moments = [sp.Symbol(f"{a}{k}_moment", real=True) for k in range(1, n_links + 1) for a in "xyz"]
    phi = moments + list(MASSES[:n_links])
    com = [tuple(moments[3 * k + j] / MASSES[k] for j in range(3)) for k in range(n_links)]
    tau = sp.Matrix([sp.expand(e) for e in gravity_general(robot, com)])
    # sines and cosines of the revolute joints' angles, a prismatic joint's extension itself
    gens = [g for q, link in zip(Q, robot.links)
            for g in ((q,) if link.prismatic else (sp.sin(q), sp.cos(q)))]

    def coefficients(expr: sp.Expr) -> dict:
        poly = sp.Poly(sp.expand(sp.expand_trig(expr)), *gens)
        return dict(poly.terms())

    cols = []  # per parameter: {(row, monomial): coefficient}
    for p in phi:
        col = {}
        for i in range(n_links):
            for mono, c in coefficients(sp.diff(tau[i], p)).items():
                col[(i, mono)] = c
        cols.append(col)
    keys = sorted(set().union(*cols), key=str)
    c_sym = sp.Matrix([[col.get(k, 0) for col in cols] for k in keys])
    c_num = np.array(c_sym.subs(values).evalf(), dtype=float)
    kept: list[int] = []
    for j in range(len(phi)):
        trial = kept + [j]
        if np.linalg.matrix_rank(c_num[:, trial], tol=1e-9 * max(1.0, np.abs(c_num).max())) == len(trial):
            kept = trial
    # rows that make the kept columns square and regular, for the exact solves
    rows: list[int] = []
    for r in range(len(keys)):
        trial = rows + [r]
        if np.linalg.matrix_rank(c_num[trial][:, kept]) == len(trial):
            rows = trial
        if len(rows) == len(kept):
            break
    a = c_sym.extract(rows, kept)
    beta = {j: phi[j] for j in kept}
    for j in range(len(phi)):
        if j in kept:
            continue
        k = a.LUsolve(c_sym.extract(rows, [j])).applyfunc(sp.simplify)
        check = (c_sym.extract(list(range(len(keys))), kept) * k - c_sym[:, j]).applyfunc(sp.simplify)
        if any(e != 0 for e in check):
            raise ValueError(f"{robot.name}: gravity column {phi[j]} is not a fixed combination of the kept ones")
        for n, jj in enumerate(kept):
            beta[jj] = beta[jj] + k[n] * phi[j]
    to_links = {moments[3 * k + j]: MASSES[k] * COM[k][j] for k in range(n_links) for j in range(3)}
    names, meanings, columns = [], {}, []
    for jj in kept:
        p = phi[jj]
        name = f"c{p.name[0]}{p.name[1]}" if p in moments else f"cm{p.name[1:]}"
        names.append(name)
        meanings[name] = sp.expand(g0 * beta[jj].subs(to_links))
        columns.append(jj)
    regressor = sp.Matrix([[sp.expand(sp.diff(tau[i], phi[jj]) / g0) for jj in columns] for i in range(n_links)])
    regressor = regressor.applyfunc(simplifier(robot))
    syms = tuple(sp.Symbol(n, real=True) for n in names)
    # exact: tau = regressor * (g beta), beta in the moments
    beta_m = [g0 * beta[jj] for jj in columns]
    residual = (tau - regressor * sp.Matrix(beta_m)).applyfunc(lambda e: sp.simplify(sp.expand(sp.expand_trig(e))))
    if any(e != 0 for e in residual):
        raise ValueError(f"{robot.name}: minimal gravity regressor is not exact: {list(residual)}")
    general = gravity_general(robot, [tuple(r) for r in COM[:n_links]])
    tool_sub = tool_substitution(n_links)
    tool = tuple(sp.simplify(sp.expand(meanings[n].subs(tool_sub, simultaneous=True) - meanings[n])) for n in names)
    return GravityModel(robot, general, tuple(names), syms, tuple(meanings[n] for n in names),
                        regressor, tool, tuple(tuple(r) for r in COM[:n_links]))


def gravity_model(spec) -> GravityModel:
    """The gravity model of a ``derive.robots.RobotSpec``: the model file's grouping when it
    gives one, else the minimal identifiable set."""
    if spec.com_form is not None:
        return grouped_gravity(spec.dh, spec.com_form, spec.meanings)
    return minimal_gravity(spec.dh, spec.params)
