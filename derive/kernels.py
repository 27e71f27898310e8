"""Turn the derivation's results into ``Kernel``s, the functions the emitters write out.

One list per robot; the names are the generated module's private kernel names
(``rccl/kinematics/<robot>.py`` wraps them into the public API of the contract).
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from derive.dh import Q
from derive.forward import t6, t6_chained, tidy
from derive.gravity import COM, MASSES, GravityModel, d_t, g0, m_t, gravity_general
from derive.inverse import POSE_INPUT, IKSolution, SINGULAR_TOL
from derive.jacobian import Differential, TriangularForm, substitute, triangular_form
from derive.kernel import Arg, Guard, Kernel
from derive.robots import RobotSpec


def _vec(prefix: str, n: int) -> sp.Matrix:
    return sp.Matrix(sp.symbols(f"{prefix}1:{n + 1}", real=True))


@dataclass(frozen=True)
class Derivation:
    """All symbolic results for one robot (the report reads these too)."""

    spec: RobotSpec
    t6: sp.Matrix
    ik: IKSolution | None  # None for a 7-joint arm (derive.redundant plugs its solver in)
    diff: Differential
    gravity: GravityModel


def _guard(name: str, expr: sp.Expr, error: str, message: str) -> Guard:
    return Guard(name, expr, error, message)


def build_kernels(d: Derivation) -> list[Kernel]:
    spec, robot = d.spec, d.spec.name
    params = dict(spec.params)
    n = len(spec.dh.links)
    q = sp.Matrix(Q[:n])
    qarg = Arg("q", q, "joint variables (rad; m for Microbo joints 2, 3)")
    ks: list[Kernel] = []

    def kernel(name, doc, inputs, outputs, guards=(), source="", stages=(), staged=(), program=False):
        used = set()
        for o in outputs:
            used |= o.value.free_symbols
        for g in guards:
            used |= g.expr.free_symbols
        defined = set()
        if program:  # the outputs are written in the stage symbols, each defined from the inputs
            defined = {s for s, _ in stages}
            for _, e in stages:
                used |= sp.sympify(e).free_symbols
        given = set().union(*(a.value.free_symbols for a in inputs)) | set(params) | defined
        if used - given:
            raise ValueError(f"{robot}.{name}: outputs depend on {sorted(map(str, used - given))}, "
                             "which are neither inputs nor robot constants")
        kp = {s: v for s, v in params.items() if s in used}
        ks.append(Kernel(robot, name, doc, tuple(inputs), tuple(outputs), tuple(guards), kp, source,
                         tuple(stages), tuple(staged), program=program))

    # -- forward kinematics ------------------------------------------------------------
    chain_defs, chain_t6 = t6_chained(spec.dh)  # structure hint: one run of A matrices at a time
    kernel("fk", f"T{n}: link {n} in the base frame (4x4 homogeneous transform, m)",
           [qarg], [Arg("T", d.t6, f"base_to_link{n}")], source="3.16-3.18",
           stages=tuple(chain_defs), staged=(chain_t6,))
    if d.ik is None:  # a redundant arm: its IK kernels, when derive.redundant has a solver
        from derive.redundant import redundant_ik_kernels

        for k in redundant_ik_kernels(d):
            ks.append(k)
        _differential_kernels(d, kernel, qarg, n)
        _gravity_kernels(d, kernel, qarg, n)
        return _with_dynamics(ks, spec)

    # -- inverse kinematics ------------------------------------------------------------
    cfg = sp.Matrix(d.ik.config)
    guards = [_guard(*g) for g in d.ik.guards]
    kernel("ik", "joint variables for pose T in one configuration (signs +-1: "
           + ", ".join(spec.config_fields) + ")",
           [Arg("T", POSE_INPUT, "base_to_link6"), Arg("config", cfg, "configuration signs")],
           [Arg("q", sp.Matrix(d.ik.joints), "joint variables")], guards, source="3.19-3.53")
    q5w, q6w = d.ik.wrist_given_q4
    kernel("ik_wrist", "theta5, theta6 for pose T when q1..q4 are given (wrist singularity: "
           "theta4 kept from a reference)",
           [Arg("T", POSE_INPUT, "base_to_link6"), qarg],
           [Arg("q56", sp.Matrix([q5w, q6w]), "theta5, theta6")], source="3.33, 3.35, 3.46, 3.47")

    # configuration indicators: sign of each is the configuration of q
    ind = sp.Matrix(d.ik.indicators)
    kernel("config_indicators", "values whose signs are the configuration of q "
           "(" + ", ".join(spec.config_fields) + ")", [qarg],
           [Arg("indicator", ind, "sign = configuration")], source="3.24, 3.27, 3.39, 3.51")

    # -- Jacobians -----------------------------------------------------------------------
    j4, j6 = d.diff.j4, d.diff.j6
    kernel("jacobian4", "4J: motion of link 6 observed in frame 4 per unit joint rate",
           [qarg], [Arg("J", j4, "(dx, dy, dz, dx_rot, dy_rot, dz_rot) in frame 4")],
           source="3.54-3.61, 3.67, 3.69")
    kernel("jacobian6", "6J: motion of link 6 observed in frame 6 per unit joint rate",
           [qarg], [Arg("J", j6, "(dx, dy, dz, dx_rot, dy_rot, dz_rot) in frame 6")],
           source="3.54-3.61")

    dq, dc, f, tau = _vec("dq", 6), _vec("dc", 6), _vec("f", 6), _vec("tau", 6)
    b = d.diff.b
    bb = sp.diag(b, b)  # D_{4,6} = F_{4,6} (3.80 corrected)
    bbt = sp.diag(b.T, b.T)  # D_{6,4} = F_{6,4}
    jr, jr_inv, y = d.diff.j4_reduced, d.diff.j4_reduced_inv, d.diff.y
    y_inv = y.inv()
    dc4 = j4 * dq
    inv_guards = _jacobian_guards(d.ik)
    tri = triangular_form(d.diff)
    for frame in (4, 6):
        st = _structure_hints(tri, y, bb, bbt, frame, dq, dc, f, tau) if tri is not None else {}
        if frame == 4:
            fwd = (jr * (y * dq)).applyfunc(sp.expand)
            torque = (y.T * (jr.T * f)).applyfunc(sp.expand)
            joint = (y_inv * (jr_inv * dc)).applyfunc(sp.expand)
            force = (jr_inv.T * (y_inv.T * tau)).applyfunc(sp.expand)
            src = ("3.71, 3.75", "3.72, 3.76", "3.73, 3.77", "3.74, 3.78")
        else:
            fwd = bb * (jr * (y * dq)).applyfunc(sp.expand)
            torque = (y.T * (jr.T * (bbt * f))).applyfunc(sp.expand)
            joint = (y_inv * (jr_inv * (bbt * dc))).applyfunc(sp.expand)
            force = bb * (jr_inv.T * (y_inv.T * tau)).applyfunc(sp.expand)
            src = ("3.79",) * 4
        kernel(f"cartesian_from_joint{frame}", f"dc = J dq observed in frame {frame}",
               [qarg, Arg("dq", dq, "joint rates or differentials")],
               [Arg("dc", fwd, f"Cartesian differential in frame {frame}")], (), src[0], *st.get("fwd", ()))
        kernel(f"torque_from_force{frame}", f"tau = J^T f with f observed in frame {frame}",
               [qarg, Arg("f", f, f"force/moment in frame {frame}")],
               [Arg("tau", torque, "joint torques (N m; N on prismatic joints)")], (), src[1], *st.get("torque", ()))
        kernel(f"joint_from_cartesian{frame}", f"dq = J^-1 dc with dc observed in frame {frame}",
               [qarg, Arg("dc", dc, f"Cartesian differential in frame {frame}")],
               [Arg("dq", joint, "joint differentials")], inv_guards, src[2], *st.get("joint", ()))
        kernel(f"force_from_torque{frame}", f"f = J^-T tau, observed in frame {frame}",
               [qarg, Arg("tau", tau, "joint torques")],
               [Arg("f", force, f"force/moment in frame {frame}")], inv_guards, src[3], *st.get("force", ()))

    _gravity_kernels(d, kernel, qarg, n)
    return _with_dynamics(ks, spec)


def _differential_kernels(d: Derivation, kernel, qarg: Arg, n: int) -> None:
    """A 7-joint arm's Jacobians (6 x n, derive.jacobian.redundant_differential) and the two
    forward computations; the inverse ones are the runtime's least-squares solutions."""
    j4, jn = d.diff.j4, d.diff.j6
    kernel("jacobian4", f"4J: motion of link {n} observed in frame 4 per unit joint rate",
           [qarg], [Arg("J", j4, "(dx, dy, dz, dx_rot, dy_rot, dz_rot) in frame 4")], source="3.54-3.61, 3.81")
    kernel("jacobian6", f"{n}J: motion of link {n} observed in frame {n} per unit joint rate",
           [qarg], [Arg("J", jn, f"(dx, dy, dz, dx_rot, dy_rot, dz_rot) in frame {n}")], source="3.54-3.61")
    dq, f = _vec("dq", n), _vec("f", 6)
    for frame, j in ((4, j4), (6, jn)):
        where = 4 if frame == 4 else n
        # a program: J's entries once (as the jacobian kernels), then J dq and J^T f in them;
        # J dq written out expanded is too large for the emitters' search on seven joints
        names = sp.numbered_symbols("jc", real=True)
        stages = []
        js = sp.zeros(6, n)
        for r in range(6):
            for c in range(n):
                if j[r, c] != 0:
                    js[r, c] = next(names)
                    stages.append((js[r, c], j[r, c]))
        dc_out, tau_out = js * dq, js.T * f
        kernel(f"cartesian_from_joint{frame}", f"dc = J dq observed in frame {where}",
               [qarg, Arg("dq", dq, "joint rates or differentials")],
               [Arg("dc", dc_out, f"Cartesian differential in frame {where}")], (), "3.71, 3.75",
               stages=tuple(stages), staged=(dc_out,), program=True)
        kernel(f"torque_from_force{frame}", f"tau = J^T f with f observed in frame {where}",
               [qarg, Arg("f", f, f"force/moment in frame {where}")],
               [Arg("tau", tau_out, "joint torques (N m)")], (), "3.72, 3.76",
               stages=tuple(stages), staged=(tau_out,), program=True)


