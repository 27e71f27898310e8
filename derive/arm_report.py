"""reports/derivation-<robot>.md: the derivation of an arm that is not one of the thesis's.

The thesis arms are audited against the print (reports/thesis-equations.md, derive.report);
any other arm has no print to compare with, so its report shows what the derivation did,
in the thesis's order: the DH table, the A matrices (3.3), T6 (3.16), the elements of
L_i = U_i (3.19) the inverse solves and the closed forms it found, the link-4 Jacobian
(3.54-3.61) and the denominators of its inverse, and the gravity coefficients with their
regressor (4.20, 4.24). Expressions are SymPy's, lengths kept as symbols.
"""
from __future__ import annotations

from pathlib import Path

import sympy as sp

from derive.dh import a_matrices
from derive.kernels import Derivation

COMMAND = "make derive  (python -m derive)"


def _expr(e) -> str:
    return sp.sstr(e)


def _matrix(m: sp.Matrix, name: str) -> list[str]:
    lines = ["```", f"{name} ="]
    for i in range(m.rows):
        lines.append("  [" + ",  ".join(_expr(m[i, j]) for j in range(m.cols)) + "]")
    lines.append("```")
    return lines


def _entries(m: sp.Matrix, name: str) -> list[str]:
    lines = ["```"]
    for i in range(m.rows):
        for j in range(m.cols):
            if m[i, j] != 0:
                lines.append(f"{name}[{i + 1},{j + 1}] = {_expr(m[i, j])}")
    lines.append("```")
    return lines


def arm_report(d: Derivation) -> str:
    spec, ik, diff, gm = d.spec, d.ik, d.diff, d.gravity
    dh = spec.dh
    out = [f"# Derivation: {spec.name}", "",
           f"Written by `{COMMAND}` from `models/{Path(spec.model_path).name}`; do not edit.",
           "Not a thesis arm: nothing here is compared with the print (that is",
           "reports/thesis-equations.md for the PUMA 260 and the Microbo); the cross-check",
           "against Pinocchio is tests/test_crosscheck.py and `python -m derive.crosscheck`.",
           "", "## DH table (standard, thesis eq. 3.3)", "",
           "| joint | kind | theta | d | a | alpha |", "|---|---|---|---|---|---|"]
    for i, (link, kind) in enumerate(zip(dh.links, spec.kinds), start=1):
        out.append(f"| {i} | {kind} | {_expr(link.theta)} | {_expr(link.d)} | {_expr(link.a)} | {_expr(link.alpha)} |")
    out += ["", "Lengths (m): " + ", ".join(f"{s} = {v!r}" for s, v in spec.params.items() if str(s) != "g")
            + f"; g = {spec.params[sp.Symbol('g', positive=True)]!r} m/s^2.", ""]
    out += ["## A matrices (3.3)", ""]
    for k, a in enumerate(a_matrices(dh), start=1):
        out += _matrix(a, f"A{k}")
    n = len(dh.links)
    out += ["", f"## T{n} = A1 ... A{n} (3.16)", ""]
    out += _entries(d.t6[:3, :], f"T{n}")
    if ik is None:
        return "\n".join(out + _redundant_sections(d)) + "\n"
    out += ["", f"## Inverse kinematics: {ik.kind} class, Paul's method (3.19)", "",
            "Each step reads an element of (A1..Ai)^-1 T6 = A(i+1)..A6 that holds one new unknown",
            "(the thesis equation it mirrors on the PUMA 260 in the first column).", "",
            "| mirrors | premultiplied by | element | left side (pose, solved joints) | right side |",
            "|---|---|---|---|---|"]
    for e in ik.equations:
        out.append(f"| {e.thesis} | {e.premultiplied} inverse A | ({e.row},{e.col}) | `{_expr(e.lhs)}` | `{_expr(e.rhs)}` |")
    out += ["", "Configuration signs: " + ", ".join(map(str, ik.config)) + "; the sign of each indicator",
            "(a function of q) is the configuration of q:", "", "```"]
    for c, ind in zip(ik.config, ik.indicators):
        out.append(f"{c}: {_expr(ind)}")
    out += ["```", "", "Closed forms (intermediate names as in the code):", "", "```"]
    for name, e in ik.named.items():
        out.append(f"{name} = {_expr(e)}")
    out += ["```", "", "Guards (a negative value raises the error):", "",
            "| guard | error | meaning |", "|---|---|---|"]
    for name, _, error, message in ik.guards:
        out.append(f"| {name} | {error} | {message} |")
    out += _jacobian_and_gravity(d)
    return "\n".join(out) + "\n"


