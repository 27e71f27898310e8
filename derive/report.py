"""reports/thesis-equations.md: every thesis equation the derivation covers, print vs derivation.

For each equation: what the print says (``derive.thesis_print``), whether the derived
expression agrees, and for each disagreement whether it is OCR damage (lost minus signs,
misread letters) or a true erratum, with the corrected (derived) form. Agreement is
tested by evaluating printed minus derived at random points in 40-digit arithmetic
(closed-form trigonometric and rational expressions: zero at five random points means
zero); "signs only" means that after full expansion the two sides have the same terms
with the same magnitudes, i.e. the print lost minus signs, the OCR's usual damage.
"""
from __future__ import annotations

from pathlib import Path

import sympy as sp

from derive import thesis_print as tp
from derive.compare import DC, DQ, TAU, F, Row, equal, namespace, parse, pretty, status_of, verdict
from derive.dh import Q, a2, a_matrices, d3, d4
from derive.inverse import POSE, premultiplied
from derive.kernels import Derivation

COMMAND = "make derive  (python -m derive)"

def _matrix_rows(eq: str, what: str, printed_rows, derived: sp.Matrix, ns, note: str = "",
                 overrides: dict | None = None) -> list[Row]:
    """One row per entry that differs; ``overrides[(i, j)] = (status, note)`` classifies
    a difference the automatic test cannot (a slipped column, a misread letter)."""
    overrides = overrides or {}
    rows = []
    for i, prow in enumerate(printed_rows):
        for j, text in enumerate(prow):
            p = parse(text, ns)
            d = derived[i, j]
            v = verdict(p, d)
            status, why = status_of(v)
            if v != "confirmed" and (i, j) in overrides:
                status, why = overrides[(i, j)]
            if status != "confirmed":
                rows.append(Row(eq, f"{what} [{i + 1},{j + 1}]", text, status,
                                "; ".join(x for x in (why, note) if x), pretty(d, "d2" in ns and ns["d2"] == Q[1])))
    if not rows:
        rows.append(Row(eq, what, "every entry as printed", "confirmed", note))
    return rows


def rows_for(d: Derivation) -> list[Row]:
    name = d.spec.name
    puma = name == "puma260"
    ns = namespace(name)
    rows: list[Row] = []
    # A matrices
    amats = a_matrices(d.spec.dh)
    for k, (eq, prows) in enumerate((tp.A_PUMA if puma else tp.A_MICROBO).items()):
        rows += _matrix_rows(eq, f"A{k + 1}", prows, amats[k], ns)
    # T6
    t6 = d.t6
    printed_t6 = tp.T6_PUMA if puma else tp.T6_MICROBO
    eq = "3.17" if puma else "3.18"
    for key in tp.T6_ORDER:
        col = "noap".index(key[0])
        r = "xyz".index(key[1])
        p = parse(printed_t6[key], ns)
        v = verdict(p, t6[r, col])
        status, why = status_of(v)
        rows.append(Row(eq, f"T6 {key}", printed_t6[key], status, why,
                        "" if status == "confirmed" else pretty(t6[r, col], not puma)))
    # element equations of Paul's method
    for eq, i, col, lhs, rhs, note in (tp.ELEMENT_EQS_PUMA if puma else tp.ELEMENT_EQS_MICROBO):
        left, right = premultiplied(d.spec.dh, i)
        for r in range(3):
            for side, texts, mat in (("lhs", lhs, left), ("rhs", rhs, right)):
                p = parse(texts[r], ns)
                der = mat[r, col - 1]
                v = verdict(p, der)
                err = ""
                if v == "differs" and eq in ("3.47",) and side == "lhs":
                    o_version = parse(texts[r].replace("a", "o").replace("od2", "a2"), ns)
                    if verdict(o_version, der) in ("confirmed", "sign"):
                        err = "a printed where o is meant (the element is in the o column); with o it agrees"
                status, why = status_of(v, err)
                if status != "confirmed":
                    rows.append(Row(eq, f"(A...)^-1 T6 = U, column {col}, row {r + 1} {side}", texts[r],
                                    status, "; ".join(x for x in (why, note) if x), pretty(der, not puma)))
        if not any(r.eq == eq for r in rows):
            rows.append(Row(eq, f"elements of column {col} after {i} inverse A matrices", "as printed",
                            "confirmed", note))
    rows += _ik_rows(d, ns)
    rows += _jacobian_rows(d, ns)
    rows += _computation_rows(d, ns)
    rows += _gravity_rows(d, ns)
    return rows


