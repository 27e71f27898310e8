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


@lru_cache(maxsize=None)
def base_to_link(robot: DHRobot, k: int) -> sp.Matrix:
    """T_k = A_1 ... A_k (thesis 4.9): frame k in the base frame; T_0 = I."""
    if k == 0:
        return sp.eye(4)
    return tidy_matrix(base_to_link(robot, k - 1) * a_matrices(robot)[k - 1])


@lru_cache(maxsize=None)
def link_to_link(robot: DHRobot, i: int, k: int) -> sp.Matrix:
    """Frame k in frame i: A_{i+1} ... A_k for i <= k, the inverse otherwise."""
    if i == k:
        return sp.eye(4)
    if i > k:
        return tidy_matrix(inverse_transform(link_to_link(robot, k, i)))
    a = a_matrices(robot)
    out = sp.eye(4)
    for j in range(i, k):
        out = tidy_matrix(out * a[j])
    return out


def t6(robot: DHRobot) -> sp.Matrix:
    """Thesis 3.16: link 6 in the base frame."""
    return base_to_link(robot, 6)
