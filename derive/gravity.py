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

import sympy as sp

from derive.dh import Q, DHRobot, a2, d4
from derive.forward import base_to_link, link_to_link, tidy

g0 = sp.Symbol("g", positive=True)
MASSES = sp.symbols("m1:7", positive=True)
COM = [sp.symbols(f"x{k} y{k} z{k}", real=True) for k in range(1, 7)]
#: tool load of 4.26: mass m_t at distance d_t along z6
m_t, d_t = sp.symbols("m_t d_t", real=True)


def gravity_general(robot: DHRobot, com: list[tuple[sp.Expr, sp.Expr, sp.Expr]],
                    masses=MASSES) -> sp.Matrix:
    """Thesis 4.20 for arbitrary centres of mass ``com[k-1]`` in frame k."""
    gvec = sp.Matrix([0, 0, -g0])
    tau = []
    for i in range(1, 7):
        t_prev = base_to_link(robot, i - 1)
        n, o, a = t_prev[:3, 0], t_prev[:3, 1], t_prev[:3, 2]
        if robot.links[i - 1].prismatic:
            h = sp.Matrix([[0, 0, 0, (gvec.T * a)[0]]])
        else:
            h = sp.Matrix([[(gvec.T * o)[0], -(gvec.T * n)[0], 0, 0]])
        total = sp.zeros(4, 1)
        for k in range(i, 7):
            r = sp.Matrix([*com[k - 1], 1])
            total += masses[k - 1] * link_to_link(robot, i - 1, k) * r
        tau.append(tidy(-(h * total)[0]))
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
    names = tuple(meanings)
    syms = tuple(sp.Symbol(n, real=True) for n in names)
    # eliminate one mass-moment combination per coefficient: solve meaning_j = c_j for
    # one inertial symbol each, substitute, and the remainder must vanish identically
    rows = []
    for e in general:
        rows.append(sp.expand(e))
    unknowns = []
    for name, expr in meanings.items():
        free = sorted((s for s in sp.expand(expr).free_symbols if s not in (g0, a2, d4)),
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
    assert all(r == 0 for r in residual), f"{robot.name}: gravity does not group: {residual}"
    # 4.26: a point mass m_t at d_t along z6 joins link 6 (mass and first moment add)
    shifted = {}
    for name, expr in meanings.items():
        bumped = expr.subs(tool_com, simultaneous=True)
        shifted[name] = sp.simplify(sp.expand(bumped - expr))
    return GravityModel(robot, general, names, syms, tuple(meanings.values()), regressor,
                        tuple(shifted[n] for n in names), tuple(com))


def puma_gravity() -> GravityModel:
    """PUMA 260 with the centres of mass of 4.21, grouped as in 4.24."""
    from derive.dh import PUMA260

    (x1, y1, z1), (x2, y2, z2), (x3, y3, z3), (x4, y4, z4), (x5, y5, z5), (x6, y6, z6) = COM
    com = [(0, 0, z1), (x2, 0, z2), (0, 0, z3), (0, y4, 0), (0, 0, z5), (0, 0, z6)]
    general = gravity_general(PUMA260, com)
    m1, m2, m3, m4, m5, m6 = MASSES
    meanings = {
        "c12": g0 * (m2 * x2 + a2 * (m2 + m3 + m4 + m5 + m6)),
        "c13": -g0 * (m3 * z3 + m4 * y4 + d4 * (m4 + m5 + m6)),
        "c15": -g0 * (m5 * z5 + m6 * z6),
    }
    # the tool: link 6's first moment m6*z6 grows by m_t*d_t
    tool = {m6: m6 + m_t, z6: (m6 * z6 + m_t * d_t) / (m6 + m_t)}
    return _group(PUMA260, general, meanings, com, tool)


def microbo_gravity() -> GravityModel:
    """Microbo: 4.20 with the prismatic h; centres of mass chosen as on the PUMA.

    The thesis measured no Microbo gravity (4.1: its gearing made that impractical), so
    the grouping is ours: links 4-6 carry their mass on the joint-4 axis (y4) and on the
    tool axis (z5, z6); links 1-3 anywhere.
    """
    from derive.dh import MICROBO

    (x1, y1, z1), (x2, y2, z2), (x3, y3, z3), (x4, y4, z4), (x5, y5, z5), (x6, y6, z6) = COM
    com = [(x1, y1, z1), (x2, y2, z2), (x3, y3, z3), (0, y4, 0), (0, 0, z5), (0, 0, z6)]
    general = gravity_general(MICROBO, com)
    m1, m2, m3, m4, m5, m6 = MASSES
    # named as models/microbo.toml names them: c12 the lift force of the vertical axis
    # (N), c15 with the PUMA's definition (N m)
    meanings = {
        "c12": g0 * (m2 + m3 + m4 + m5 + m6),
        "c15": -g0 * (m5 * z5 + m6 * z6),
    }
    tool = {m6: m6 + m_t, z6: (m6 * z6 + m_t * d_t) / (m6 + m_t)}
    return _group(MICROBO, general, meanings, com, tool)