def _ik_rows(d: Derivation, ns) -> list[Row]:
    """The closed-form solutions (3.36-3.41, 3.48-3.53), checked numerically at random
    reachable poses against the derived solution (angles compared modulo 2 pi)."""
    import math

    import numpy as np

    puma = d.spec.name == "puma260"
    params = d.spec.params
    sol = d.ik
    # the derived solution as emitted (lambdifying the nested expressions directly is slow)
    import importlib

    mod = importlib.import_module(f"rccl.kinematics.{d.spec.name}")
    fk = mod.fk
    rng = np.random.default_rng(5)
    lo, hi = np.array(d.spec.lower), np.array(d.spec.upper)

    def derived(pose_flat, cfg):
        t = np.vstack([np.reshape(pose_flat, (3, 4)), [0.0, 0.0, 0.0, 1.0]])
        return list(mod.ik(t, cfg))
    n_ok = {}
    rows = []

    def wrap(x):
        return (x + math.pi) % (2 * math.pi) - math.pi

    checks = _printed_solutions(puma, params)
    trials = 40
    for _ in range(trials):
        q = rng.uniform(lo, hi)
        t = np.array(fk(q), dtype=float)
        pose = dict(zip([str(s) for s in POSE[:3, :]], t[:3, :].ravel()))
        cfg = (1, 1, 1) if puma else (1,)
        if puma:
            # the printed + signs: right arm (+ root in 3.36), + root in 3.37, 0 < theta5 < pi
            h = params[a2] * math.cos(q[1]) - params[d4] * math.sin(q[1] + q[2])
            cfg = (1, 1 if (-h * math.cos(q[2])) >= 0 else -1, 1)
        want = derived(list(t[:3, :].ravel()), list(cfg))
        for key, (eq, fn, idx, _text, _note, _fix) in checks.items():
            got = fn(pose, want)
            ok = abs(wrap(got - want[idx])) < 1e-9 if idx not in ((1, 2) if not puma else ()) else abs(got - want[idx]) < 1e-12
            n_ok.setdefault(key, []).append(ok)
    for key, (eq, fn, idx, text, note, fix) in checks.items():
        good = all(n_ok[key])
        if good:
            rows.append(Row(eq, f"solution for {key} (agrees at {trials} random poses)", text, "confirmed", note))
        else:
            status = "erratum" if note.startswith("erratum") else "OCR"
            rows.append(Row(eq, f"solution for {key} (differs at random poses)", text, status, note, fix))
    return rows


