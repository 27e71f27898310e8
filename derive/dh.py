"""Denavit-Hartenberg tables of the two arms and the A matrix of thesis eq. 3.3.

The tables are symbolic (a2, d3, d4 stay symbols; numbers are substituted only when
code is emitted) so that every derived expression can be compared with the print.
Joint variables are ``q1..q6``; for the Microbo ``q2`` and ``q3`` are the prismatic
extensions d2 and d3 (metres), every other joint variable an angle (radians).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import sympy as sp

#: joint variables of up to 7 joints, shared by every arm (q2, q3 are lengths on the
#: Microbo); a 6-joint arm uses Q[:6], the redundant Panda all seven
Q = sp.symbols("q1:8", real=True)
#: the joint counts the derivation handles: six (the thesis's arms) and seven (redundant)
N_JOINTS = (6, 7)

#: the PUMA's fixed link lengths of Table 3.1 (metres)
a2, d3, d4 = sp.symbols("a2 d3 d4", positive=True)


@dataclass(frozen=True)
class DHLink:
    """One row of a DH table (thesis 3.2.1 steps 8-11); angles in radians."""

    d: sp.Expr
    theta: sp.Expr
    alpha: sp.Expr
    a: sp.Expr
    prismatic: bool = False


@dataclass(frozen=True)
class DHRobot:
    """A serial arm as its DH table plus the names the derivation needs."""

    name: str
    links: tuple[DHLink, ...]
    params: tuple[sp.Symbol, ...]  # fixed lengths that stay symbolic

    @property
    def prismatic(self) -> tuple[bool, ...]:
        return tuple(link.prismatic for link in self.links)


def a_matrix(link: DHLink) -> sp.Matrix:
    """Thesis eq. 3.3: transform from frame i-1 to frame i.

    The print lost every minus sign of 3.3; this is the standard DH form
    Rot(z, theta) Trans(z, d) Trans(x, a) Rot(x, alpha), which is what the printed
    A matrices 3.4-3.15 are instances of.
    """
    ct, st = sp.cos(link.theta), sp.sin(link.theta)
    ca, sa = sp.cos(link.alpha), sp.sin(link.alpha)
    return sp.Matrix(
        [
            [ct, -st * ca, st * sa, link.a * ct],
            [st, ct * ca, -ct * sa, link.a * st],
            [0, sa, ca, link.d],
            [0, 0, 0, 1],
        ]
    )


_deg = sp.pi / 180

#: Table 3.1 with the signs of alpha that the printed A matrices 3.4-3.9 require
#: (the table itself prints |alpha| only): alpha = 90, 0, -90, 90, -90, 0 degrees.
PUMA260 = DHRobot(
    name="puma260",
    links=(
        DHLink(0, Q[0], 90 * _deg, 0),
        DHLink(0, Q[1], 0, a2),
        DHLink(d3, Q[2], -90 * _deg, 0),
        DHLink(d4, Q[3], 90 * _deg, 0),
        DHLink(0, Q[4], -90 * _deg, 0),
        DHLink(0, Q[5], 0, 0),
    ),
    params=(a2, d3, d4),
)

#: Table 3.2: joint 2 (theta = 90 deg fixed) and joint 3 are prismatic; the alphas are
#: those the printed A matrices 3.10-3.15 require (all non-zero alphas +90 degrees).
MICROBO = DHRobot(
    name="microbo",
    links=(
        DHLink(0, Q[0], 0, 0),
        DHLink(Q[1], 90 * _deg, 90 * _deg, 0, prismatic=True),
        DHLink(Q[2], 0, 0, 0, prismatic=True),
        DHLink(0, Q[3], 90 * _deg, 0),
        DHLink(0, Q[4], 90 * _deg, 0),
        DHLink(0, Q[5], 0, 0),
    ),
    params=(),
)

ROBOTS = {r.name: r for r in (PUMA260, MICROBO)}


def a_matrices(robot: DHRobot) -> list[sp.Matrix]:
    """A_1..A_6 of a robot (thesis 3.4-3.9 for the PUMA, 3.10-3.15 for the Microbo)."""
    return [a_matrix(link) for link in robot.links]


def joint_symbols(robot: DHRobot) -> tuple[sp.Symbol, ...]:
    """q1..qn of ``robot`` (n = 6 or 7)."""
    return Q[:len(robot.links)]


def inverse_transform(t: sp.Matrix) -> sp.Matrix:
    """Inverse of a homogeneous transform: (R^T, -R^T p)."""
    r = t[:3, :3]
    p = t[:3, 3]
    out = sp.eye(4)
    out[:3, :3] = r.T
    out[:3, 3] = -r.T * p
    return out


def _length(value: float, name: str, params: dict[sp.Symbol, float]) -> sp.Expr:
    """A fixed DH length: 0 stays 0, any other value becomes the symbol ``name`` (a2, d3,
    ...) whose number is substituted only when code is emitted."""
    if value == 0.0:
        return sp.Integer(0)
    sym = sp.Symbol(name, positive=True) if value > 0 else sp.Symbol(name, negative=True)
    params[sym] = float(value)
    return sym


def _angle(value: float, name: str, params: dict[sp.Symbol, float]) -> sp.Expr:
    """A fixed DH angle: a whole number of degrees is exact (90 deg = pi/2, as the thesis
    tables), any other value a symbol substituted at emission."""
    deg = math.degrees(value)
    if abs(deg - round(deg)) < 1e-9:
        return sp.Integer(round(deg)) * _deg
    sym = sp.Symbol(name, real=True)
    params[sym] = float(value)
    return sym


def dh_from_model(model) -> tuple[DHRobot, dict[sp.Symbol, float]]:
    """The symbolic DH table of a robot's model file (``rcci.models.RobotModel``) and the
    numbers of its symbols (SI).

    Joint i's variable q_i is added to theta (revolute) or d (prismatic), the other
    parameters are fixed: zero lengths stay 0, whole-degree angles are exact, every other
    value is a symbol named after its table entry (a2, d3, ...). For the thesis arms this
    is Table 3.1 / 3.2 exactly (``PUMA260``, ``MICROBO``).
    """
    if model.n_joints not in N_JOINTS:
        raise ValueError(f"{model.path}: robot.n_joints = {model.n_joints}: the derivation "
                         "handles six-joint arms and seven-joint (redundant) ones")
    params: dict[sp.Symbol, float] = {}
    links = []
    for j, q in zip(model.joints, Q):
        i = j.index
        prismatic = j.kind == "prismatic"
        if prismatic:
            if j.d != 0.0:
                raise ValueError(f"{model.path}: joints.{i}.d: offset {j.d} on the joint "
                                 "variable is not supported by the derivation")
            d, theta = q, _angle(j.theta, f"theta{i}", params)
        else:
            if j.theta != 0.0:
                raise ValueError(f"{model.path}: joints.{i}.theta: offset {j.theta} on the "
                                 "joint variable is not supported by the derivation")
            d, theta = _length(j.d, f"d{i}", params), q
        links.append(DHLink(d, theta, _angle(j.alpha, f"alpha{i}", params),
                            _length(j.a, f"a{i}", params), prismatic=prismatic))
    return DHRobot(model.name, tuple(links), tuple(params)), params
