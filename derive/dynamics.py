"""The whole dynamics equation (thesis 4.6): D(q) qdd + c(q, qd) + t_g(q) = t_j, derived as
straight-line programs (recursive Newton-Euler, composite rigid bodies), never expanded.

Frames. Link j's inertial parameters are written in its *joint frame* j': DH frame j-1 turned
by theta_j and shifted by d_j along z_{j-1} (so z_j' is joint j's axis and link j is fixed in
j'; DH frame j = j' Tx(a_j) Rx(alpha_j)). From (j-1)' to j' the step is
Tx(a_{j-1}) Rx(alpha_{j-1}) Rz(theta_j) Tz(d_j): a modified-DH step, which is what makes the
grouping rules of the base parameters short (``derive.dynamics_base``).

Parameters of link j (SI): XXj XYj XZj YYj YZj ZZj (inertia about the origin of j', kg m^2),
MXj MYj MZj (first moment m c, kg m), Mj (mass, kg); IAj is the rotor inertia of joint j
reflected to the joint (kg m^2, or kg on a prismatic joint), which adds IAj qdd_j to t_j.
Gravity is g = (0, 0, -g) in the base frame (4.22), entered as the base's acceleration +g z0.

Every quantity of the recursions is one symbol of a ``Program`` (an assignment list): the
expressions stay small, SymPy never multiplies the chain out, and the emitters share the
common subexpressions of the whole list.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Sequence

import sympy as sp

from derive.dh import Q, DHRobot
from derive.gravity import g0

#: joint rates and accelerations of up to 7 joints (a 6-joint arm uses the first six)
QD = sp.symbols("qd1:8", real=True)
QDD = sp.symbols("qdd1:8", real=True)
#: the ten inertial parameters of a link, in the order of the regressor's columns
PARAM_KINDS = ("XX", "XY", "XZ", "YY", "YZ", "ZZ", "MX", "MY", "MZ", "M")


def link_params(j: int) -> dict[str, sp.Symbol]:
    """The standard parameters of link j (1-based), by kind."""
    return {k: sp.Symbol(f"{k}{j}", real=True) for k in PARAM_KINDS}


#: the link parameters of up to 7 links, link by link (10 per link), and the rotor inertias;
#: an n-joint arm's are ``standard_params(n)`` and ``rotor_params(n)``
STANDARD: tuple[sp.Symbol, ...] = tuple(s for j in range(1, 8) for s in link_params(j).values())
ROTOR: tuple[sp.Symbol, ...] = tuple(sp.Symbol(f"IA{j}", real=True) for j in range(1, 8))


def standard_params(n: int) -> tuple[sp.Symbol, ...]:
    """The 10 n standard link parameters of an n-joint arm (60 for the thesis's arms)."""
    return STANDARD[:10 * n]


def rotor_params(n: int) -> tuple[sp.Symbol, ...]:
    """The n rotor inertias IA1..IAn."""
    return ROTOR[:n]


def cross(a: Sequence[sp.Expr], b: Sequence[sp.Expr]) -> list[sp.Expr]:
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def hat(p: Sequence[sp.Expr]) -> sp.Matrix:
    return sp.Matrix([[0, -p[2], p[1]], [p[2], 0, -p[0]], [-p[1], p[0], 0]])


class Program:
    """An assignment list: ``let`` names an expression (numbers and symbols stay as they are)."""

    def __init__(self, prefix: str) -> None:
        self.defs: list[tuple[sp.Symbol, sp.Expr]] = []
        self._names = sp.numbered_symbols(prefix, real=True)

    def let(self, e: sp.Expr) -> sp.Expr:
        e = sp.sympify(e)
        if e.is_Atom or (e.is_Mul and len(e.args) == 2 and e.args[0].is_Number and e.args[1].is_Atom):
            return e
        s = next(self._names)
        self.defs.append((s, e))
        return s

    def vec(self, v: Sequence[sp.Expr]) -> list[sp.Expr]:
        return [self.let(x) for x in v]


def rot_x(alpha: sp.Expr) -> sp.Matrix:
    c, s = sp.cos(alpha), sp.sin(alpha)
    return sp.Matrix([[1, 0, 0], [0, c, -s], [0, s, c]])


def rot_z(theta: sp.Expr) -> sp.Matrix:
    c, s = sp.cos(theta), sp.sin(theta)
    return sp.Matrix([[c, -s, 0], [s, c, 0], [0, 0, 1]])


@dataclass(frozen=True)
class Step:
    """From joint frame (j-1)' to j' (j = 1: from the base frame 0): rotation and origin."""

    R: sp.Matrix
    p: list[sp.Expr]
    prismatic: bool


def steps(robot: DHRobot) -> list[Step]:
    """The six steps Tx(a_{j-1}) Rx(alpha_{j-1}) Rz(theta_j) Tz(d_j), in the joint variables."""
    out = []
    for j, link in enumerate(robot.links):
        prev_a, prev_alpha = (0, 0) if j == 0 else (robot.links[j - 1].a, robot.links[j - 1].alpha)
        rx = rot_x(prev_alpha)
        p = [prev_a, -sp.sin(prev_alpha) * link.d, sp.cos(prev_alpha) * link.d]
        out.append(Step(rx * rot_z(link.theta), p, link.prismatic))
    return out


def link_frame_offset(robot: DHRobot, j: int) -> tuple[sp.Matrix, list[sp.Expr]]:
    """DH frame j in joint frame j': Tx(a_j) Rx(alpha_j) as (rotation, origin)."""
    link = robot.links[j - 1]
    return rot_x(link.alpha), [link.a, 0, 0]


@dataclass
class Motion:
    """Forward recursion: angular velocity, angular acceleration and origin acceleration
    (gravity included) of every joint frame, in that frame; the rotations as symbols."""

    w: list[list[sp.Expr]]
    dw: list[list[sp.Expr]]
    a: list[list[sp.Expr]]
    R: list[sp.Matrix]  # R[j]: (j-1)' to j' (0-based j), entries as program symbols
    p: list[list[sp.Expr]]


def motion(prog: Program, robot: DHRobot, qd: Sequence[sp.Expr], qdd: Sequence[sp.Expr],
           gravity: sp.Expr = g0) -> Motion:
    """Newton-Euler outward pass (velocities and accelerations of the joint frames)."""
    w = [sp.Integer(0)] * 3
    dw = [sp.Integer(0)] * 3
    a = [sp.Integer(0), sp.Integer(0), gravity]
    ws, dws, accs, rs, ps = [], [], [], [], []
    for j, st in enumerate(steps(robot)):
        r = st.R.applyfunc(prog.let)
        p = prog.vec(st.p)
        rt = r.T
        # origin of j' moves with frame (j-1)'
        a_o = [a[k] + x + y for k, (x, y) in enumerate(zip(cross(dw, p), cross(w, cross(w, p))))]
        a_new = prog.vec(list(rt * sp.Matrix(a_o)))
        w_in = prog.vec(list(rt * sp.Matrix(w)))
        dw_in = prog.vec(list(rt * sp.Matrix(dw)))
        if st.prismatic:
            w_new, dw_new = w_in, dw_in
            cor = cross(w_new, [0, 0, 2 * qd[j]])
            a_new = prog.vec([a_new[0] + cor[0], a_new[1] + cor[1], a_new[2] + qdd[j]])
        else:
            w_new = prog.vec([w_in[0], w_in[1], w_in[2] + qd[j]])
            dw_new = prog.vec([dw_in[0] + w_in[1] * qd[j], dw_in[1] - w_in[0] * qd[j], dw_in[2] + qdd[j]])
        ws.append(w_new), dws.append(dw_new), accs.append(a_new), rs.append(r), ps.append(p)
        w, dw, a = w_new, dw_new, a_new
    return Motion(ws, dws, accs, rs, ps)


def inertia_tensor(par: dict[str, sp.Expr]) -> sp.Matrix:
    return sp.Matrix([[par["XX"], par["XY"], par["XZ"]], [par["XY"], par["YY"], par["YZ"]],
                      [par["XZ"], par["YZ"], par["ZZ"]]])


def body_wrench(w, dw, a, par: dict[str, sp.Expr]) -> tuple[list[sp.Expr], list[sp.Expr]]:
    """Force and moment about the frame origin that accelerate one body (Newton-Euler)."""
    h = [par["MX"], par["MY"], par["MZ"]]
    inertia = inertia_tensor(par)
    iw = list(inertia * sp.Matrix(w))
    f = [par["M"] * a[k] + x + y for k, (x, y) in enumerate(zip(cross(dw, h), cross(w, cross(w, h))))]
    n = [x + y + z for x, y, z in zip(list(inertia * sp.Matrix(dw)), cross(w, iw), cross(h, a))]
    return f, n


def transport(prog: Program, r: sp.Matrix, p, f, n) -> tuple[list[sp.Expr], list[sp.Expr]]:
    """A wrench in frame j' seen in frame (j-1)' (R, p: the step from (j-1)' to j')."""
    f2 = prog.vec(list(r * sp.Matrix(f)))
    n2 = list(r * sp.Matrix(n))
    n2 = prog.vec([x + y for x, y in zip(n2, cross(p, f2))])
    return f2, n2


def rnea(prog: Program, robot: DHRobot, params: Sequence[dict[str, sp.Expr]], qd, qdd,
         rotor: Sequence[sp.Expr] | None = None, gravity: sp.Expr = g0) -> list[sp.Expr]:
    """Joint torques t_j of 4.6 without friction: D qdd + c + t_g (+ rotor IA_j qdd_j)."""
    nj = len(robot.links)
    rotor = (0,) * nj if rotor is None else rotor
    m = motion(prog, robot, qd, qdd, gravity)
    tau: list[sp.Expr] = [sp.Integer(0)] * nj
    f_tot: list[sp.Expr] | None = None
    n_tot: list[sp.Expr] | None = None
    for j in range(nj - 1, -1, -1):
        f, n = body_wrench(m.w[j], m.dw[j], m.a[j], params[j])
        if f_tot is not None:
            fc, nc = transport(prog, m.R[j + 1], m.p[j + 1], f_tot, n_tot)
            f, n = [x + y for x, y in zip(f, fc)], [x + y for x, y in zip(n, nc)]
        f_tot, n_tot = prog.vec(f), prog.vec(n)
        axis = f_tot[2] if robot.links[j].prismatic else n_tot[2]
        tau[j] = axis + rotor[j] * qdd[j]
    return tau


def move_params(r: sp.Matrix, p, par: dict[str, sp.Expr], let: Callable = lambda e: e) -> dict[str, sp.Expr]:
    """Parameters of a body given in frame B, written in frame A (B's orientation r and
    origin p in A): mass unchanged, h' = R h + m p, I' = R I R^T - [Rh][p] - [p][Rh] - m [p]^2."""
    mass = par["M"]
    rh = [let(x) for x in r * sp.Matrix([par["MX"], par["MY"], par["MZ"]])]
    h2 = [rh[k] + mass * p[k] for k in range(3)]
    ph, rhh = hat(p), hat(rh)
    i2 = r * inertia_tensor(par) * r.T - rhh * ph - ph * rhh - mass * ph * ph
    return {"XX": i2[0, 0], "XY": i2[0, 1], "XZ": i2[0, 2], "YY": i2[1, 1], "YZ": i2[1, 2],
            "ZZ": i2[2, 2], "MX": h2[0], "MY": h2[1], "MZ": h2[2], "M": mass}


def crba(prog: Program, robot: DHRobot, params: Sequence[dict[str, sp.Expr]],
         rotor: Sequence[sp.Expr] | None = None) -> sp.Matrix:
    """The inertia matrix D(q) (4.6) by composite rigid bodies, in the joint frames."""
    nj = len(robot.links)
    rotor = (0,) * nj if rotor is None else rotor
    st = steps(robot)
    rs = [s.R.applyfunc(prog.let) for s in st]
    ps = [prog.vec(s.p) for s in st]
    comp: list[dict[str, sp.Expr]] = [dict() for _ in range(nj)]
    comp[nj - 1] = {k: prog.let(v) for k, v in params[nj - 1].items()}
    for j in range(nj - 2, -1, -1):
        moved = move_params(rs[j + 1], ps[j + 1], comp[j + 1], prog.let)
        comp[j] = {k: prog.let(params[j][k] + moved[k]) for k in PARAM_KINDS}
    d = sp.zeros(nj, nj)
    for j in range(nj):
        c = comp[j]
        if robot.links[j].prismatic:
            n, f = [c["MY"], -c["MX"], 0], [0, 0, c["M"]]
        else:
            n, f = [c["XZ"], c["YZ"], c["ZZ"]], [-c["MY"], c["MX"], 0]
        d[j, j] = (f[2] if robot.links[j].prismatic else n[2]) + rotor[j]
        for i in range(j - 1, -1, -1):
            f, n = transport(prog, rs[i + 1], ps[i + 1], f, n)
            d[i, j] = d[j, i] = f[2] if robot.links[i].prismatic else n[2]
    return d


def derivatives(prog: Program, outputs: Sequence[sp.Expr], wrt: Sequence[sp.Symbol],
                first: int = 0) -> list[list[sp.Expr]]:
    """Forward-mode derivatives of ``outputs`` (written in the program's symbols from
    ``prog.defs[first:]`` on) with respect to each symbol of ``wrt``: appends the derivative
    assignments to the program; returns [d outputs / d wrt_k for k]."""
    result = []
    defs = list(prog.defs[first:])
    for x in wrt:
        dmap: dict[sp.Symbol, sp.Expr] = {}

        def d(e: sp.Expr) -> sp.Expr:
            e = sp.sympify(e)
            total = sp.Integer(0)
            for s in e.free_symbols:
                ds = sp.Integer(1) if s == x else dmap.get(s, sp.Integer(0))
                if ds != 0:
                    total += sp.diff(e, s) * ds
            return total

        for s, e in defs:
            dv = prog.let(d(e))
            if dv != 0:
                dmap[s] = dv
        result.append([prog.let(d(o)) for o in outputs])
    return result


def coriolis_matrix(prog: Program, d: sp.Matrix, qd: Sequence[sp.Expr], first: int = 0) -> sp.Matrix:
    """Christoffel form C(q, qd) of c = C qd with D' - 2C skew (what Pinocchio computes):
    C = (D' + P - P^T) / 2, P_kj = d(D qd)_k / d q_j, D' = sum_j qd_j dD/dq_j."""
    nj = d.rows
    flat = [d[i, j] for i in range(nj) for j in range(i, nj)]
    index = {}
    n = 0
    for i in range(nj):
        for j in range(i, nj):
            index[(i, j)] = index[(j, i)] = n
            n += 1
    dd = derivatives(prog, flat, Q[:nj], first)  # dd[k][index(i, j)] = dD_ij / dq_k
    ddot = sp.Matrix(nj, nj, lambda i, j: prog.let(sum(qd[k] * dd[k][index[(i, j)]] for k in range(nj))))
    pm = sp.Matrix(nj, nj, lambda k, j: prog.let(sum(dd[j][index[(k, i)]] * qd[i] for i in range(nj))))
    return sp.Matrix(nj, nj, lambda k, j: prog.let((ddot[k, j] + pm[k, j] - pm[j, k]) / 2))


@dataclass
class Columns:
    """The regressor: per parameter, its six joint torques (program symbols)."""

    names: list[sp.Symbol] = field(default_factory=list)
    torque: list[list[sp.Expr]] = field(default_factory=list)


def regressor(prog: Program, robot: DHRobot, qd, qdd, keep: Sequence[sp.Symbol] | None = None,
              combos: dict[sp.Symbol, dict[sp.Symbol, sp.Expr]] | None = None,
              gravity: sp.Expr = g0) -> Columns:
    """dt_j/d(parameter) for the standard parameters (or only ``keep``), linear by
    construction: each parameter's unit wrench on its link carried down the chain.
    ``combos`` maps a column name to {standard parameter: weight} (a base column that is a
    fixed combination of standard columns); default: each kept parameter's own column."""
    m = motion(prog, robot, qd, qdd, gravity)
    nj = len(robot.links)
    wanted = list(keep) if keep is not None else list(standard_params(nj)) + list(rotor_params(nj))
    combos = combos or {p: {p: sp.Integer(1)} for p in wanted}
    out = Columns()
    for name in wanted:
        parts = combos[name]
        # the standard columns of this combination, link by link (tip first: carry down)
        tau = [sp.Integer(0)] * nj
        by_link: dict[int, dict[str, sp.Expr]] = {}
        for p, weight in parts.items():
            if p in ROTOR:
                j = ROTOR.index(p)
                tau[j] += weight * qdd[j]
                continue
            j = STANDARD.index(p) // 10
            by_link.setdefault(j, {k: sp.Integer(0) for k in PARAM_KINDS})[PARAM_KINDS[STANDARD.index(p) % 10]] += weight
        f_tot = n_tot = None
        for j in range(nj - 1, -1, -1):
            if f_tot is not None:
                f_tot, n_tot = transport(prog, m.R[j + 1], m.p[j + 1], f_tot, n_tot)
            if j in by_link:
                f, n = body_wrench(m.w[j], m.dw[j], m.a[j], by_link[j])
                if f_tot is None:
                    f_tot, n_tot = prog.vec(f), prog.vec(n)
                else:
                    f_tot = prog.vec([x + y for x, y in zip(f_tot, f)])
                    n_tot = prog.vec([x + y for x, y in zip(n_tot, n)])
            if f_tot is not None:
                tau[j] += f_tot[2] if robot.links[j].prismatic else n_tot[2]
        out.names.append(name)
        out.torque.append([prog.let(t) for t in tau])
    return out
