"""Forward kinematics: T6 = A1 A2 A3 A4 A5 A6 (thesis 3.16-3.18) and partial products."""
from __future__ import annotations

from functools import lru_cache

import sympy as sp

from derive.dh import DHRobot, a_matrices, inverse_transform


def tidy(expr: sp.Expr) -> sp.Expr:
    """Expand and fold sin/cos products back into sin(qi + qj) forms (the thesis's S23)."""
    return sp.trigsimp(sp.expand(expr))


def tidy_matrix(m: sp.Matrix) -> sp.Matrix:
    return m.applyfunc(tidy)


def simplifier(robot: DHRobot):
    """How the products of ``robot``'s A matrices are simplified: ``tidy`` (trigsimp, the
    thesis's S23 forms) for a 6-joint arm; ``sp.expand`` alone for a 7-joint one, whose
    seven-fold products trigsimp takes minutes per entry to fold (the emitters' common-
    subexpression elimination shares the products instead)."""
    return tidy if len(robot.links) <= 6 else sp.expand


@lru_cache(maxsize=None)
def base_to_link(robot: DHRobot, k: int) -> sp.Matrix:
    """T_k = A_1 ... A_k (thesis 4.9): frame k in the base frame; T_0 = I."""
    if k == 0:
        return sp.eye(4)
    return (base_to_link(robot, k - 1) * a_matrices(robot)[k - 1]).applyfunc(simplifier(robot))


@lru_cache(maxsize=None)
def link_to_link(robot: DHRobot, i: int, k: int) -> sp.Matrix:
    """Frame k in frame i: A_{i+1} ... A_k for i <= k, the inverse otherwise."""
    if i == k:
        return sp.eye(4)
    simplify = simplifier(robot)
    if i > k:
        return inverse_transform(link_to_link(robot, k, i)).applyfunc(simplify)
    if i == 0:
        return base_to_link(robot, k)  # the same products, computed once
    a = a_matrices(robot)
    out = sp.eye(4)
    for j in range(i, k):
        out = (out * a[j]).applyfunc(simplify)
    return out


def t6(robot: DHRobot) -> sp.Matrix:
    """Thesis 3.16: link 6 in the base frame (the last link, link 7, of a 7-joint arm)."""
    return base_to_link(robot, len(robot.links))


def chain_groups(robot: DHRobot) -> list[list[int]]:
    """Runs of consecutive A matrices (0-based link indices) multiplied out together.

    A_i joins the run before it when it has no translation (A5 A6 of the wrist: their
    product is a pure rotation) or when the previous link's alpha is 0 (parallel axes,
    as PUMA joints 2 and 3: the run's rotation depends on theta2 + theta3 only, the
    thesis's S23/C23). The PUMA gives A1 | A2 A3 | A4 A5 A6.
    """
    groups: list[list[int]] = []
    for i, link in enumerate(robot.links):
        moves = link.d != 0 or link.a != 0
        parallel = i > 0 and robot.links[i - 1].alpha == 0
        if groups and (not moves or parallel):
            groups[-1].append(i)
        else:
            groups.append([i])
    return groups


def t6_chained(robot: DHRobot) -> tuple[list[tuple[sp.Symbol, sp.Expr]], sp.Matrix]:
    """T6 = A1 A2 ... A6 evaluated from the tool end one run of ``chain_groups`` at a time.

    Returns the definitions of the intermediate products' entries (symbols k0, k1, ...)
    and T6 written with them: a structure hint for the C lowering, which otherwise
    multiplies the expanded 3.17 out term by term. Same values as ``t6``.
    """
    a = a_matrices(robot)
    names = sp.numbered_symbols("k", real=True)
    defs: list[tuple[sp.Symbol, sp.Expr]] = []
    groups = chain_groups(robot)
    acc = None
    for g in reversed(groups):
        run = sp.eye(4)
        for i in g:
            run = (run * a[i]).applyfunc(simplifier(robot))
        if acc is None:
            acc = run
            continue
        acc = run * _named(acc, names, defs)
    return defs, acc


def _named(m: sp.Matrix, names, defs: list) -> sp.Matrix:
    """m with every entry that is not a number replaced by a new symbol defined in defs."""
    out = sp.Matrix(m)
    for r in range(3):
        for c in range(4):
            e = m[r, c]
            if not e.is_Number and not e.is_Symbol:
                s = next(names)
                defs.append((s, e))
                out[r, c] = s
    return out