def _with_dynamics(ks: list[Kernel], spec: RobotSpec) -> list[Kernel]:
    """The kernels followed by the whole equation 4.6 (derive.dynamics): D, c, C, inverse
    dynamics, base regressor."""
    from derive.dynamics_kernels import dynamics_kernels
    from rcci.models import load_robot

    return ks + dynamics_kernels(spec, load_robot(spec.name).links)[0]


def _gravity_kernels(d: Derivation, kernel, qarg: Arg, n: int) -> None:
    """Gravity (4.8-4.26): the grouped or minimal coefficients, their regressor, 4.20 from
    link data, the coefficients of link data and the tool load."""
    spec = d.spec
    # -- gravity -----------------------------------------------------------------------
    gm = d.gravity
    if spec.gravity_coeffs and tuple(gm.coeff_names) != tuple(spec.gravity_coeffs):
        raise ValueError(f"{spec.model_path}: gravity_coeffs: data file has "
                         f"{list(spec.gravity_coeffs)}, the derivation groups 4.20 into "
                         f"{list(gm.coeff_names)}")
    c = sp.Matrix(gm.coeff_symbols)
    kernel("gravity", "tau_g = regressor(q) c: torques holding the arm against gravity",
           [qarg, Arg("c", c, "gravity loading coefficients " + ", ".join(gm.coeff_names))],
           [Arg("tau", gm.regressor * c, "N m (N on prismatic joints)")], source="4.24, 4.25")
    kernel("gravity_regressor", "d tau_g / d c (tau_g is linear in the coefficients)",
           [qarg], [Arg("Y", gm.regressor, f"{n} x k")], source="4.24")
    masses = sp.Matrix(MASSES[:n])
    com = sp.Matrix([list(r) for r in COM[:n]])
    general = gravity_general(spec.dh, [tuple(r) for r in COM[:n]])
    kernel("gravity_links", "tau_g from link masses and centres of mass (eq. 4.20, no "
           "centre-of-mass assumption)",
           [qarg, Arg("m", masses, "link masses, kg"),
            Arg("com", com, "centre of mass of link k in frame k, m (row k-1)")],
           [Arg("tau", general, "N m (N on prismatic joints)")], source="4.8-4.20")
    meaning = sp.Matrix(gm.coeff_meaning)
    kernel("coefficients_from_links", "gravity loading coefficients of given link masses and "
           "centres of mass (those 4.24 assumes: 4.21 for the PUMA)",
           [Arg("m", masses, "link masses, kg"),
            Arg("com", com, "centre of mass of link k in frame k, m (row k-1)")],
           [Arg("c", meaning, ", ".join(gm.coeff_names))], source="4.24")
    load = sp.Matrix([m_t, d_t])
    kernel("tool_load", f"coefficients with a tool of mass m_t at d_t along z{n} (4.26)",
           [Arg("c", c, "coefficients without the tool"),
            Arg("load", load, "(m_t kg, d_t m)")],
           [Arg("c_loaded", c + sp.Matrix(gm.tool_update), "coefficients with the tool")],
           source="4.26")