def _printed_solutions(puma: bool, params) -> dict:
    """The printed closed forms as numeric functions (pose dict, derived q) -> value."""
    import math

    atan2, sqrt, pi = math.atan2, math.sqrt, math.pi
    if puma:
        A2, D3, D4 = params[a2], params[d3], params[d4]

        def th1_print(p, q):  # 3.36 as printed: atan2(py, pz)
            r2 = p["px"] ** 2 + p["py"] ** 2
            return atan2(p["py"], p["pz"]) + atan2(D3, sqrt(max(0.0, r2 - D3**2)))

        def th1_fixed(p, q):  # pz read as px
            r2 = p["px"] ** 2 + p["py"] ** 2
            return atan2(p["py"], p["px"]) + atan2(D3, sqrt(max(0.0, r2 - D3**2)))

        def th3(p, q):  # 3.37 with the elbow sign of the derived solution's configuration
            s1, c1 = math.sin(q[0]), math.cos(q[0])
            fp = c1 * p["px"] + s1 * p["py"]
            f = 2 * A2 * D4
            dd = D4**2 + A2**2 - fp**2 - p["pz"] ** 2
            sign = 1 if math.cos(q[2]) >= 0 else -1
            return pi / 2 - atan2(sign * sqrt(max(0.0, f**2 - dd**2)), dd)

        def th2(p, q):  # 3.38
            s1, c1 = math.sin(q[0]), math.cos(q[0])
            fp = c1 * p["px"] + s1 * p["py"]
            w1, w2 = A2 * math.cos(q[2]), D4 - A2 * math.sin(q[2])
            return atan2(p["pz"] * w1 - fp * w2, p["pz"] * w2 + fp * w1) - q[2]

        def fa(p, q):
            s1, c1 = math.sin(q[0]), math.cos(q[0])
            return p["ay"] * c1 - p["ax"] * s1, p["ay"] * s1 + p["ax"] * c1

        def th4(p, q):  # 3.39a: 0 < theta5 < pi
            fa1, fa2 = fa(p, q)
            s23, c23 = math.sin(q[1] + q[2]), math.cos(q[1] + q[2])
            return atan2(fa1, s23 * p["az"] + c23 * fa2) + pi

        def th5_print(p, q):  # 3.40 as printed, with o
            s1, c1 = math.sin(q[0]), math.cos(q[0])
            s4, c4 = math.sin(q[3]), math.cos(q[3])
            s23, c23 = math.sin(q[1] + q[2]), math.cos(q[1] + q[2])
            f11, f12 = p["oy"] * c1 - p["ox"] * s1, p["oy"] * s1 + p["ox"] * c1
            return atan2(-f11 * s4 - c4 * (p["oz"] * s23 + f12 * c23), -f12 * s23 + p["oz"] * c23)

        def th5_a(p, q):  # 3.40 with a for o
            s1, c1 = math.sin(q[0]), math.cos(q[0])
            s4, c4 = math.sin(q[3]), math.cos(q[3])
            s23, c23 = math.sin(q[1] + q[2]), math.cos(q[1] + q[2])
            f11, f12 = p["ay"] * c1 - p["ax"] * s1, p["ay"] * s1 + p["ax"] * c1
            return atan2(-f11 * s4 - c4 * (p["az"] * s23 + f12 * c23), -f12 * s23 + p["az"] * c23)

        def th6(p, q):  # 3.41
            s1, c1 = math.sin(q[0]), math.cos(q[0])
            s4, c4 = math.sin(q[3]), math.cos(q[3])
            s5, c5 = math.sin(q[4]), math.cos(q[4])
            s23, c23 = math.sin(q[1] + q[2]), math.cos(q[1] + q[2])
            f1, f2 = p["oy"] * c1 - p["ox"] * s1, p["oy"] * s1 + p["ox"] * c1
            inner = f1 * s4 + c4 * (p["oz"] * s23 + f2 * c23)
            return atan2(s5 * (f2 * s23 - p["oz"] * c23) - c5 * inner, c4 * f1 - s4 * (p["oz"] * s23 + f2 * c23))

        return {
            "theta1 (as printed)": ("3.36", th1_print, 0, "atan2(py, pz) + atan2(d3, sqrt(r^2 - d3^2)), r^2 = px^2 + py^2",
                                    "OCR: pz printed for px (3.24 also prints atan2(px, pz) and r^2 = px^2 + pz^2)", "atan2(py, px) + atan2(d3, arm sqrt(px^2 + py^2 - d3^2))"),
            "theta1": ("3.36", th1_fixed, 0, "atan2(py, px) + atan2(d3, +sqrt(r^2 - d3^2)) (pz read as px)", "", ""),
            "theta3": ("3.37", th3, 2, "pi/2 - atan2(+-sqrt(f^2 - d^2), d), f = 2 a2 d4, d = d4^2 + a2^2 - fp^2 - pz^2", "", ""),
            "theta2": ("3.38", th2, 1, "atan2(pz w1 - fp w2, pz w2 + fp w1) - theta3, w1 = a2 C3, w2 = d4 - a2 S3", "", ""),
            "theta4": ("3.39", th4, 3, "atan2(fa1, S23 az + C23 fa2) + pi for 0 < theta5 < pi (a); without + pi for -pi < theta5 < 0 (b)", "", ""),
            "theta5 (as printed)": ("3.40", th5_print, 4, "atan2(-f11 S4 - C4(oz S23 + f12 C23), -f12 S23 + oz C23), f11 = oy C1 - ox S1, f12 = oy S1 + ox C1",
                                    "erratum: the orientation vector o is printed where the approach vector a belongs (3.33 has a); with a it agrees", "atan2(-fa1 S4 - C4(az S23 + fa2 C23), -fa2 S23 + az C23), fa1 = ay C1 - ax S1, fa2 = ay S1 + ax C1"),
            "theta5": ("3.40", th5_a, 4, "the same with a for o", "", ""),
            "theta6": ("3.41", th6, 5, "atan2(S5(fo2 S23 - oz C23) - C5[fo1 S4 + C4(oz S23 + fo2 C23)], C4 fo1 - S4(oz S23 + fo2 C23))", "", ""),
        }

    def m_th1(p, q):
        return atan2(p["py"], p["px"])

    def m_d2(p, q):
        return p["pz"]

    def m_d3(p, q):
        return sqrt(p["px"] ** 2 + p["py"] ** 2)

    def m_th4(p, q):  # 3.51a, comma restored: 0 < theta5 < pi
        s1, c1 = math.sin(q[0]), math.cos(q[0])
        return atan2(p["az"], p["ay"] * c1 - p["ax"] * s1)

    def m_th5(p, q):  # 3.52 with S1 for the printed S4 in the cosine argument
        s1, c1 = math.sin(q[0]), math.cos(q[0])
        s4, c4 = math.sin(q[3]), math.cos(q[3])
        return atan2(p["az"] * s4 + c4 * (p["ay"] * c1 - p["ax"] * s1), -(p["ay"] * s1 + p["ax"] * c1))

    def m_th6_print(p, q):  # 3.53 as printed, with a
        s1, c1 = math.sin(q[0]), math.cos(q[0])
        s4, c4 = math.sin(q[3]), math.cos(q[3])
        s5, c5 = math.sin(q[4]), math.cos(q[4])
        y = (p["ay"] * s1 + c1 * p["ax"]) * s5 + c5 * (p["az"] * s4 + c4 * (c1 * p["ay"] - p["ax"] * s1))
        x = (c1 * p["ay"] - p["ax"] * s1) * s4 - c4 * p["az"]
        return atan2(y, x)

    def m_th6(p, q):  # with o and the sign the derivation gives
        s1, c1 = math.sin(q[0]), math.cos(q[0])
        s4, c4 = math.sin(q[3]), math.cos(q[3])
        s5, c5 = math.sin(q[4]), math.cos(q[4])
        y = (p["oy"] * s1 + c1 * p["ox"]) * s5 + c5 * (p["oz"] * s4 + c4 * (c1 * p["oy"] - p["ox"] * s1))
        x = (c1 * p["oy"] - p["ox"] * s1) * s4 - c4 * p["oz"]
        return atan2(-y, x)

    return {
        "theta1": ("3.48", m_th1, 0, "atan2(py, px)", "", ""),
        "d2": ("3.49", m_d2, 1, "pz", "", ""),
        "d3": ("3.50", m_d3, 2, "sqrt(px^2 + py^2)", "", ""),
        "theta4": ("3.51", m_th4, 3, "atan2(az, ay C1 - ax S1) (comma restored), + pi in the other wrist configuration", "", ""),
        "theta5": ("3.52", m_th5, 4, "atan2(az S4 + C4(ay C1 - ax S1), -(ay S1 + ax C1)) (printed S4 read as S1)", "", ""),
        "theta6 (as printed)": ("3.53", m_th6_print, 5, "atan2((ay S1 + C1 ax) S5 + C5(az S4 + C4(C1 ay - ax S1)), (C1 ay - ax S1) S4 - C4 az)",
                                "erratum: a printed for o (as in 3.47) and the sine argument's sign lost; derived: atan2(-[(oy S1 + ox C1) S5 + C5(oz S4 + C4(oy C1 - ox S1))], (oy C1 - ox S1) S4 - oz C4)", "atan2(-[(oy S1 + ox C1) S5 + C5(oz S4 + C4(oy C1 - ox S1))], (oy C1 - ox S1) S4 - oz C4)"),
        "theta6": ("3.53", m_th6, 5, "corrected: o for a, minus on the sine argument", "", ""),
    }


