"""Inverse kinematics by Paul's method (thesis 3.19-3.53).

Premultiply T6 = A1..A6 by A1^-1, A2^-1 A1^-1, ... (3.19), read off the matrix elements
that contain a single new unknown, and solve them with the atan2 forms (3.20, 3.21).
The result is one closed-form expression per joint variable in terms of the entries of
T6 (n, o, a, p) and the configuration signs, plus guards that say when no (or no unique)
solution exists. Three classes of arm with a spherical wrist (Pieper's) are solved:
articulated (PUMA, thesis 3.22-3.41), cylindrical (Microbo, 3.42-3.53) and spherical
(Stanford: revolute, revolute, prismatic, as Paul 1981 solves the Stanford arm);
``class_reasons`` says which conditions of each a table fails.
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from derive.dh import Q, DHRobot
from derive.forward import link_to_link, t6, tidy

nx, ny, nz, ox, oy, oz, ax, ay, az, px, py, pz = sp.symbols(
    "nx ny nz ox oy oz ax ay az px py pz", real=True
)
#: the pose T6 as a matrix of symbols (a homogeneous transform)
POSE = sp.Matrix([[nx, ox, ax, px], [ny, oy, ay, py], [nz, oz, az, pz], [0, 0, 0, 1]])
#: the same as a kernel input: the bottom row is read but not used by the solutions
POSE_INPUT = sp.Matrix(POSE[:3, :].tolist() + [list(sp.symbols("b0:4", real=True))])
arm, elbow, wrist, boom = sp.symbols("arm elbow wrist boom", real=True)

#: relative tolerance with which a boundary pose (stretched elbow, arm on the d3
#: cylinder) still counts as reachable: a few hundred ulps of the squared reach
REACH_RTOL = 1e-12
#: |sin theta5| (or a normalised distance) below which the solution is not unique
SINGULAR_TOL = 1e-9
#: relative tolerance on the squared distance of the wrist centre from the shoulder
#: (PUMA folded elbow, a2 = d4): that pose is also on the d3 cylinder, where theta1 comes
#: from a square root of a radicand that is 0 up to rounding, so the computed distance^2
#: carries about r^2 * eps (~1e-17 scale) of noise; 1e-12 (0.5 um) stays clear of it
FOLD_RTOL = 1e-12


@dataclass(frozen=True)
class PickedEquation:
    """One element of L_i = U_i (3.19) used to solve for a joint variable."""

    thesis: str  # equation number in the thesis
    premultiplied: int  # how many inverse A matrices premultiply T6
    row: int  # 1-based
    col: int  # 1-based
    lhs: sp.Expr  # in terms of T6 entries and joints already solved
    rhs: sp.Expr  # in terms of the remaining joint variables


@dataclass(frozen=True)
class IKSolution:
    """Closed-form inverse kinematics of one robot."""

    robot: DHRobot
    equations: tuple[PickedEquation, ...]
    joints: tuple[sp.Expr, ...]  # q1..q6 as functions of POSE and the config signs
    config: tuple[sp.Symbol, ...]
    guards: tuple[tuple[str, sp.Expr, str, str], ...]  # (name, expr, error, message)
    wrist_given_q4: tuple[sp.Expr, sp.Expr]  # q5, q6 with q1..q4 as inputs
    named: dict[str, sp.Expr]  # intermediate quantities, for the report
    kind: str  # "articulated" (PUMA class), "cylindrical" (Microbo), "spherical" (Stanford)
    indicators: tuple[sp.Expr, ...]  # functions of q whose signs are the config signs


def premultiplied(robot: DHRobot, i: int, pose: sp.Matrix = POSE) -> tuple[sp.Matrix, sp.Matrix]:
    """(L_i, U_i): (A1..Ai)^-1 T6 and A_{i+1}..A6, the two sides of thesis 3.19."""
    left = (link_to_link(robot, i, 0) * pose).applyfunc(tidy)
    right = link_to_link(robot, i, 6)
    return left, right


def pick(robot: DHRobot, thesis: str, i: int, row: int, col: int) -> PickedEquation:
    """Element (row, col) of L_i = U_i; the same as ``premultiplied``'s, tidying that
    element of L_i alone."""
    left = tidy((link_to_link(robot, i, 0)[row - 1, :] * POSE[:, col - 1])[0, 0])
    return PickedEquation(thesis, i, row, col, left, link_to_link(robot, i, 6)[row - 1, col - 1])


def solve_sin_cos(a: sp.Expr, b: sp.Expr, c: sp.Expr, sign: sp.Expr,
                  radicand: sp.Expr | None = None) -> sp.Expr:
    """Thesis 3.21: theta with a sin(theta) + b cos(theta) = c.

    theta = -atan2(b, a) + atan2(c, sign*sqrt(a^2 + b^2 - c^2)); the radicand is clamped
    at zero so that boundary poses within the reach tolerance stay finite (the guard
    on the radicand rejects the others).
    """
    if radicand is None:
        radicand = a**2 + b**2 - c**2
    else:
        assert sp.expand(radicand - (a**2 + b**2 - c**2)) == 0, "radicand must equal a^2 + b^2 - c^2"
    root = sp.sqrt((radicand + sp.Abs(radicand)) / 2)  # sqrt(max(0, radicand))
    return -sp.atan2(b, a) + sp.atan2(c, sign * root)


def _unknown_coefficients(expr: sp.Expr, s: sp.Expr, c: sp.Expr) -> tuple[sp.Expr, sp.Expr, sp.Expr]:
    """Write expr = A s + B c + C (expr linear in s and c)."""
    expr = sp.expand(expr)
    a_ = expr.coeff(s)
    b_ = expr.coeff(c)
    rest = sp.expand(expr - a_ * s - b_ * c)
    return a_, b_, rest


@dataclass(frozen=True)
class SphericalWrist:
    """theta4, theta5, theta6 of a spherical wrist (3.31-3.35), each in terms of the joints
    before it: the steps the PUMA and Stanford classes share."""

    equations: tuple[PickedEquation, ...]
    theta4: sp.Expr   # of q1..q3 and the wrist sign (3.31)
    theta5: sp.Expr   # of q1..q4 (3.33)
    theta6: sp.Expr   # of q1..q5 (3.35)
    norm: sp.Expr     # |S5| of q1..q3

    def joints(self, sub123: dict[sp.Symbol, sp.Expr]) -> tuple[sp.Expr, ...]:
        """theta4, theta5, theta6, |S5| with q1..q3 given by ``sub123``, and theta6 of q1..q4."""
        q1, q2, q3, q4, q5, q6 = Q[:6]
        theta4 = self.theta4.subs(sub123, simultaneous=True)
        norm = self.norm.subs(sub123, simultaneous=True)
        theta5 = self.theta5.subs({**sub123, q4: theta4}, simultaneous=True)
        theta6 = self.theta6.subs({**sub123, q4: theta4, q5: theta5}, simultaneous=True)
        return theta4, theta5, theta6, norm, self.theta6.subs({q5: self.theta5})


def spherical_wrist(r: DHRobot) -> SphericalWrist:
    """Paul's wrist steps: rows 1, 2 of the 3rd column of A3^-1 A2^-1 A1^-1 T6 = U4 (3.31,
    +-C4 S5 and +-S4 S5, the wrist sign choosing the branch: the 180 degree shift of the text
    after 3.31), then of A4^-1..A1^-1 T6 = U5 (3.33, +-S5, +-C5), then the 2nd column of
    A5^-1..A1^-1 T6 = U6 (3.35, +-S6, +-C6)."""
    q1, q2, q3, q4, q5, q6 = Q[:6]
    e_4a, e_4b = pick(r, "3.31", 3, 1, 3), pick(r, "3.31", 3, 2, 3)
    k_c = sp.simplify(e_4a.rhs / (sp.cos(q4) * sp.sin(q5)))
    k_s = sp.simplify(e_4b.rhs / (sp.sin(q4) * sp.sin(q5)))
    _require(r, k_c in (1, -1) and k_s in (1, -1), "the wrist must be spherical (3.31: +-C4 S5, +-S4 S5)")
    theta4 = sp.atan2(wrist * k_s * e_4b.lhs, wrist * k_c * e_4a.lhs)
    e_5a, e_5b = pick(r, "3.33", 4, 1, 3), pick(r, "3.33", 4, 2, 3)
    ks5 = sp.simplify(e_5a.rhs / sp.sin(q5))
    kc5 = sp.simplify(e_5b.rhs / sp.cos(q5))
    _require(r, ks5 in (1, -1) and kc5 in (1, -1), "the wrist must be spherical (3.33: +-S5, +-C5)")
    e_6a, e_6b = pick(r, "3.35", 5, 1, 2), pick(r, "3.35", 5, 2, 2)
    ks6 = sp.simplify(e_6a.rhs / sp.sin(q6))
    kc6 = sp.simplify(e_6b.rhs / sp.cos(q6))
    _require(r, ks6 in (1, -1) and kc6 in (1, -1), "3.35 must read +-S6, +-C6")
    return SphericalWrist((e_4a, e_4b, e_5a, e_5b, e_6a, e_6b), theta4,
                          sp.atan2(ks5 * e_5a.lhs, kc5 * e_5b.lhs), sp.atan2(ks6 * e_6a.lhs, kc6 * e_6b.lhs),
                          sp.sqrt(e_4a.lhs**2 + e_4b.lhs**2))


def articulated_ik(r: DHRobot) -> IKSolution:
    """The PUMA class (thesis eqs. 3.22-3.41 for the PUMA 260), derived from the table of
    ``r``: six revolute joints, a1 = 0 with the shoulder axes perpendicular, joints 2 and 3
    parallel, a spherical wrist at the origin of frame 6; the elbow offset a3 and the base
    height d1 may be non-zero (PUMA 560). Config signs arm, elbow, wrist (each +1 or -1).
    """
    q1, q2, q3, q4, q5, q6 = Q[:6]
    s1, c1 = sp.sin(q1), sp.cos(q1)
    a2 = r.links[1].a
    eqs: list[PickedEquation] = []

    # theta1: row 3 of the 4th column of A1^-1 T6 = U2 (3.23): px S1 - py C1 = d3
    e_p1 = pick(r, "3.23", 1, 1, 4)
    e_p2 = pick(r, "3.23", 1, 2, 4)
    e_p3 = pick(r, "3.23", 1, 3, 4)
    eqs += [e_p1, e_p2, e_p3]
    a_, b_, rest = _unknown_coefficients(e_p3.lhs - e_p3.rhs, s1, c1)
    d3 = -rest  # the offset of the arm's plane from the joint-1 axis (d2 + d3)
    _require(r, not (d3.free_symbols & (set(Q) | set(POSE))),
             "row 3 of A1^-1 T6 = U2 must fix theta1 alone (px S1 - py C1 = const)")
    theta1 = solve_sin_cos(a_, b_, d3, arm)
    radicand1 = a_**2 + b_**2 - d3**2

    # theta3: sum of squares of rows 1, 2 of (3.23) (3.25): f S3 - g C3 = d
    fp, fz = e_p1.lhs, e_p2.lhs  # C1 px + S1 py, pz (pz - d1 with a base height)
    squares = sp.expand(sp.trigsimp(sp.expand(e_p1.rhs**2 + e_p2.rhs**2)))
    f = -squares.coeff(sp.sin(q3))
    g = squares.coeff(sp.cos(q3))
    const = sp.expand(squares + f * sp.sin(q3) - g * sp.cos(q3))
    _require(r, not (const.free_symbols & set(Q)) and not (f.free_symbols & set(Q))
             and not (g.free_symbols & set(Q)) and f != 0,
             "the wrist centre's distance from the shoulder must depend on theta3 alone")
    # forearm length from the elbow axis to the wrist centre: L^2 = a3^2 + d4^2
    forearm = sp.sqrt(sp.expand(const - a2**2))
    _require(r, sp.expand(f**2 + g**2 - 4 * a2**2 * forearm**2) == 0,
             "rows 1, 2 of U2 must be the two-link form a2 + forearm (parallel joints 2, 3)")
    d = const - fp**2 - fz**2
    # elbow up <=> elbow above the shoulder-wrist line <=> arm*cos(theta3 - phi) < 0 with
    # phi = atan2(a3, d4) the forearm's angle offset (see report)
    # the difference of squares factored as (r^2 - (a2 - L)^2)((a2 + L)^2 - r^2): near the
    # stretched elbow the difference would cancel catastrophically, the factors do not
    reach2 = fp**2 + fz**2
    radicand3_q1 = (reach2 - (a2 - forearm) ** 2) * ((a2 + forearm) ** 2 - reach2)
    theta3_of_q1 = solve_sin_cos(f, -g, d, -arm * elbow, radicand3_q1)
    theta3 = theta3_of_q1.subs(q1, theta1)
    radicand3 = radicand3_q1.subs(q1, theta1)

    # theta2 + theta3: rows 1 and 3 of the 4th column of A3^-1 A2^-1 A1^-1 T6 = U4 (3.29)
    e_23a = pick(r, "3.29", 3, 1, 4)
    e_23b = pick(r, "3.29", 3, 3, 4)
    eqs += [e_23a, e_23b]
    s23, c23 = sp.sin(q2 + q3), sp.cos(q2 + q3)
    sv, cv = sp.symbols("s23 c23", real=True)
    lin = [
        (e.lhs - e.rhs).subs({s23: sv, c23: cv}) for e in (e_23a, e_23b)
    ]
    if any(e.free_symbols & {q2} for e in lin):
        # trigsimp wrote some products as sums (sin(q1 + q2 + q3)/2 ...): expand in q1, q3
        # and the angle t = q2 + q3, then read S23, C23 off
        t = sp.Symbol("t23", real=True)
        lin = [sp.expand(sp.expand_trig((e.lhs - e.rhs).subs(q2, t - q3))).subs(
            {sp.sin(t): sv, sp.cos(t): cv}) for e in (e_23a, e_23b)]
        lin = [sp.expand(sp.expand_trig(e)) for e in lin]
    _require(r, all(not (e.free_symbols & {q2}) for e in lin),
             "rows 1, 3 of the 4th column of A3^-1..A1^-1 T6 = U4 must be linear in S23, C23")
    sol = sp.solve(lin, [sv, cv], dict=True)[0]
    num_s, den_s = sp.fraction(sp.factor(sol[sv]))
    num_c, den_c = sp.fraction(sp.factor(sol[cv]))
    assert sp.simplify(den_s - den_c) == 0
    den = sp.expand(den_s)
    # the common denominator must be fp^2 + pz^2 > 0 so that it drops out of atan2
    sgn = 1 if sp.expand(den - (fp**2 + fz**2)) == 0 else -1
    _require(r, sp.expand(den - sgn * (fp**2 + fz**2)) == 0,
             f"theta2 + theta3: denominator {den} is not the squared shoulder-wrist distance")
    theta23_of_q13 = sp.atan2(sgn * num_s, sgn * num_c)  # in terms of q1 and q3
    theta23 = theta23_of_q13.subs({q1: theta1, q3: theta3}, simultaneous=True)
    theta2 = theta23 - theta3
    fold = (fp**2 + fz**2).subs(q1, theta1)

    # theta4..6: the spherical wrist (3.31-3.35)
    w = spherical_wrist(r)
    eqs += list(w.equations)
    theta4, theta5, theta6, wrist_norm, theta6_given_q4 = w.joints({q1: theta1, q2: theta2, q3: theta3})

    scale = (a2 + forearm + sp.Abs(d3)) ** 2
    guards = (
        ("guard_arm_reach", radicand1 + REACH_RTOL * (px**2 + py**2 + d3**2), "Unreachable",
         "the wrist centre lies inside the cylinder of radius d3 about the joint-1 axis"),
        ("guard_elbow_reach", radicand3 + REACH_RTOL * (2 * a2 * forearm) ** 2, "Unreachable",
         "the wrist centre is farther from the shoulder than a2 + d4 (beyond the stretched elbow)"),
        ("guard_folded", fold - FOLD_RTOL * scale, "Singular",
         "the wrist centre is at the shoulder (elbow fully folded): theta2 is undetermined"),
        ("guard_wrist", wrist_norm - SINGULAR_TOL, "Singular",
         "sin(theta5) = 0: joints 4 and 6 are aligned and only theta4 + theta6 is determined"),
    )
    # configuration indicators: h is the wrist centre's distance in front of the joint-1
    # axis in the arm's plane (sign = arm); cos(theta3 - phi) the elbow's bend (3.24, 3.27)
    h = tidy(e_p1.rhs)
    bend = (f * sp.cos(q3) + g * sp.sin(q3)) / (2 * a2 * forearm)  # = cos(theta3 - phi)
    named = {
        "f_p": fp, "f": f, "d": d, "r2": px**2 + py**2, "u1": a2 * sp.cos(q3),
        "u2": forearm - a2 * sp.sin(q3), "theta1": theta1, "theta3": theta3_of_q1,
        "theta23": theta23_of_q13, "theta4": w.theta4, "theta5": w.theta5,
        "theta6": w.theta6, "h": h, "bend": bend, "forearm": forearm, "d_off": d3,
    }
    indicators = (h, -h * sp.expand(bend), sp.sin(q5))
    return IKSolution(r, tuple(eqs), (theta1, theta2, theta3, theta4, theta5, theta6),
                      (arm, elbow, wrist), guards, (w.theta5, theta6_given_q4), named,
                      "articulated", indicators)


def cylindrical_ik(r: DHRobot) -> IKSolution:
    """The Microbo class (thesis eqs. 3.42-3.53 for the Microbo Ecureuil): a revolute
    column, vertical and radial prismatic joints meeting its axis, a spherical wrist;
    config sign wrist (+1 or -1)."""
    q1, q2, q3, q4, q5, q6 = Q[:6]
    eqs: list[PickedEquation] = []
    # 3.42: the fourth column of A1^-1 T6 = U2 (cylindrical coordinates)
    e_p1 = pick(r, "3.42", 1, 1, 4)
    e_p2 = pick(r, "3.42", 1, 2, 4)
    e_p3 = pick(r, "3.42", 1, 3, 4)
    eqs += [e_p1, e_p2, e_p3]
    _require(r, e_p2.rhs == 0 and e_p3.rhs == q2 and e_p1.rhs == q3,
             "the 4th column of A1^-1 T6 = U2 must be (d3, 0, d2): cylindrical coordinates")
    # -px S1 + py C1 = 0 with d3 = px C1 + py S1 > 0 (d3 cannot be negative): 3.43
    theta1 = sp.atan2(py, px)
    ext2 = pz  # 3.49
    ext3 = sp.sqrt(px**2 + py**2)  # 3.44, 3.50

    # theta4: third column of A1^-1 T6 = U2 (the print's 3.45 is this element set)
    e_4a = pick(r, "3.45", 1, 2, 3)
    e_4b = pick(r, "3.45", 1, 3, 3)
    e_4c = pick(r, "3.45", 1, 1, 3)
    eqs += [e_4c, e_4a, e_4b]
    k_c = sp.simplify(e_4a.rhs / (sp.cos(q4) * sp.sin(q5)))
    k_s = sp.simplify(e_4b.rhs / (sp.sin(q4) * sp.sin(q5)))
    _require(r, k_c in (1, -1) and k_s in (1, -1), "the wrist must be spherical (3.45)")
    theta4_of_q1 = sp.atan2(wrist * k_s * e_4b.lhs, wrist * k_c * e_4a.lhs)
    wrist_norm = sp.sqrt(e_4a.lhs**2 + e_4b.lhs**2)

    # theta5: third column of A4^-1..A1^-1 T6 = U5 (3.46)
    e_5a = pick(r, "3.46", 4, 1, 3)
    e_5b = pick(r, "3.46", 4, 2, 3)
    eqs += [e_5a, e_5b]
    ks5 = sp.simplify(e_5a.rhs / sp.sin(q5))
    kc5 = sp.simplify(e_5b.rhs / sp.cos(q5))
    theta5_of_q14 = sp.atan2(ks5 * e_5a.lhs, kc5 * e_5b.lhs)

    # theta6: second column of A5^-1..A1^-1 T6 = U6 (3.47)
    e_6a = pick(r, "3.47", 5, 1, 2)
    e_6b = pick(r, "3.47", 5, 2, 2)
    eqs += [e_6a, e_6b]
    ks6 = sp.simplify(e_6a.rhs / sp.sin(q6))
    kc6 = sp.simplify(e_6b.rhs / sp.cos(q6))
    theta6_of_q145 = sp.atan2(ks6 * e_6a.lhs, kc6 * e_6b.lhs)

    theta4 = theta4_of_q1.subs(q1, theta1)
    wrist_norm = wrist_norm.subs(q1, theta1)
    theta5 = theta5_of_q14.subs({q1: theta1, q4: theta4}, simultaneous=True)
    theta6 = theta6_of_q145.subs({q1: theta1, q4: theta4, q5: theta5}, simultaneous=True)
    theta6_given_q4 = theta6_of_q145.subs(q5, theta5_of_q14)
    guards = (
        ("guard_axis", ext3 - SINGULAR_TOL, "Singular",
         "the wrist centre is on the joint-1 axis (d3 = 0): theta1 is undetermined"),
        ("guard_wrist", wrist_norm - SINGULAR_TOL, "Singular",
         "sin(theta5) = 0: joints 4 and 6 are aligned and only theta4 + theta6 is determined"),
    )
    named = {"theta1": theta1, "d2": ext2, "d3": ext3, "theta4": theta4_of_q1,
             "theta5": theta5_of_q14, "theta6": theta6_of_q145}
    return IKSolution(r, tuple(eqs), (theta1, ext2, ext3, theta4, theta5, theta6), (wrist,),
                      guards, (theta5_of_q14, theta6_given_q4), named, "cylindrical",
                      (sp.sin(q5),))


def spherical_ik(r: DHRobot) -> IKSolution:
    """The Stanford class (Paul 1981's solution of the Stanford arm, written in the thesis's
    steps 3.19-3.21): joint 1 revolute with a1 = 0 and alpha1 = +-90 deg, joint 2 a revolute
    shoulder through which the boom passes (a2 = 0, alpha2 = +-90 deg, a shoulder offset d2
    allowed), joint 3 the prismatic boom (a3 = 0, alpha3 = 0), a spherical wrist at the
    origin of frame 6 (a fixed d4 along the boom allowed). Config signs arm, boom, wrist.

    boom = +1 is the boom extended through the wrist centre (q3 + d4 > 0); boom = -1 the
    boom reversed through the shoulder (theta2 + pi, q3 + d4 < 0): a solution of the table,
    which the runtime reports Unreachable (prismatic joint out of its range) unless the
    model's range of joint 3 allows it; the Stanford arm's (0.30-1.27 m) does not.
    """
    q1, q2, q3, q4, q5, q6 = Q[:6]
    s1, c1 = sp.sin(q1), sp.cos(q1)
    eqs: list[PickedEquation] = []

    # theta1: row 3 of the 4th column of A1^-1 T6 = U2, as the PUMA's 3.23: the wrist
    # centre's offset from the boom's plane is the shoulder offset d2
    e_p1 = pick(r, "3.23", 1, 1, 4)
    e_p2 = pick(r, "3.23", 1, 2, 4)
    e_p3 = pick(r, "3.23", 1, 3, 4)
    eqs += [e_p1, e_p2, e_p3]
    a_, b_, rest = _unknown_coefficients(e_p3.lhs - e_p3.rhs, s1, c1)
    d_off = -rest
    _require(r, not (d_off.free_symbols & (set(Q) | set(POSE))),
             "row 3 of A1^-1 T6 = U2 must fix theta1 alone (px S1 - py C1 = const)")
    theta1 = solve_sin_cos(a_, b_, d_off, arm)
    radicand1 = a_**2 + b_**2 - d_off**2

    # theta2 and the boom: rows 1, 2 of the same column (Paul's Stanford solution, the
    # Microbo's cylindrical coordinates 3.42 in the boom's plane): +-S2 (q3 + d4), +-C2 (q3 + d4)
    reach_s = sp.expand(sp.simplify(e_p1.rhs / sp.sin(q2)))
    reach_c = sp.expand(sp.simplify(e_p2.rhs / sp.cos(q2)))
    ks2, kc2 = reach_s.coeff(q3), reach_c.coeff(q3)
    _require(r, ks2 in (1, -1) and kc2 in (1, -1)
             and sp.expand(ks2 * reach_s - kc2 * reach_c) == 0
             and not ((ks2 * reach_s - q3).free_symbols & set(Q)),
             "rows 1, 2 of the 4th column of U2 must be +-S2 (q3 + d4), +-C2 (q3 + d4): the boom "
             "through the shoulder")
    boom_off = sp.expand(ks2 * reach_s - q3)  # d4: the wrist centre beyond the boom's zero
    fs, fc = ks2 * e_p1.lhs, kc2 * e_p2.lhs  # (q3 + d4) S2 and (q3 + d4) C2 from the pose
    theta2_of_q1 = sp.atan2(boom * fs, boom * fc)
    length2_of_q1 = fs**2 + fc**2  # (q3 + d4)^2: the wrist centre's distance from the shoulder
    ext_of_q1 = boom * sp.sqrt(length2_of_q1) - boom_off
    theta2 = theta2_of_q1.subs(q1, theta1)
    ext3 = ext_of_q1.subs(q1, theta1)
    length2 = length2_of_q1.subs(q1, theta1)

    # theta4..6: the spherical wrist, as the PUMA's (3.31-3.35)
    w = spherical_wrist(r)
    eqs += list(w.equations)
    theta4, theta5, theta6, wrist_norm, theta6_given_q4 = w.joints({q1: theta1, q2: theta2, q3: ext3})

    planar2 = a_**2 + b_**2  # the wrist centre's squared distance from the joint-1 axis
    if d_off == 0:
        arm_guard = ("guard_axis", sp.sqrt(planar2) - SINGULAR_TOL, "Singular",
                     "the wrist centre is on the joint-1 axis: theta1 is undetermined")
    else:
        arm_guard = ("guard_arm_reach", radicand1 + REACH_RTOL * (planar2 + d_off**2), "Unreachable",
                     "the wrist centre lies inside the cylinder of radius d2 (the shoulder offset) "
                     "about the joint-1 axis")
    # at the shoulder theta1 comes from a square root of a rounding-level radicand (the
    # pose is on the d2 cylinder), so the squared length carries ~ d2^2 eps of noise:
    # FOLD_RTOL of the pose's scale stays clear of it, SINGULAR_TOL^2 keeps it negative at 0
    scale = d_off**2 + planar2 + fc.subs(q1, theta1) ** 2
    guards = (
        arm_guard,
        ("guard_boom", length2 - FOLD_RTOL * scale - SINGULAR_TOL**2, "Singular",
         "the wrist centre is at the shoulder (boom length q3 + d4 = 0): theta2 is undetermined"),
        ("guard_wrist", wrist_norm - SINGULAR_TOL, "Singular",
         "sin(theta5) = 0: joints 4 and 6 are aligned and only theta4 + theta6 is determined"),
    )
    # configuration indicators: the second solution of 3.21's a S1 + b C1 = d2 is told by
    # the sign of a C1 - b S1, the wrist centre's reach in the boom's plane across the
    # joint-1 axis (the PUMA's h, 3.24); the boom's signed length; S5 (3.39)
    fk = t6(r)
    h = tidy((a_ * c1 - b_ * s1).subs({px: fk[0, 3], py: fk[1, 3]}, simultaneous=True))
    named = {"d_off": d_off, "r2": planar2, "theta1": theta1, "f_s": fs, "f_c": fc,
             "theta2": theta2_of_q1, "q3": ext_of_q1, "theta4": w.theta4,
             "theta5": w.theta5, "theta6": w.theta6, "h": h, "boom_off": boom_off}
    indicators = (h, q3 + boom_off, sp.sin(q5))
    return IKSolution(r, tuple(eqs), (theta1, theta2, ext3, theta4, theta5, theta6),
                      (arm, boom, wrist), guards, (w.theta5, theta6_given_q4), named,
                      "spherical", indicators)


class OutsideClass(ValueError):
    """The arm is outside the classes with a closed-form inverse the derivation knows."""


def _require(r: DHRobot, ok: bool, why: str) -> None:
    if not ok:
        raise OutsideClass(f"{r.name}: {why}")


def _zero(e) -> bool:
    return sp.sympify(e) == 0


def _quarter(e) -> bool:
    return sp.sympify(e) in (sp.pi / 2, -sp.pi / 2)


def _wrist_reasons(r: DHRobot) -> list[str]:
    """Why the last three joints are not a spherical wrist at the origin of frame 6."""
    l4, l5, l6 = r.links[3:]
    out = []
    if any(link.prismatic for link in (l4, l5, l6)):
        out.append("joints 4-6 must be revolute")
    if not all(_zero(x) for x in (l4.a, l5.a, l6.a, l5.d, l6.d)):
        out.append("a4 = a5 = a6 = 0 and d5 = d6 = 0 (wrist axes meeting at the origin of frame 6)")
    if not (_quarter(l4.alpha) and _quarter(l5.alpha)):
        out.append("alpha4, alpha5 = +-90 deg (perpendicular wrist axes)")
    return out


#: the class of a 7-joint arm: its inverse kinematics has a free parameter (derive.redundant)
REDUNDANT = "redundant (7 joints)"


def class_reasons(r: DHRobot) -> dict[str, list[str]]:
    """For each class with a closed-form inverse, the conditions ``r`` fails (empty = in it).

    A 7-joint arm is of the redundant class: the 6-joint classes' conditions do not apply
    (Pieper's closed forms solve six unknowns from one pose); its inverse kinematics,
    with one joint (or an arm angle) free, plugs in through ``derive.redundant``."""
    if len(r.links) == 7:
        from derive.redundant import class_reasons as redundant_reasons  # derive.inverse_redundant's

        six = ["six joints (Pieper's closed forms solve six unknowns from one pose)"]
        return {REDUNDANT: redundant_reasons(r), "articulated (PUMA class)": six, "cylindrical (Microbo class)": six,
                "spherical (Stanford class)": six}
    l1, l2, l3 = r.links[:3]
    wrist = _wrist_reasons(r)
    art = []
    if any(link.prismatic for link in r.links[:3]):
        art.append("joints 1-3 must be revolute")
    if not (_zero(l1.a) and _quarter(l1.alpha)):
        art.append("a1 = 0 and alpha1 = +-90 deg (joint 1 axis meets joint 2 axis at right angles)")
    if not (_zero(l2.alpha) and _zero(l2.d) and not _zero(l2.a)):
        art.append("alpha2 = 0, d2 = 0, a2 != 0 (joints 2 and 3 parallel, upper arm of length a2)")
    if not _quarter(l3.alpha):
        art.append("alpha3 = +-90 deg")
    if _zero(r.links[3].d):
        art.append("d4 != 0 (a forearm)")
    cyl = []
    if [link.prismatic for link in r.links[:3]] != [False, True, True]:
        cyl.append("joint kinds revolute, prismatic, prismatic")
    elif not (all(_zero(x) for x in (l1.a, l1.alpha, l1.d, l2.a, l3.a, l3.alpha, l3.theta))
              and _quarter(l2.alpha) and _quarter(l2.theta) and _zero(r.links[3].d)):
        cyl.append("vertical joint 2 and radial joint 3 meeting the joint-1 axis (Table 3.2 form)")
    sph = []
    if [link.prismatic for link in r.links[:3]] != [False, False, True]:
        sph.append("joint kinds revolute, revolute, prismatic")
    else:
        if not (_zero(l1.a) and _quarter(l1.alpha)):
            sph.append("a1 = 0 and alpha1 = +-90 deg (joint 1 axis meets joint 2 axis at right angles)")
        if not (_zero(l2.a) and _quarter(l2.alpha)):
            sph.append("a2 = 0 and alpha2 = +-90 deg (the boom through the shoulder axis, "
                       "perpendicular to it)")
        if not (_zero(l3.a) and _zero(l3.alpha)):
            sph.append("a3 = 0 and alpha3 = 0 (joint 4 on the boom's axis)")
    return {"articulated (PUMA class)": art + wrist, "cylindrical (Microbo class)": cyl + wrist,
            "spherical (Stanford class)": sph + wrist}


def solve_ik(r: DHRobot) -> IKSolution | None:
    """The closed-form inverse of ``r``, chosen by the shape of its DH table; an arm outside
    every class is refused with the conditions it fails. None for a 7-joint arm: a pose
    does not fix its joints, its solver (with a free parameter) is ``derive.redundant``'s."""
    reasons = class_reasons(r)
    if not reasons.get(REDUNDANT, ["-"]):
        return None  # the redundant class: derive.redundant, not Paul's method
    if not reasons["articulated (PUMA class)"]:
        return articulated_ik(r)
    if not reasons["cylindrical (Microbo class)"]:
        return cylindrical_ik(r)
    if not reasons["spherical (Stanford class)"]:
        return spherical_ik(r)
    why = "; ".join(f"not {k}: needs {', '.join(v)}" for k, v in reasons.items())
    raise OutsideClass(f"{r.name}: no closed-form inverse kinematics for this DH table ({why}). "
                       "Pieper's closed forms need a spherical wrist and an arm of one of these shapes.")
