"""The dynamics section of an arm's derivation report (thesis eq. 4.6, ``derive.dynamics``):
frames, the grouping rules as applied, the base parameters with their meanings, and the
operation counts of the generated C dynamics kernels."""
from __future__ import annotations

from pathlib import Path

import sympy as sp

from derive.dynamics_base import base_parameters
from derive.opcount import count_file
from derive.robots import RobotSpec

ROOT = Path(__file__).resolve().parent.parent
KERNELS = ("inverse_dynamics", "inertia_matrix", "coriolis", "coriolis_matrix", "base_regressor", "base_parameters")


def dynamics_section(spec: RobotSpec, level: str = "##") -> list[str]:
    """Markdown lines of the dynamics section of ``spec``'s report."""
    bp = base_parameters(spec.dh, spec.params)
    out = [f"{level} The whole dynamics (eq. 4.6): D(q) qdd + c(q, qd) + t_g(q) = t_j", "",
           "Derived by derive/dynamics.py as straight-line programs (recursive Newton-Euler for the inverse "
           "dynamics, c and the regressor; composite rigid bodies for D; C = (D' + P - P^T)/2 with P = d(D qd)/dq, "
           "the Christoffel form, by forward differentiation of the D program), never expanded. Link j's "
           "parameters are in its joint frame j' (DH frame j-1 turned by theta_j and shifted by d_j: z along joint "
           "j's axis; DH frame j = j' Tx(a_j) Rx(alpha_j)): XXj XYj XZj YYj YZj ZZj the inertia about the origin "
           "of j' (kg m^2), MXj MYj MZj = m_j c_j (kg m), Mj (kg); IAj the rotor inertia reflected to joint j. "
           "The generated module's `base_parameters(m, com, inertia, rotor)` computes them from the data file's "
           "form (centre of mass and inertia about it in DH frame k). t_g, the static case (qd = qdd = 0), equals "
           "the gravity kernels of 4.20/4.24 (tests/test_dynamics.py::test_gravity_is_the_static_case); "
           "friction (4.27) and the actuator term t_a are not in these kernels.", "",
           f"{level}# Grouping rules, as applied (tip to base)", ""]
    out += [f"- {r}" for r in bp.rules]
    out += ["", "Then numerically (regressor columns at 24 random states): parameters with no effect on any "
            "torque: " + (", ".join(bp.dropped) or "none") + "; columns folded into earlier ones: "
            + ("; ".join(bp.folded) or "none") + ".", "",
            f"{level}# Base parameters ({len(bp.names)}; the generated module's BASE_PARAMETERS, the columns of "
            "base_regressor)", "", "| base parameter | = (standard parameters, joint frames) |", "|---|---|"]
    for name, meaning in zip(bp.names, bp.meanings):
        out.append(f"| {name} | `{sp.sstr(meaning)}` |")
    c_file = ROOT / "rccl" / "kinematics" / "_c" / f"{spec.name}.c"
    if c_file.exists():
        rows = {r["kernel"]: r for r in count_file(c_file) if r["kernel"] in KERNELS}
        out += ["", f"{level}# Operation counts of the generated C (rccl/kinematics/_c/{spec.name}.c)", "",
                "| kernel | mul/div | add/sub | sin/cos |", "|---|---:|---:|---:|"]
        for k in KERNELS:
            if k in rows:
                r = rows[k]
                out.append(f"| {k} | {r['mul_div']} | {r['add_sub']} | {r['trig']} |")
    return out + [""]
