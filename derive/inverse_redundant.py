"""Closed-form inverse kinematics of a redundant 7-joint arm with q7 as the free parameter.

The class is the Panda's (Franka Emika), in the standard-DH table derive sees (the loader
converts the published modified-DH table, rcci.models.modified_dh; frame 7 = the flange):
axes 1, 2, 3 meet at the shoulder point S (the origin of frames 1 and 2), axes 5 and 6
meet at the wrist point W (the origin of frame 5), an elbow (joint 4) between them with
offsets a3, a4, and a joint 7 after W. With q7 given, frame 6 is known from the pose,
T06 = T07 A7(q7)^-1 (the step of He & Liu 2021's geometric solver), and so is W (its
place in frame 6 does not depend on q6). The remaining six joints then follow in the
thesis's manner (read off elements with one new unknown, atan2 forms 3.20, 3.21), each
step checked by SymPy on the table (``OutsideClass`` names the step that fails):

* q4 from the squared shoulder-wrist distance |W - S|^2, a function of q4 alone
  (a S4 + b C4 = c, form 3.21; config sign ``elbow`` picks the root);
* q6 from S seen from frame 4: writing A5 = Rz(q5) B5, S4 = Rz(q5) B5 A6(q6) S6 with S4
  of q4 (arm side) and S6 = T06^-1 S from the pose; the z component does not depend on
  q5 and gives q6 (form 3.21; config sign ``wrist``);
* q5 from the x, y components (one atan2: the angle from B5 A6 S6 to S4 about z4);
* q1, q2, q3 from Rz(q1) Rx(alpha1) Rz(q2) Rx(alpha2) Rz(q3) = R06 (B3 A4 A5 A6)_R^T, a
  Z-Y-Z-like triple: q2 from the (3, 3) element with the sign ``shoulder`` (= sign of
  sin q2) choosing the branch, q1 from the third column, q3 from the third row.

Configuration fields, in the order of the ``config`` input: ``shoulder`` (sign of sin q2),
``elbow`` (which of the two elbow angles q4 giving the same shoulder-wrist distance),
``wrist`` (which of the two q6 putting S at the height along the joint-5 axis that q4
needs). Up to 8 solutions per pose and q7; joint ranges are the runtime's to apply.

Guards (a negative value raises the named error of models/kinematics.py): the
shoulder-wrist distance outside the elbow's range, or no q6 for the height q4 needs
(Unreachable); S on the joint-6 axis (q6 undetermined), on the joint-5 axis (q5
undetermined), or sin q2 = 0 (joints 1 and 3 aligned, only q1 + q3 determined): Singular.
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from derive.dh import DHRobot, a_matrix, inverse_transform
from derive.inverse import POSE, POSE_INPUT, REACH_RTOL, SINGULAR_TOL, OutsideClass, solve_sin_cos
from derive.kernel import Arg, Guard, Kernel

#: joint variables of a 7-joint arm (the same symbols as derive.dh.Q's)
Q7 = sp.symbols("q1:8", real=True)
#: the free parameter of the redundant inverse: the value of joint 7 (rad)
FREE = sp.Symbol("q7_free", real=True)
shoulder, elbow, wrist = sp.symbols("shoulder elbow wrist", real=True)
#: configuration fields of the redundant class, in the order of the ``config`` input
CONFIG_FIELDS = ("shoulder", "elbow", "wrist")
#: the class's name, as the keys of derive.inverse.class_reasons name the 6-joint classes
CLASS = "redundant (Panda class, q7 free)"
#: pi as a number for the emitted code (an atan2 of constants folds to pi in SymPy)
PI = sp.Float(sp.pi.evalf(20), 20)


def _zero(e) -> bool:
    return sp.sympify(e) == 0


def _quarter(e) -> bool:
    return sp.sympify(e) in (sp.pi / 2, -sp.pi / 2)


def class_reasons(r: DHRobot) -> list[str]:
    """The conditions of the redundant class that the (standard-DH) table ``r`` fails;
    empty when it is in the class."""
    if len(r.links) != 7:
        return [f"7 joints (the table has {len(r.links)})"]
    out = []
    l1, l2, l3, l4, l5, l6, l7 = r.links
    if any(link.prismatic for link in r.links):
        out.append("all seven joints revolute")
    elif not all(_zero(link.theta - q) for link, q in zip(r.links, Q7)):
        out.append("no joint offsets (theta_i = q_i)")
    if not (_zero(l1.a) and _zero(l2.a) and _zero(l2.d) and _quarter(l1.alpha) and _quarter(l2.alpha)):
        out.append("a1 = a2 = 0, d2 = 0, alpha1, alpha2 = +-90 deg (axes 1, 2, 3 meeting at the "
                   "shoulder point)")
    if not (_quarter(l3.alpha) and _quarter(l4.alpha)):
        out.append("alpha3, alpha4 = +-90 deg (the elbow axis perpendicular to the upper arm "
                   "and the forearm)")
    if not (_zero(l5.a) and _quarter(l5.alpha)):
        out.append("a5 = 0, alpha5 = +-90 deg (axes 5 and 6 meeting at the wrist point)")
    return out


def _require(r: DHRobot, ok: bool, why: str) -> None:
    if not ok:
        raise OutsideClass(f"{r.name}: {why}")


def _fold(e: sp.Expr) -> sp.Expr:
    return sp.expand(sp.trigsimp(sp.expand(e)))


@dataclass(frozen=True)
class RedundantIK:
    """Closed-form inverse of a 7-joint arm with q7 given (``FREE``)."""

    robot: DHRobot
    joints: tuple[sp.Expr, ...]  # q1..q7 of POSE, FREE and the config signs
    config: tuple[sp.Symbol, ...]  # shoulder, elbow, wrist
    guards: tuple[tuple[str, sp.Expr, str, str], ...]  # (name, expr, error, message)
    indicators: tuple[sp.Expr, ...]  # functions of q whose signs are the config signs
    named: dict[str, sp.Expr]  # intermediate quantities (for reports and checks)
    kind: str = "redundant"


def redundant_ik(r: DHRobot) -> RedundantIK:
    """Derive the closed form of a table in the redundant class (see the module doc)."""
    reasons = class_reasons(r)
    _require(r, not reasons, "not in the redundant class: needs " + ", ".join(reasons))
    q1, q2, q3, q4, q5, q6, q7 = Q7
    a = [a_matrix(link) for link in r.links]
    # B_i = Rz(q_i)^-1 A_i: the constant part of each link transform
    b = [(_rz(-q) * m).applyfunc(sp.simplify) for q, m in zip(Q7, a)]
    # frame 6 from the pose and q7: T06 = T07 A7(q7)^-1; W in frame 6 does not move with q6
    t06 = POSE * inverse_transform(a[6].subs(q7, FREE))
    w6 = inverse_transform(a[5])[:, 3].applyfunc(sp.simplify)
    s0 = (a[0] * a[1])[:, 3]
    s3 = inverse_transform(a[2])[:, 3].applyfunc(sp.simplify)
    _require(r, not ((w6.free_symbols | s0.free_symbols | s3.free_symbols) & set(Q7)),
             "W in frame 6, S in the base and S in frame 3 must be fixed points")
    w0 = t06 * w6
    # q4: |W - S|^2 from the pose and from the arm (3.21 form a S4 + b C4 = c)
    d_pose = sp.expand(sum((w0[i] - s0[i]) ** 2 for i in range(3)))
    w3 = (a[3] * a[4])[:, 3]
    d_q4 = _fold(sum((w3[i] - s3[i]) ** 2 for i in range(3)))
    _require(r, (d_q4.free_symbols & set(Q7)) <= {q4}, "the shoulder-wrist distance must depend on q4 alone")
    a4, b4 = d_q4.coeff(sp.sin(q4)), d_q4.coeff(sp.cos(q4))
    c4 = sp.expand(d_pose - (d_q4 - a4 * sp.sin(q4) - b4 * sp.cos(q4)))
    _require(r, not (a4 == 0 and b4 == 0), "the elbow must change the shoulder-wrist distance")
    theta4 = solve_sin_cos(a4, b4, c4, elbow)
    radicand4 = a4**2 + b4**2 - c4**2
    # q6: S4 (arm side, q4) = Rz(q5) B5 A6(q6) S6 (pose side); z is free of q5
    s4 = (inverse_transform(a[3]) * s3).applyfunc(_fold)
    _require(r, (s4.free_symbols & set(Q7)) <= {q4}, "S in frame 4 must depend on q4 alone")
    # S6 = (x, y, z): S in frame 6, from the pose (T06^-1 S) or from the arm (for the indicator)
    x6 = sp.Matrix([*sp.symbols("x6_ y6_ z6_", real=True), 1])
    s6_pose = inverse_transform(t06) * s0
    s6_arm = inverse_transform(a[5]) * inverse_transform(a[4]) * s4
    m = b[4] * a[5] * x6
    sv, cv = sp.symbols("s6_ c6_", real=True)
    mz = sp.expand(m[2].subs({sp.sin(q6): sv, sp.cos(q6): cv}))
    a6_x, b6_x = mz.coeff(sv), mz.coeff(cv)
    rest = sp.expand(mz - a6_x * sv - b6_x * cv)
    _require(r, not (rest.free_symbols & (set(Q7) | {sv, cv})),
             "the z4 component of B5 A6 S6 must be linear in S6, C6")
    on_pose = dict(zip(x6[:3], s6_pose[:3]))
    a6, b6 = a6_x.subs(on_pose, simultaneous=True), b6_x.subs(on_pose, simultaneous=True)
    c6 = s4[2] - rest.subs(on_pose, simultaneous=True)
    m = m.subs(on_pose, simultaneous=True)
    theta6_of_q4 = solve_sin_cos(a6, b6, c6, wrist)
    radicand6_of_q4 = a6**2 + b6**2 - c6**2
    # q5: the angle about z4 from m = B5 A6 S6 to S4 (both in the x4-y4 plane)
    mx, my = m[0], m[1]
    theta5_of_q46 = sp.atan2(mx * s4[1] - my * s4[0], mx * s4[0] + my * s4[1])
    norm5_of_q4 = sp.sqrt(s4[0] ** 2 + s4[1] ** 2)
    # q1, q2, q3: Rz(q1) Rx(alpha1) Rz(q2) Rx(alpha2) Rz(q3) = R06 (B3 A4 A5 A6)_R^T
    r_pose = t06[:3, :3] * (b[2] * a[3] * a[4] * a[5])[:3, :3].T
    r03 = (a[0] * a[1] * _rz(q3))[:3, :3].applyfunc(sp.simplify)
    ks = [sp.simplify(r03[i, j] / f) for (i, j), f in (
        ((2, 2), sp.cos(q2)), ((0, 2), sp.cos(q1) * sp.sin(q2)), ((1, 2), sp.sin(q1) * sp.sin(q2)),
        ((2, 0), sp.sin(q2) * sp.cos(q3)), ((2, 1), sp.sin(q2) * sp.sin(q3)))]
    _require(r, all(k in (1, -1) for k in ks),
             "the shoulder's rotation must read +-C2, +-C1 S2, +-S1 S2, +-S2 C3, +-S2 S3")
    k33, k13, k23, k31, k32 = ks
    e13, e23, e33, e31, e32 = r_pose[0, 2], r_pose[1, 2], r_pose[2, 2], r_pose[2, 0], r_pose[2, 1]
    sin2 = sp.sqrt(e13**2 + e23**2)
    theta2_of = sp.atan2(shoulder * sin2, k33 * e33)
    theta1_of = sp.atan2(shoulder * k23 * e23, shoulder * k13 * e13)
    theta3_of = sp.atan2(shoulder * k32 * e32, shoulder * k31 * e31)
    theta6 = theta6_of_q4.subs(q4, theta4)
    theta5 = theta5_of_q46.subs({q4: theta4, q6: theta6}, simultaneous=True)
    sub456 = {q4: theta4, q5: theta5, q6: theta6}
    theta1, theta2, theta3 = (t.subs(sub456, simultaneous=True) for t in (theta1_of, theta2_of, theta3_of))
    guards = (
        ("guard_elbow_reach", radicand4 + REACH_RTOL * (a4**2 + b4**2), "Unreachable",
         "the wrist point is outside the elbow's range of shoulder-wrist distances"),
        ("guard_wrist_height", radicand6_of_q4.subs(q4, theta4) + REACH_RTOL * (a6**2 + b6**2),
         "Unreachable", "for this q7 no q6 puts the shoulder point at the height along the "
         "joint-5 axis that the elbow needs"),
        ("guard_axis6", sp.sqrt(a6**2 + b6**2) - SINGULAR_TOL, "Singular",
         "the shoulder point is on the joint-6 axis: q6 is undetermined"),
        ("guard_axis5", norm5_of_q4.subs(q4, theta4) - SINGULAR_TOL, "Singular",
         "the shoulder point is on the joint-5 axis: q5 is undetermined"),
        ("guard_shoulder", sin2.subs(sub456, simultaneous=True) - SINGULAR_TOL, "Singular",
         "sin q2 = 0: joints 1 and 3 are aligned and only q1 + q3 is determined"),
    )
    # indicators: solve_sin_cos's root sign is that of a C - b S (S6 written in q for the wrist)
    on_arm = dict(zip(x6[:3], s6_arm[:3]))
    ind_wrist = _fold((a6_x * sp.cos(q6) - b6_x * sp.sin(q6)).subs(on_arm, simultaneous=True))
    indicators = (sp.sin(q2), sp.expand(a4 * sp.cos(q4) - b4 * sp.sin(q4)), ind_wrist)
    named = {"S": s0, "W6": w6, "S4": s4, "dist2_pose": d_pose, "dist2_q4": d_q4,
             "theta4": theta4, "theta6_of_q4": theta6_of_q4, "theta5_of_q46": theta5_of_q46,
             "theta1_of": theta1_of, "theta2_of": theta2_of, "theta3_of": theta3_of}
    return RedundantIK(r, (theta1, theta2, theta3, theta4, theta5, theta6, FREE),
                       (shoulder, elbow, wrist), guards, indicators, named)


def _rz(q: sp.Expr) -> sp.Matrix:
    """Rot(z, q) as a 4x4 transform."""
    c, s = sp.cos(q), sp.sin(q)
    return sp.Matrix([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])


def solver_kernels(ik: RedundantIK, params: dict[sp.Symbol, float], robot: str) -> list[Kernel]:
    """The ``ik`` kernel (T (4, 4) of the flange, m; q7, rad; config signs -> q (7,) and the
    guards) and ``config_indicators`` (q (7,) -> the values whose signs are q's config)."""

    def kernel(name, doc, inputs, outputs, guards=(), source=""):
        # pi (from atan2 of constant coefficients) as a number: the C printer takes no symbol pi
        outputs = [Arg(o.name, o.value.xreplace({sp.pi: PI}), o.doc) for o in outputs]
        guards = [Guard(g.name, g.expr.xreplace({sp.pi: PI}), g.error, g.message) for g in guards]
        used = set().union(*(o.value.free_symbols for o in outputs), *(g.expr.free_symbols for g in guards))
        return Kernel(robot, name, doc, tuple(inputs), tuple(outputs), tuple(guards),
                      {s: v for s, v in params.items() if s in used}, source)

    return [
        kernel("ik", "joint variables for pose T and free value q7 in one configuration (signs +-1: "
               + ", ".join(CONFIG_FIELDS) + ")",
               [Arg("T", POSE_INPUT, "base_to_flange"), Arg("q7", sp.Matrix([FREE]), "joint 7 (rad)"),
                Arg("config", sp.Matrix(ik.config), "configuration signs")],
               [Arg("q", sp.Matrix(ik.joints), "joint variables")],
               [Guard(*g) for g in ik.guards], source="3.19-3.21"),
        kernel("config_indicators", "values whose signs are the configuration of q ("
               + ", ".join(CONFIG_FIELDS) + ")", [Arg("q", sp.Matrix(Q7), "joint variables (rad)")],
               [Arg("indicator", sp.Matrix(ik.indicators), "sign = configuration")], source="3.21"),
    ]


def ik_kernels(derivation) -> list[Kernel]:
    """The plug-in of derive.redundant (the 7-joint derivation): the ``ik`` and
    ``config_indicators`` kernels of ``derivation.spec``'s arm (``ik_all`` is added by the C
    lowering, derive.lowering.all_configurations_kernels)."""
    spec = derivation.spec
    return solver_kernels(redundant_ik(spec.dh), dict(spec.params), spec.name)
