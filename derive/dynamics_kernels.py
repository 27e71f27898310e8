"""The dynamics kernels of one arm (thesis 4.6): inverse dynamics, D, c, C, the base
regressor and the base parameters, as ``Kernel``s whose stages are the program.

The inverse dynamics, D, c and C carry the data file's link inertials (``[[links]]``: mass,
centre of mass and inertia about it, in DH frame k), i.e. the rigid body that Pinocchio's
``rnea`` integrates on the shipped URDF. Friction (4.27) and rotor inertia are not in them:
the rotor inertias are columns of the base regressor (IA_j qdd_j adds to t_j), and the
friction model is a separate function of the generated module.
"""
from __future__ import annotations

import sympy as sp

from derive.dh import Q
from derive.dynamics import QD, QDD, Program, coriolis_matrix, crba, link_params, regressor, rnea
from derive.dynamics_base import COMS, INERTIA, MASS, BaseParameters, base_parameters, numeric_standard
from derive.dynamics import ROTOR
from derive.kernel import Arg, Kernel
from derive.robots import RobotSpec

#: prefix of the programs' assignment symbols (distinct from the lowering's t, s_, c_, x_)
PREFIX = "v"
BASE_NAMES_LABEL = "base parameters in the order: "


def _kernel(spec: RobotSpec, name: str, doc: str, inputs: list[Arg], outputs: list[Arg],
            prog: Program, source: str) -> Kernel:
    used = set()
    for _, e in prog.defs:
        used |= sp.sympify(e).free_symbols
    for a in outputs:
        used |= a.value.free_symbols
    params = {s: v for s, v in spec.params.items() if s in used}
    return Kernel(spec.name, name, doc, tuple(inputs), tuple(outputs), (), params, source,
                  tuple(prog.defs), tuple(a.value for a in outputs), program=True)


def dynamics_kernels(spec: RobotSpec, links) -> tuple[list[Kernel], BaseParameters]:
    """The dynamics kernels of ``spec`` with the link inertials ``links`` (rcci.models.LinkInertial)."""
    dh = spec.dh
    nj = len(dh.links)
    std = numeric_standard(dh, spec.params, links)
    par = [{k: sp.Float(std[s], 17) if std[s] else sp.Integer(0) for k, s in link_params(j + 1).items()}
           for j in range(nj)]
    q, qd, qdd = sp.Matrix(Q[:nj]), sp.Matrix(QD[:nj]), sp.Matrix(QDD[:nj])
    qa = Arg("q", q, "joint variables (rad; m on prismatic joints)")
    qda = Arg("qd", qd, "joint rates (rad/s; m/s)")
    qdda = Arg("qdd", qdd, "joint accelerations (rad/s^2; m/s^2)")
    ks = []

    prog = Program(PREFIX)
    tau = rnea(prog, dh, par, QD, QDD)
    ks.append(_kernel(spec, "inverse_dynamics", "t_j = D(q) qdd + c(q, qd) + t_g(q): rigid-body joint "
                      "torques of the data file's inertials (recursive Newton-Euler; no friction, no rotor)",
                      [qa, qda, qdda], [Arg("tau", sp.Matrix(tau), "N m (N on prismatic joints)")], prog, "4.6"))
    prog = Program(PREFIX)
    d = crba(prog, dh, par)
    ks.append(_kernel(spec, "inertia_matrix", "D(q): the joint-space inertia matrix (composite rigid bodies)",
                      [qa], [Arg("D", d, "kg m^2 (kg on prismatic rows and columns)")], prog, "4.6"))
    prog = Program(PREFIX)
    c = rnea(prog, dh, par, QD, [0] * nj, gravity=0)
    ks.append(_kernel(spec, "coriolis", "c(q, qd): Coriolis and centrifugal torques (Newton-Euler, "
                      "qdd = 0, no gravity)", [qa, qda], [Arg("c", sp.Matrix(c), "N m (N)")], prog, "4.6"))
    prog = Program(PREFIX)
    d = crba(prog, dh, par)
    cm = coriolis_matrix(prog, d, QD)
    ks.append(_kernel(spec, "coriolis_matrix", "C(q, qd) with c = C qd and D' - 2C skew-symmetric "
                      "(Christoffel symbols of D)", [qa, qda], [Arg("C", cm, "N m s (N s)")], prog, "4.6"))
    bp = base_parameters(dh, spec.params)
    prog = Program(PREFIX)
    cols = regressor(prog, dh, QD, QDD, keep=list(bp.leaders))
    y = sp.Matrix(nj, len(bp.names), lambda i, j: cols.torque[j][i])
    ks.append(_kernel(spec, "base_regressor", "Y(q, qd, qdd) with t_j = Y beta (rigid body, gravity and "
                      "rotor inertias; beta: the base parameters)", [qa, qda, qdda],
                      [Arg("Y", y, f"{nj} x b, columns in BASE_PARAMETERS order")], prog, "4.6"))
    ks.append(_base_parameter_kernel(spec, bp))
    return ks, bp


def _base_parameter_kernel(spec: RobotSpec, bp: BaseParameters) -> Kernel:
    """beta of given link inertials (DH frame k, as the data file) and rotor inertias."""
    from derive.dynamics_base import standard_from_links

    std = standard_from_links(spec.dh)
    nj = len(spec.dh.links)
    rotor = sp.Matrix(sp.symbols(f"rotor1:{nj + 1}", real=True))
    sub = {**std, **dict(zip(ROTOR, rotor))}
    beta = sp.Matrix([sp.expand(sp.sympify(m).xreplace(sub)) for m in bp.meanings])
    prog = Program(PREFIX)
    return _kernel(spec, "base_parameters", f"the base parameters of link inertials: masses ({nj},) kg, "
                   f"centres of mass ({nj}, 3) m and inertias about them ({nj}, 6: ixx iyy izz ixy ixz iyz) "
                   f"kg m^2 in DH frames 1..{nj}, rotor inertias ({nj},) at the joints",
                   [Arg("m", sp.Matrix(MASS[:nj]), "kg"), Arg("com", sp.Matrix([list(r) for r in COMS[:nj]]), "m"),
                    Arg("inertia", sp.Matrix([list(r) for r in INERTIA[:nj]]), "kg m^2"),
                    Arg("rotor", rotor, "kg m^2 (kg)")],
                   [Arg("beta", beta, BASE_NAMES_LABEL + ", ".join(bp.names))], prog, "4.6")


def base_names(kernels: list[Kernel]) -> tuple[str, ...]:
    """The base parameters' names, from the base_parameters kernel."""
    k = next(k for k in kernels if k.name == "base_parameters")
    return tuple(k.outputs[0].doc[len(BASE_NAMES_LABEL):].split(", "))