def _jacobian_rows(d: Derivation, ns) -> list[Row]:
    puma = d.spec.name == "puma260"
    rows = []
    diff = d.diff
    if puma:
        slip = ("OCR", "the column boundary in row 3 was lost: '- d4 S4' printed in column 2 is "
                       "column 3's entry (with its sign)")
        rows += _matrix_rows("3.67", "4J'", tp.J4R_PUMA, diff.j4_reduced, ns, "",
                             {(2, 1): slip, (2, 2): slip})
        rows += _matrix_rows("3.68", "4J'^-1", tp.J4R_INV_PUMA, diff.j4_reduced_inv, ns, tp.J4R_INV_NOTE)
        rows += _matrix_rows("3.81", "B", tp.B_PUMA, diff.b, ns)
    else:
        rows += _matrix_rows("3.69", "4J", tp.J4_MICROBO, diff.j4_reduced, ns)
        rows += _matrix_rows("3.70", "4J^-1", tp.J4_INV_MICROBO, diff.j4_reduced_inv, ns)
        rows += _matrix_rows("3.82", "B", tp.B_MICROBO, diff.b, ns)
    return rows


def _computation_rows(d: Derivation, ns) -> list[Row]:
    puma = d.spec.name == "puma260"
    diff = d.diff
    j4 = diff.j4
    jinv = diff.y.inv() * diff.j4_reduced_inv
    dq = sp.Matrix(list(DQ.values()))
    dc = sp.Matrix(list(DC.values()))
    f = sp.Matrix(list(F.values()))
    tau = sp.Matrix(list(TAU.values()))
    derived = {"forward": j4 * dq, "torque": j4.T * f, "joint": jinv * dc, "force": jinv.T * tau}
    labels = {"forward": ("dx", "dy", "dz", "d_psi", "d_rho", "d_phi"),
              "torque": tuple(f"tau{i}" for i in range(1, 7)),
              "joint": tuple(f"dth{i}" for i in range(1, 7)),
              "force": ("fx", "fy", "fz", "tau_x", "tau_y", "tau_z")}
    rows = []
    for eq, (kind, steps, note) in (tp.COMP_PUMA if puma else tp.COMP_MICROBO).items():
        env = dict(ns)
        texts, printed = {}, {}
        for name, text in steps:
            value = parse(text, env)
            texts[name] = text
            if name.startswith("out"):
                # later lines use this output: give them the derived value, so that one
                # damaged line does not condemn the lines after it
                printed[name] = value
                value = derived[kind][int(name[3:]) - 1]
            env[name] = value
        bad = []
        fixes = tp.COMP_FIXES.get(eq, {})
        for i in range(6):
            p = printed[f"out{i + 1}"]
            der = derived[kind][i]
            v = verdict(p, der)
            if v != "confirmed":
                status, why = status_of(v)
                if v == "differs" and i + 1 in fixes:
                    status, why = fixes[i + 1]
                bad.append(Row(eq, f"{kind}: {labels[kind][i]}", texts.get(f"out{i + 1}", ""), status,
                               "; ".join(x for x in (why, note) if x), pretty(sp.factor(der), not puma)))
        rows += bad or [Row(eq, f"{kind} computation, all six lines", "as printed", "confirmed", note)]
    return rows