def _jacobian_guards(ik: IKSolution) -> list[Guard]:
    """Where 4J' (or 4J) is singular: the denominators of its inverse, by IK class."""
    s5 = sp.sin(Q[4])
    wrist = _guard("guard_wrist", sp.Abs(s5) - SINGULAR_TOL, "Singular",
                   "sin(theta5) = 0: wrist singularity, joints 4 and 6 aligned")
    if ik.kind == "articulated":
        h, bend = ik.named["h"], ik.named["bend"]
        a2 = ik.robot.links[1].a
        return [
            _guard("guard_shoulder", sp.Abs(h) - SINGULAR_TOL * (a2 + ik.named["forearm"]), "Singular",
                   "h = a2 C2 - d4 S23 = 0: the wrist centre is on the d3-cylinder about "
                   "the joint-1 axis (shoulder singularity)"),
            _guard("guard_elbow", sp.Abs(bend) - SINGULAR_TOL, "Singular",
                   "cos(theta3) = 0: the elbow is stretched or fully folded"),
            wrist,
        ]
    if ik.kind == "spherical":
        return [
            _guard("guard_boom", sp.Abs(Q[2] + ik.named["boom_off"]) - SINGULAR_TOL, "Singular",
                   "q3 + d4 = 0: the boom's length is zero, the wrist centre at the shoulder"),
            _guard("guard_shoulder", sp.Abs(sp.sin(Q[1])) - SINGULAR_TOL, "Singular",
                   "sin(theta2) = 0: the boom is parallel to the joint-1 axis (the wrist "
                   "centre on the d2-cylinder about it, shoulder singularity)"),
            wrist,
        ]
    return [
        _guard("guard_axis", sp.Abs(Q[2]) - SINGULAR_TOL, "Singular",
               "d3 = 0: the wrist centre is on the joint-1 axis"),
        wrist,
    ]