def _redundant_sections(d: Derivation) -> list[str]:
    """A 7-joint arm: the plug-in point of its inverse kinematics, its 6 x 7 Jacobians (sizes:
    their entries are the expanded products, hundreds of terms), gravity."""
    from derive.redundant import SOLVER_MODULE, solver_available

    n = len(d.spec.dh.links)
    out = ["", "## Inverse kinematics: redundant class (7 joints)", "",
           "A pose fixes six of the seven joint variables' combinations: Paul's method (3.19) has one",
           "unknown too many. The closed-form solver with a free parameter (one joint or an arm",
           f"angle) is `{SOLVER_MODULE}` (plugged in by derive/redundant.py): "
           + ("present, its kernels are emitted." if solver_available() else
              "not derived yet, so the generated module's ik and ik_all raise NoSolver naming it."),
           "", f"## Jacobians (6 x {n}): link {n} observed in frame {n} and in frame 4's axes", "",
           f"{n}J column i is D_(i-1,{n}) c_i (3.57-3.61 with k = {n}); 4J = diag(B, B) {n}J with B the",
           f"rotation of frame {n} in frame 4 (3.81), the motion of link {n}'s origin in frame 4's axes.",
           "The inverse computations are the runtime's minimum-norm and least-squares solutions",
           "(rccl/kinematics/redundant.py); no symbolic inverse.", "",
           "| matrix | non-zero entries | operations (SymPy count_ops, expanded) |", "|---|---|---|"]
    for name, m in (("4J", d.diff.j4), (f"{n}J", d.diff.j6)):
        nz = sum(1 for e in m if e != 0)
        out.append(f"| {name} | {nz} | {sum(sp.count_ops(e) for e in m)} |")
    return out + _gravity(d)


def _jacobian_and_gravity(d: Derivation) -> list[str]:
    """The link-4 Jacobian of a 6-joint arm, the denominators of its inverse, gravity."""
    diff = d.diff
    out = ["", "## Jacobian of link 6 observed in frame 4 (3.54-3.61)", ""]
    out += _entries(diff.j4, "4J")
    if diff.y != sp.eye(6):
        out += ["", "Joints 2 and 3 are parallel: 4J = 4J' Y with Y of 3.63 (dq2 + dq3 as one rate).", ""]
    out += ["", "Factors of the denominators of the inverse (a zero is a singularity):", "", "```"]
    out += [_expr(f) for f in diff.det_factors]
    out += ["```"]
    return out + _gravity(d)


def _gravity(d: Derivation) -> list[str]:
    """The gravity coefficients with their meanings, and their regressor (4.20, 4.24)."""
    spec, gm = d.spec, d.gravity
    out = ["", "## Gravity (4.20, 4.24)", "",
            "tau_g = Y(q) c holds the arm against g = (0, 0, -g) in the base frame. "
            + ("The coefficients are the model file's grouping." if spec.com_form is not None else
               "The coefficients are the minimal identifiable set found by the derivation "
               "(derive.gravity.minimal_gravity): each is g times one first moment m_k r_k with "
               "every parameter that cannot be told apart from it folded in."), "",
            "| coefficient | in link masses m_k and centres of mass (x_k, y_k, z_k) in frame k |",
            "|---|---|"]
    for n, m in zip(gm.coeff_names, gm.coeff_meaning):
        out.append(f"| {n} | `{_expr(m)}` |")
    out += ["", "Regressor Y(q), one row per joint:", ""]
    out += _entries(gm.regressor, "Y")
    return out


def write_arm_report(d: Derivation, path: Path) -> Path:
    from derive.dynamics_report import dynamics_section

    text = arm_report(d) + "\n" + "\n".join(dynamics_section(d.spec))
    path.parent.mkdir(parents=True, exist_ok=True)
    if not path.exists() or path.read_text() != text:
        path.write_text(text)
    return path