def _gravity_rows(d: Derivation, ns) -> list[Row]:
    gm = d.gravity
    puma = d.spec.name == "puma260"
    rows = []
    if not puma:
        rows.append(Row("4.20", "Microbo gravity vector (prismatic h for joints 2, 3)",
                        "(the thesis gives no Microbo gravity model)", "checked",
                        "derived: tau_g = (0, c12, 0, -c15 C4 S5, -c15 S4 C5, 0) with c12 = g(m2+..+m6), "
                        "c15 = -g(m5 z5 + m6 z6); cross-checked against Pinocchio",
                        pretty(list(gm.regressor * sp.Matrix(gm.coeff_symbols)), True)))
        return rows
    c = {n: sp.Symbol(n, real=True) for n in gm.coeff_names}
    env = {**ns, **c}
    tau = gm.regressor * sp.Matrix(gm.coeff_symbols)
    bad = []
    for i, text in enumerate(tp.GRAVITY_PUMA):
        v = verdict(parse(text, env), tau[i])
        if v != "confirmed":
            status, why = status_of(v)
            bad.append(Row("4.24", f"tau_g{i + 1}", text, status, why, pretty(tau[i])))
    rows += bad or [Row("4.24", "gravity vector, all six rows", "as printed", "confirmed",
                        "derived from 4.20 with the centres of mass of 4.21 and g = (0, 0, -g) (upright); "
                        "the grouping into c12, c13, c15 is exact (no remainder)")]
    for name, meaning in zip(gm.coeff_names, gm.coeff_meaning):
        text = tp.COEFFS_PUMA[name]
        v = verdict(parse(text, env), meaning)
        if v == "confirmed":
            rows.append(Row("4.24", f"coefficient {name}", text, "confirmed"))
        else:
            rows.append(Row("4.24", f"coefficient {name}", text, "erratum" if name == "c13" else "differs",
                            "m3 x3 printed, but 4.21 puts link 3's centre of mass on z3, r3 = (0, 0, z3); only "
                            "m3 z3 multiplies S23 in 4.20" if name == "c13" else "", pretty(meaning)))
    reg = gm.regressor
    ok = equal(tau[1], tau[2] + sp.cos(Q[1]) * gm.coeff_symbols[0])
    rows.append(Row("4.25", "tau_g2 = tau_g3 + C2 c12", "t_g2 = t_g3 + C2 c12", "confirmed" if ok else "differs"))
    for name, inc in zip(gm.coeff_names, gm.tool_update):
        text = tp.TOOL_PUMA[name]
        v = verdict(parse(text, env), inc)
        rows.append(Row("4.26", f"tool load: {name}' - {name}", text, "confirmed" if v == "confirmed" else "differs",
                        "the load is link 6 gaining mass m_t at (0, 0, d_t)", "" if v == "confirmed" else pretty(inc)))
    del reg
    return rows