def _structure_hints(tri: TriangularForm, y: sp.Matrix, bb: sp.Matrix, bbt: sp.Matrix, frame: int,
                     dq: sp.Matrix, dc: sp.Matrix, f: sp.Matrix, tau: sp.Matrix) -> dict[str, tuple]:
    """The four Jacobian computations written the way 3.71-3.78 are: with the block-
    triangular form of 4J' (substitution instead of the expanded inverse 3.68), and in
    frame 6 as one map of (3.79) before or after the frame-4 computation.

    Returns {computation: (stage definitions, (outputs in the stage symbols,))}: a
    structure hint for the C lowering, which keeps it only where it counts fewer
    operations; the kernels' outputs stay the authoritative values.
    """
    names = sp.numbered_symbols("z", real=True)

    def define(exprs, defs):
        syms = [next(names) for _ in exprs]
        defs.extend(zip(syms, exprs))
        return syms

    r, m, j21, j22 = tri.r, tri.m, tri.j21, tri.j22
    hints = {}
    # forward: dc = [R^T M x_a; J21 x_a + J22 x_b], x = Y dq
    defs: list = []
    x = list(y * dq)
    v = define(list(m * sp.Matrix(x[:3])), defs)
    out = list(r.T * sp.Matrix(v)) + list(j21 * sp.Matrix(x[:3]) + j22 * sp.Matrix(x[3:]))
    if frame == 6:
        out = list(bb * sp.Matrix(define(out, defs)))
    hints["fwd"] = (tuple(defs), (sp.Matrix(out),))
    # torque: tau = Y^T [M^T R f_a + J21^T f_b; J22^T f_b]
    defs = []
    fv = list(f) if frame == 4 else define(list(bbt * f), defs)
    g = define(list(r * sp.Matrix(fv[:3])), defs)
    fa, fb = sp.Matrix(g), sp.Matrix(fv[3:])
    out = y.T * sp.Matrix(list(m.T * fa + j21.T * fb) + list(j22.T * fb))
    hints["torque"] = (tuple(defs), (out,))
    # joint: M x_a = R dc_a, J22 x_b = dc_b - J21 x_a, dq = Y^-1 x
    defs = []
    cv = list(dc) if frame == 4 else define(list(bbt * dc), defs)
    g = define(list(r * sp.Matrix(cv[:3])), defs)
    xa = [next(names) for _ in range(3)]
    defs.extend(substitute(m, g, xa, names))
    rb = list(sp.Matrix(cv[3:]) - j21 * sp.Matrix(xa))
    xb = [next(names) for _ in range(3)]
    defs.extend(substitute(j22, rb, xb, names))
    hints["joint"] = (tuple(defs), (y.inv() * sp.Matrix(xa + xb),))
    # force: J22^T f_b = tau'_b, M^T g = tau'_a - J21^T f_b, f_a = R^T g, tau' = Y^-T tau
    defs = []
    tp = list(y.inv().T * tau)
    fb = [next(names) for _ in range(3)]
    defs.extend(substitute(j22.T, tp[3:], fb, names))
    ra = list(sp.Matrix(tp[:3]) - j21.T * sp.Matrix(fb))
    g = [next(names) for _ in range(3)]
    defs.extend(substitute(m.T, ra, g, names))
    out = list(r.T * sp.Matrix(g)) + fb
    if frame == 6:
        out = list(bb * sp.Matrix(define(out, defs)))
    hints["force"] = (tuple(defs), (sp.Matrix(out),))
    return hints
