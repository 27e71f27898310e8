"""Differential kinematics: the D and F maps (1.13, 1.23), the link-4 Jacobian
(3.54-3.61), the PUMA's modified 4J' (3.62-3.67), the symbolic inverses (3.68, 3.70),
the four Jacobian computations (3.71-3.78) and the frame 4 <-> 6 maps (3.79-3.82).

Differential vectors are (dx, dy, dz, delta_x, delta_y, delta_z); force vectors
(fx, fy, fz, mx, my, mz); both observed in the frame named by the superscript.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass

import sympy as sp

from derive.dh import Q, DHRobot
from derive.forward import link_to_link, simplifier, tidy, tidy_matrix


def _cross(u: sp.Matrix, v: sp.Matrix) -> sp.Matrix:
    return u.cross(v)


def d_map(x: sp.Matrix) -> sp.Matrix:
    """Thesis 1.13: D_{O,X}, mapping a differential change seen in O to X.

    x is the transform from O to X with columns n, o, a, p. Row blocks are
    [n^T, (p x n)^T], [o^T, (p x o)^T], [a^T, (p x a)^T] for the translations and
    [0, n^T], ... for the rotations (the print writes "p . n" for p x n).
    """
    n, o, a, p = (x[:3, j] for j in range(4))
    rows = []
    for v in (n, o, a):
        rows.append(list(v.T) + list(_cross(p, v).T))
    for v in (n, o, a):
        rows.append([0, 0, 0] + list(v.T))
    return sp.Matrix(rows)


def f_map(x: sp.Matrix) -> sp.Matrix:
    """Thesis 1.23: F_{O,X}, mapping a force vector seen in O to X (= D_{O,X}^-T)."""
    n, o, a, p = (x[:3, j] for j in range(4))
    rows = []
    for v in (n, o, a):
        rows.append(list(v.T) + [0, 0, 0])
    for v in (n, o, a):
        rows.append(list(_cross(p, v).T) + list(v.T))
    return sp.Matrix(rows)


def joint_screw(prismatic: bool) -> sp.Matrix:
    """Thesis 3.56: c_i, a unit change along (prismatic) or about (revolute) z_{i-1}."""
    c = sp.zeros(6, 1)
    c[2 if prismatic else 5] = 1
    return c


def link_jacobian(robot: DHRobot, k: int) -> sp.Matrix:
    """Thesis 3.57-3.61: kJ, the Jacobian of link 6's motion observed in link k.

    Column i is D_{i-1,k}(c_i) with X = transform from frame i-1 to frame k. For
    joints beyond k the transform is the inverse of A_k+1..A_i-1; this is valid because
    the motion is of link 6, whose origin coincides with those of frames 4 and 5 on both
    arms (A5 and A6 have no translation).
    """
    cols = []
    for i in range(1, len(robot.links) + 1):
        x = link_to_link(robot, i - 1, k)
        cols.append((d_map(x) * joint_screw(robot.links[i - 1].prismatic)).applyfunc(simplifier(robot)))
    return sp.Matrix.hstack(*cols)


def y_matrix() -> sp.Matrix:
    """Thesis 3.63: Y with (dq1, dq2, dq2 + dq3, dq4, dq5, dq6) = Y dq."""
    y = sp.eye(6)
    y[2, 1] = 1
    return y


def block_inverse(j: sp.Matrix) -> sp.Matrix:
    """Inverse of a 6x6 Jacobian whose top-right 3x3 block is zero.

    Both arms' link-4 Jacobians have this shape (the wrist joints do not move the wrist
    centre), so J^-1 = [[J11^-1, 0], [-J22^-1 J21 J11^-1, J22^-1]], each 3x3 inverse by
    the adjugate and simplified.
    """
    assert j[:3, 3:] == sp.zeros(3, 3), "top-right block must vanish"
    j11, j21, j22 = j[:3, :3], j[3:, :3], j[3:, 3:]
    i11 = _inv3(j11)
    i22 = _inv3(j22)
    out = sp.zeros(6, 6)
    out[:3, :3] = i11
    out[3:, 3:] = i22
    out[3:, :3] = (-i22 * j21 * i11).applyfunc(lambda e: sp.factor(tidy(e)))
    return out.applyfunc(_no_tan)


def _no_tan(e: sp.Expr) -> sp.Expr:
    """Write tan as sin/cos: trigsimp likes tan, but tan(q5) is infinite at q5 = pi/2."""
    return sp.factor(e.replace(sp.tan, lambda x: sp.sin(x) / sp.cos(x)))


def _inv3(m: sp.Matrix) -> sp.Matrix:
    det = sp.factor(tidy(m.det()))
    adj = m.adjugate().applyfunc(tidy)
    return (adj / det).applyfunc(sp.factor)


@dataclass(frozen=True)
class Differential:
    """Everything chapter 3.5-3.7 derives for one robot."""

    robot: DHRobot
    j4: sp.Matrix  # 4J
    j6: sp.Matrix  # 6J
    j4_reduced: sp.Matrix  # 4J' (PUMA) or 4J (Microbo): the matrix that is inverted
    j4_reduced_inv: sp.Matrix | None  # None for a 7-joint arm (6 x 7: no inverse)
    y: sp.Matrix  # 4J = 4J' Y (identity for the Microbo)
    b: sp.Matrix  # 3.81/3.82: D_{4,6} = diag(B, B)
    d46: sp.Matrix
    f46: sp.Matrix
    det_factors: tuple[sp.Expr, ...]  # denominators of the inverse (zero = singular)


def differential(robot: DHRobot, reduce_23: bool) -> Differential:
    if len(robot.links) == 7:
        return redundant_differential(robot)
    j4 = link_jacobian(robot, 4)
    j6 = link_jacobian(robot, 6)
    y = y_matrix() if reduce_23 else sp.eye(6)
    j4r = tidy_matrix(j4 * y.inv())
    j4r_inv = block_inverse(j4r)
    x46 = link_to_link(robot, 4, 6)
    d46 = tidy_matrix(d_map(x46))
    f46 = tidy_matrix(f_map(x46))
    b = d46[:3, :3]
    dens = set()
    for e in j4r_inv:
        _, den = sp.fraction(sp.factor(e))
        for fac in sp.Mul.make_args(den):
            base = fac.as_base_exp()[0]
            if base.free_symbols & set(Q):
                dens.add(base)
    return Differential(robot, j4, j6, j4r, j4r_inv, y, b, d46, f46,
                        tuple(sorted(dens, key=sp.default_sort_key)))


def redundant_differential(robot: DHRobot) -> Differential:
    """The Jacobians of a 7-joint arm: nJ (6 x 7), the motion of the last link observed in
    its own frame (column i = D_{i-1,n}(c_i), 3.57-3.61 with k = n), and 4J = diag(B, B) nJ,
    the same motion (of the last link's origin) observed in frame 4's axes, B the rotation
    of frame n in frame 4 (3.81). Frame 4 is not at the last link's origin here (no
    spherical wrist), so 4J is this re-expression, not kJ of 3.57 with k = 4. A 6 x 7 matrix
    has no inverse: the runtime's joint_from_cartesian / force_from_torque are the
    minimum-norm and least-squares solutions (rcci.models.kinematics); no symbolic inverse,
    reduction (3.62-3.67) or singular factors are derived."""
    n = len(robot.links)
    jn = link_jacobian(robot, n)
    x4n = link_to_link(robot, 4, n)
    b = x4n[:3, :3]
    j4 = (sp.diag(b, b) * jn).applyfunc(sp.expand)
    return Differential(robot, j4, jn, j4, None, sp.eye(n), b, d_map(x4n).applyfunc(sp.expand),
                        f_map(x4n).applyfunc(sp.expand), ())


def triangular_pivots(m: sp.Matrix) -> list[tuple[int, int]] | None:
    """(row, column) pivots that make square ``m`` triangular once rows and columns are
    permuted, in the order a substitution solves them; None if there is no such order.

    Each pivot row has exactly one non-zero among the columns not yet solved.
    """
    rows, cols = list(range(m.shape[0])), set(range(m.shape[1]))
    order: list[tuple[int, int]] = []
    while rows:
        for r in rows:
            nz = [c for c in sorted(cols) if m[r, c] != 0]
            if len(nz) == 1:
                order.append((r, nz[0]))
                rows.remove(r)
                cols.discard(nz[0])
                break
        else:
            return None
    return order


def block_pivots(m: sp.Matrix) -> list[tuple[tuple[int, ...], tuple[int, ...]]] | None:
    """(rows, columns) blocks that make square ``m`` block triangular once rows and columns
    are permuted, in the order a block substitution solves them; None if there is none.

    Each block's rows have their non-zeros, among the columns not yet solved, in exactly as
    many columns as the block has rows, and the block's determinant is not identically
    zero; the smallest such block is taken first, so a matrix that is triangular up to a
    permutation gives the pivots of ``triangular_pivots`` as blocks of one.
    """
    rows, cols = list(range(m.shape[0])), set(range(m.shape[1]))
    order: list[tuple[tuple[int, ...], tuple[int, ...]]] = []
    while rows:
        block = None
        for k in range(1, len(rows) + 1):
            for rs in itertools.combinations(rows, k):
                cs = tuple(sorted({c for r in rs for c in cols if m[r, c] != 0}))
                if len(cs) == k and tidy(m.extract(list(rs), list(cs)).det()) != 0:
                    block = (rs, cs)
                    break
            if block:
                break
        if block is None:
            return None
        order.append(block)
        rows = [r for r in rows if r not in block[0]]
        cols -= set(block[1])
    return order


def substitute(m: sp.Matrix, rhs: list[sp.Expr], unknowns: list[sp.Symbol],
               names=None) -> list[tuple[sp.Symbol, sp.Expr]]:
    """Definitions that solve ``m x = rhs`` by (block) substitution (``block_pivots``).

    ``unknowns[c]`` names x_c; each definition uses only the rhs and unknowns defined before
    it. This is how 3.73 and 3.74 are written: dtheta1 first, then dtheta2 from it, ...
    A block of more than one row is solved by its adjugate over its determinant, with one
    reciprocal of the determinant, named by the next of ``names`` (required then).
    """
    blocks = block_pivots(m)
    if blocks is None:
        raise ValueError("matrix is not block triangular under any permutation")
    defs = []
    for rs, cs in blocks:
        known = [rhs[r] - sum((m[r, k] * unknowns[k] for k in range(m.shape[1]) if k not in cs), sp.Integer(0))
                 for r in rs]
        if len(rs) == 1:
            defs.append((unknowns[cs[0]], known[0] / m[rs[0], cs[0]]))
            continue
        if names is None:
            raise ValueError("substitute: a block of more than one row needs names for its reciprocal")
        b = m.extract(list(rs), list(cs))
        w = next(names)
        defs.append((w, 1 / sp.factor(tidy(b.det()))))
        adj = b.adjugate().applyfunc(tidy)
        for i, c in enumerate(cs):
            defs.append((unknowns[c], w * sum((adj[i, j] * known[j] for j in range(len(rs))), sp.Integer(0))))
    return defs


@dataclass(frozen=True)
class TriangularForm:
    """4J' = [[R^T M, 0], [J21, J22]] (3.67, 3.69): R rotates frame 4 to frame 3 (A4's
    rotation), M is the wrist-centre Jacobian observed in frame 3 and, like J22, is
    block triangular up to a permutation (triangular for the thesis's arms; a 2x2 block
    where an elbow offset a3 != 0 couples joints 2 and 3, as on the PUMA 560); so J' and
    J'^T are solved by substitution, as 3.73 and 3.74 are, instead of multiplying by the
    expanded inverse 3.68."""

    r: sp.Matrix
    m: sp.Matrix
    j21: sp.Matrix
    j22: sp.Matrix


def triangular_form(diff: Differential) -> TriangularForm | None:
    """The block-triangular structure of diff's 4J', or None where it does not hold."""
    j = diff.j4_reduced
    r = link_to_link(diff.robot, 3, 4)[:3, :3]
    m = tidy_matrix(r * j[:3, :3])
    if j[:3, 3:] != sp.zeros(3, 3) or block_pivots(m) is None or block_pivots(m.T) is None:
        return None
    j22 = j[3:, 3:]
    if block_pivots(j22) is None or block_pivots(j22.T) is None:
        return None
    return TriangularForm(r, m, j[3:, :3], j22)