def _general_rows(derivations: dict[str, Derivation]) -> list[Row]:
    """Equations that are definitions or procedures: checked by what they produce."""
    from derive.jacobian import d_map, f_map

    rows = []
    # 1.13 / 1.22 / 1.23 on a random rigid transform
    import numpy as np

    rng = np.random.default_rng(1)
    a = rng.normal(size=(3, 3))
    qm, _ = np.linalg.qr(a)
    if np.linalg.det(qm) < 0:
        qm[:, 0] *= -1
    x = sp.eye(4)
    x[:3, :3] = sp.Matrix(qm)
    x[:3, 3] = sp.Matrix(rng.normal(size=3))
    dm, fm = d_map(x), f_map(x)
    inv_t = dm.inv().T
    err = max(abs(float(v)) for v in (fm - inv_t))
    rows.append(Row("1.13", "D_{O,X} from n, o, a, p", "rows (n, (p.n)), (o, (p.o)), ...; row 2 prints -o_y",
                    "OCR", "the print's 'p . n' is p x n and the '-o_y' sign is spurious; the derived D gives "
                    "the Jacobians that match Pinocchio (reports/crosscheck.md)",
                    "[[n^T, (p x n)^T], [o^T, (p x o)^T], [a^T, (p x a)^T], [0, n^T], [0, o^T], [0, a^T]]"))
    rows.append(Row("1.22-1.23", "F_{O,X} = D_{O,X}^-T", "[[n^T, 0], ..., [(p x n)^T, n^T], ...]",
                    "confirmed" if err < 1e-12 else "differs", f"F = D^-T checked on a random transform (error {err:.1e})"))
    rows.append(Row("3.1-3.2", "dc = J dtheta, t_j = J^T q", "as printed", "confirmed",
                    "definitions; the kernels cartesian_from_joint and torque_from_force implement them"))
    rows.append(Row("3.22, 3.28, 3.32, 3.34", "A1^-1 T6 = U2, (A1 A2 A3)^-1 T6 = U4, (A1..A4)^-1 T6 = U5, "
                    "(A1..A5)^-1 T6 = U6", "as printed", "confirmed",
                    "the premultiplied equations whose elements are 3.23, 3.29/3.31, 3.33, 3.35 (rows below)"))
    rows.append(Row("3.42-3.44", "Microbo px = C1 d3, py = S1 d3, pz = d2; theta1, d3", "as printed", "confirmed",
                    "the fourth column of 3.18; solutions as 3.48-3.50 (rows below)"))
    rows.append(Row("3.3", "general A matrix", "entries without minus signs", "OCR",
                    "the print lost every minus sign; the A matrices 3.4-3.15 are instances of the standard form",
                    "[[Ct, -St Ca, St Sa, a Ct], [St, Ct Ca, -Ct Sa, a St], [0, Sa, Ca, d], [0, 0, 0, 1]]"))
    rows.append(Row("Table 3.1", "alpha column", "90, 0, 90, 90, 90, 0", "OCR",
                    "the A matrices 3.6 and 3.8 need alpha3 = alpha5 = -90 deg", "90, 0, -90, 90, -90, 0"))
    rows.append(Row("3.16", "T6 = A1 A2 A3 A4 A5 A6", "as printed", "confirmed", "T6 matches Pinocchio on the URDF"))
    rows.append(Row("3.19", "(A1..Ai)^-1 T6 = A(i+1)..A6", "A(i+1)^-1 A(i)^-1 T6 = U(i), U(i) = A(i) A(i+1)^-1",
                    "OCR", "subscripts garbled; used as (A1 .. A(i-1))^-1 T6 = A(i) .. A6", ""))
    rows.append(Row("3.20-3.21", "a S + b C = c", "theta = -atan2(b, a) + atan2(c, +-sqrt(a^2 + b^2 - c^2))",
                    "confirmed", "used for theta1 and theta3; radicand clamped at 0 within a 1e-12 relative reach tolerance"))
    rows.append(Row("3.24", "theta1", "atan2(px, pz) + atan2(d3 +- sqrt(r^2 - d3^2)), r^2 = px^2 + pz^2", "OCR",
                    "letters and a comma misread; see 3.36", "atan2(py, px) + atan2(d3, +-sqrt(px^2 + py^2 - d3^2))"))
    rows.append(Row("3.25", "2 a2 d4 S3 = d4^2 + a2^2 - fp^2 - pz^2", "d4^2 + a2^2 - f_f^2 - p_z^2 = 2 a2 d4 S3",
                    "confirmed", "from the sum of squares of rows 1, 2 of 3.23 (asserted in derive/inverse.py)"))
    rows.append(Row("3.26", "atan2(a, b) = pi/2 - atan2(b, a)", "as printed", "confirmed", "holds modulo 2 pi"))
    rows.append(Row("3.27", "theta3", "pi/2 - atan2(+-sqrt(ff^2 - d4^2), d4), ff = 2 a2 d4, d4 = sqrt(...)", "OCR",
                    "the auxiliary names collide with d4 and f_f; 3.37 prints the intended form (f, d, no sqrt)", ""))
    rows.append(Row("3.30", "theta2 + theta3", "atan2(pz u1 - fz u2, pz w2 + fz w1), u1 = a2 c3, u2 = d4 - a2 s3",
                    "OCR", "fz is fp and u/w are one pair of names; 3.38 is the same with w", ""))
    rows.append(Row("3.54-3.59", "kJ columns j_i = D_{i-1,k}(c_i)", "as printed", "confirmed",
                    "4J and 6J built this way match Pinocchio (6J = LOCAL frame Jacobian)"))
    rows.append(Row("3.60", "revolute column ((p x n)_z, (p x o)_z, (p x a)_z, n_z, o_z, a_z)", "as printed",
                    "confirmed", "D_{i-1,k} applied to c = (0,0,0,0,0,1)"))
    rows.append(Row("3.61", "prismatic column", "(n_x, n_y, n_z, 0, 0, 0)", "erratum",
                    "D applied to c = (0,0,1,0,0,0) picks the z components of n, o, a (the Microbo's 4J, 3.69, "
                    "columns 2 and 3, and Pinocchio agree)", "(n_z, o_z, a_z, 0, 0, 0)"))
    rows.append(Row("3.62-3.63", "4J = 4J' Y", "Y printed 4x4", "OCR",
                    "Y is the 6x6 identity with Y[3,2] = 1 (dth2 + dth3 in place of dth3)", ""))
    rows.append(Row("3.64-3.66", "tau = (4J' Y)^T q, Y^-T tau = 4J'^T q",
                    "(t1, t2 - t3, t3, t4, t5, t6) = 4J'^T q", "confirmed",
                    "Y^-T tau = (t1, t2 - t3, t3, ...) by direct product"))
    rows.append(Row("3.73-3.74", "structure of the inverse Jacobian computations",
                    "substitution: dth1 first, then dth2 from it, ...", "checked",
                    "4J' is block lower triangular and its top block observed in frame 3 (rotated back through "
                    "A4) is triangular up to a permutation, as is the wrist block (derive/jacobian.py "
                    "triangular_form); the generated C solves J' and J'^T by substitution this way (signs of the "
                    "printed formulas not checked term by term; the kernels match Pinocchio)"))
    rows.append(Row("3.8 text", "each transform of (3.79): 8 multiplies and 4 additions", "as printed", "confirmed",
                    "true of B (3.81/3.82) applied to ONE 3-vector: two plane rotations, by theta5 and theta6, of "
                    "4 mul and 2 add each; a D or F map of (3.80) applies B to both halves of the 6-vector, 16 mul "
                    "and 8 add (reports/opcounts.md)"))
    rows.append(Row("3.79", "frame-6 computations via D_{4,6}, D_{6,4}, F_{4,6}, F_{6,4}", "as printed",
                    "confirmed", "the frame-6 kernels are built this way and match Pinocchio's 6J"))
    rows.append(Row("3.80", "D and F for X = A5 A6", "D_{4,6} = diag(B, B); F_{4,6} = [[0, B], [B, 0]]",
                    "erratum", "frames 4, 5, 6 share one origin (p = 0), so F_{4,6} = D_{4,6}^-T = diag(B, B); the "
                    "off-diagonal layout would exchange forces and moments",
                    "D_{4,6} = F_{4,6} = diag(B, B), D_{6,4} = F_{6,4} = diag(B^T, B^T)"))
    rows.append(Row("4.20", "tau_gi = -h_i sum_k m_k U_k r_k", "as printed", "confirmed",
                    "with h_i = (g.o, -g.n, 0, 0) revolute, (0, 0, 0, g.a) prismatic; equals Pinocchio's "
                    "generalised gravity for random masses and centres of mass (reports/crosscheck.md)"))
    rows.append(Row("4.21", "PUMA centres of mass", "(0,0,z1), (x2,0,z2), (0,0,z3), (0,y4,0), (0,0,z5), (0,0,z6)",
                    "confirmed", "with these the grouping 4.24 is exact"))
    rows.append(Row("4.22", "g in the base frame", "g^T = (0 0 g 0)", "OCR",
                    "upright mounting means g = (0, 0, -g, 0) with g = 9.81 m/s^2 > 0; the signs of Table 4.9 "
                    "(c12 > 0) need this", "(0, 0, -g, 0)"))
    rows.append(Row("4.23", "h_i = (o_z,i-1, -n_z,i-1, 0, 0)", "as printed", "confirmed", "times -g (absorbed in the c_ij)"))
    rows.append(Row("3.5 text", "wrist singularities", "PUMA theta5 = 0; Microbo theta5 = pi", "confirmed",
                    "both arms are singular wherever S5 = 0 (theta5 = 0 or pi). PUMA: theta5 = 0 is the straight "
                    "wrist (z5 = z3); Microbo: theta5 = pi is the straight wrist and theta5 = 0 points the tool "
                    "back into the arm, outside the joint range"))
    return rows


def write_report(derivations: dict[str, Derivation], path: Path) -> Path:
    lines = [
        "# Thesis equations vs the SymPy derivation",
        "",
        f"Written by `{COMMAND}`. One row per thesis equation (matrix equations: one row per",
        "entry that differs, or one row if all agree). *Print* is the OCR'd thesis as far as it",
        "can be read (derive/thesis_print.py). *Status*: **confirmed** = the derivation gives the",
        "printed expression; **OCR** = the print lost minus signs or misread letters, the",
        "intended expression is the derived one; **erratum** = the typescript itself is wrong",
        "(a wrong letter or layout that no reading of the OCR repairs); **checked** = no printed",
        "formula to compare, derived and cross-checked; in the last section (derive/audit.py)",
        "**derived** = re-derived there (SymPy, or a numeric identity at fixed random points),",
        "**implemented** = the project code named implements it and the test named verifies it,",
        "**definition** = a name, a model statement or prose (the reason is given). Where they differ the derivation",
        "wins and *Corrected* gives the derived form (S1 = sin theta1, C23 = cos(theta2 + theta3)).",
        "Comparison: printed minus derived evaluated at random points in 40-digit arithmetic;",
        "IK solution formulas are evaluated at 40 random reachable poses against the derived",
        "solution.",
        "",
    ]
    from derive.audit import rows as audit_rows

    for title, rows in [("General (chapter 1, procedures)", _general_rows(derivations))] + [
            (f"{d.spec.name}", rows_for(d)) for d in derivations.values()] + [
            ("The rest of the thesis (1.1-1.21, 3.83-3.84, 4.1-4.19, 4.27-4.57, chapter 5, appendix E)",
             audit_rows(derivations))]:
        counts = {}
        for r in rows:
            counts[r.status] = counts.get(r.status, 0) + 1
        lines += [f"## {title}", "", "Summary: " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())), "",
                  "| eq. | quantity | print | status | note | corrected (derived) |", "|---|---|---|---|---|---|"]
        for r in rows:
            cells = [r.eq, r.what, f"`{r.printed}`" if r.printed else "", r.status, r.note,
                     f"`{r.corrected}`" if r.corrected else ""]
            lines.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
        lines.append("")
    from derive.dynamics_report import dynamics_section

    lines += ["## The whole dynamics (4.6-4.7) of the thesis arms", "",
              "4.6 is derived in full (derive/dynamics.py) and 4.7 and 4.8-4.26 are its static special case: the "
              "inverse dynamics at qd = qdd = 0 is t_g, equal to the gravity kernels built from 4.20 and grouped as "
              "4.24 (tests/test_dynamics.py::test_gravity_is_the_static_case, every arm); D, c, C and the inverse "
              "dynamics equal Pinocchio's crba, computeCoriolisMatrix and rnea on the URDFs "
              "(tests/test_dynamics.py, reports/crosscheck.md).", ""]
    for d in derivations.values():
        lines += [f"### {d.spec.name}", ""] + dynamics_section(d.spec, level="####")[2:]
    path.parent.mkdir(parents=True, exist_ok=True)
    text = "\n".join(lines)
    if not path.exists() or path.read_text() != text:
        path.write_text(text)
    return path
