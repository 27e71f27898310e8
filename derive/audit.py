"""The rest of the thesis audited (reports/thesis-equations.md, last section): 1.1-1.21, 3.83-3.84,
4.1-4.19, 4.27-4.57, chapter 5 and appendix E.

Each numbered equation is either re-derived here (SymPy or a numeric identity at fixed
random points: status **derived**, or **OCR** when the derivation shows the print lost a
sign or a symbol), or implemented by project code that a named test verifies (status
**implemented**: the test is in tests/, this module never imports rci or rccl), or marked
**definition** (a name given to a quantity, a model stated, or prose: nothing to derive),
with the reason. Checks here are cheap: they run inside ``make derive``.
"""
from __future__ import annotations

import numpy as np
import sympy as sp

from derive.dh import Q, a_matrices

AUDIT_TEST = "tests/test_thesis_audit.py"

_RNG_SEED = 17


def _rigid(rng: np.random.Generator) -> np.ndarray:
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    if np.linalg.det(q) < 0:
        q[:, 0] *= -1
    x = np.eye(4)
    x[:3, :3] = q
    x[:3, 3] = rng.normal(size=3)
    return x


def _rot(axis: int, a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    r = np.eye(4)
    r[i, i], r[i, j], r[j, i], r[j, j] = c, -s, s, c
    return r


def _trans(d) -> np.ndarray:
    t = np.eye(4)
    t[:3, 3] = d
    return t


def delta_from_motion(dc: np.ndarray, eps: float = 1e-7) -> np.ndarray:
    """Delta of 1.7 obtained from a small motion: C^-1 dC for dC = C Trans(eps d) Rot(x) Rot(y) Rot(z) - C."""
    move = _trans(eps * dc[:3]) @ _rot(0, eps * dc[3]) @ _rot(1, eps * dc[4]) @ _rot(2, eps * dc[5])
    return (move - np.eye(4)) / eps


def delta_printed(dc, *, sign_of_dw_in_row_2: int = 1) -> np.ndarray:
    """1.8 as printed (row 2, column 3 reads '+dw'); ``sign_of_dw_in_row_2=-1`` is the derived form."""
    dx, dy, dz, dw, dp, df = dc
    return np.array([[0, -df, dp, dx], [df, 0, sign_of_dw_in_row_2 * dw, dy], [-dp, dw, 0, dz], [0, 0, 0, 0]])


def check_delta() -> tuple[float, float]:
    """(error of the print, error of the derived form) against a small motion (1.7-1.8)."""
    rng = np.random.default_rng(_RNG_SEED)
    dc = rng.normal(size=6)
    measured = delta_from_motion(dc)
    return (float(np.abs(delta_printed(dc) - measured).max()),
            float(np.abs(delta_printed(dc, sign_of_dw_in_row_2=-1) - measured).max()))


def check_similarity() -> float:
    """1.4-1.5 and 1.9-1.12: with XA = X^-1 A X, X XA = A X, and X^-1 (C Delta) X = XC XDelta."""
    rng = np.random.default_rng(_RNG_SEED)
    x, a, c = _rigid(rng), _rigid(rng), _rigid(rng)
    xi = np.linalg.inv(x)
    delta = delta_printed(rng.normal(size=6), sign_of_dw_in_row_2=-1)
    e1 = np.abs(x @ (xi @ a @ x) - a @ x).max()
    e2 = np.abs(xi @ (c @ delta) @ x - (xi @ c @ x) @ (xi @ delta @ x)).max()
    return float(max(e1, e2))


def check_homogeneous() -> float:
    """1.1-1.3: the 4x4 transform with columns n, o, a, p maps (r, 1) to R r + p."""
    rng = np.random.default_rng(_RNG_SEED)
    x, r = _rigid(rng), rng.normal(size=3)
    return float(np.abs((x @ np.append(r, 1.0))[:3] - (x[:3, :3] @ r + x[:3, 3])).max())


def check_virtual_work() -> bool:
    """1.14-1.19 in SymPy: for p2 = f(p1) (polar to Cartesian and a nonlinear third coordinate),
    q1 = J_f^T q2 makes q1^T dp1 = q2^T dp2 identically."""
    r, phi, z = sp.symbols("r phi z", real=True)
    p1 = sp.Matrix([r, phi, z])
    f = sp.Matrix([r * sp.cos(phi), r * sp.sin(phi), z + r ** 2 * phi])
    jf = f.jacobian(p1)                                                   # 1.16-1.17
    q2 = sp.Matrix(sp.symbols("qa qb qc", real=True))
    dp1 = sp.Matrix(sp.symbols("dr dphi dz", real=True))
    q1 = jf.T * q2                                                        # 1.19
    return sp.simplify((q1.T * dp1)[0] - (q2.T * (jf * dp1))[0]) == 0   # 1.15, 1.18


def check_error_expansion() -> tuple[float, float]:
    """3.83-3.84: prod(A_i + dA_i) - prod(A_i) - (first-order terms) shrinks as eps^2 (ratio ~100 per
    decade) and the first-order term is linear in the error parameters (M e)."""
    rng = np.random.default_rng(_RNG_SEED)
    a = [_rigid(rng) for _ in range(6)]
    da = [rng.normal(size=(4, 4)) * np.r_[1, 1, 1, 0][:, None] for _ in range(6)]

    def residual(eps: float) -> float:
        full = np.linalg.multi_dot([ai + eps * d for ai, d in zip(a, da)])
        first = sum(np.linalg.multi_dot(a[:i] + [eps * da[i]] + a[i + 1:]) for i in range(6))
        return float(np.abs(full - np.linalg.multi_dot(a) - first).max())

    return residual(1e-3) / residual(1e-4), residual(1e-4)


def _q_matrix(prismatic: bool) -> np.ndarray:
    """Q_i of 4.13/4.14 from 1.8: Delta for a unit rotation about z, or a unit translation along z."""
    dc = np.array([0, 0, 1, 0, 0, 0.0]) if prismatic else np.array([0, 0, 0, 0, 0, 1.0])
    return delta_printed(dc, sign_of_dw_in_row_2=-1)


def check_q_matrices() -> bool:
    rot = np.zeros((4, 4))
    rot[0, 1], rot[1, 0] = -1, 1
    pri = np.zeros((4, 4))
    pri[2, 3] = 1
    return bool(np.array_equal(_q_matrix(False), rot) and np.array_equal(_q_matrix(True), pri))


def check_partial_derivative(dh) -> float:
    """4.9-4.16 on the PUMA's A matrices: dT_k/dtheta_i = T_(i-1) Q_i A_i .. A_k (4.16 with U = A_i .. A_k),
    against a central difference of T_k, at a random configuration; the largest error."""
    rng = np.random.default_rng(_RNG_SEED)
    mats = a_matrices(dh)
    params = sorted(set().union(*(m.free_symbols for m in mats)) - set(Q), key=str)   # link lengths: any values
    values = {p: float(rng.uniform(0.05, 0.3)) for p in params}
    amats = [sp.lambdify([Q[:6]], m.subs(values), "numpy") for m in mats]
    q = rng.uniform(-1.5, 1.5, size=6)
    h = 1e-6

    def chain(qq, upto):
        out = np.eye(4)
        for m in amats[:upto]:
            out = out @ np.asarray(m(qq), dtype=float)
        return out

    worst = 0.0
    qm = _q_matrix(False)
    for k in range(1, 7):
        for i in range(1, k + 1):
            qp, qn = q.copy(), q.copy()
            qp[i - 1] += h
            qn[i - 1] -= h
            numeric = (chain(qp, k) - chain(qn, k)) / (2 * h)
            u = np.eye(4)
            for m in amats[i - 1:k]:
                u = u @ np.asarray(m(q), dtype=float)
            worst = max(worst, float(np.abs(chain(q, i - 1) @ qm @ u - numeric).max()))
    return worst


def gravity_work() -> dict[str, sp.Expr]:
    """4.44-4.47 over the two 90 degree segments, with tau(phi) = -m g r cos(phi) the loading gravity
    puts on the joint (the text's tau0 and tau1) and W_g the work done against it (the text's words:
    4.48's W_1 = W_f1 + W_g1 is what the motor does), W_g = -integral of tau."""
    m, g, r, phi, p0 = sp.symbols("m g r phi phi0", real=True)
    tau = -m * g * r * sp.cos(phi)
    wg1 = -sp.integrate(tau, (phi, p0, p0 + sp.pi / 2))
    wg2 = -sp.integrate(tau, (phi, p0 + sp.pi / 2, p0 + sp.pi))
    tau0, tau1 = tau.subs(phi, p0), tau.subs(phi, p0 + sp.pi / 2)
    tidy = lambda e: sp.factor(sp.expand(sp.expand_trig(sp.simplify(e))))     # noqa: E731
    return {"Wg1": tidy(wg1), "Wg2": tidy(wg2), "Wg": sp.simplify(wg1 + wg2),
            "Wg1-Wg2": sp.simplify(wg1 - wg2),
            "tau0/(Wg1-Wg2)": sp.simplify(tau0 / (wg1 - wg2)), "tau1/(Wg1+Wg2)": sp.simplify(tau1 / (wg1 + wg2))}


def check_sensitivity_algebra() -> bool:
    """4.39-4.43: subtracting the no-mass runs and the two directions leaves 2 W_mass plus the change of
    joint friction (dW = W - W'), the pulley friction equal both ways."""
    wfp, wfm, wfpp, wj, wm, dp, dm = sp.symbols("Wfp Wfm Wpulley Wjoint Wmass dWp dWm", real=True)
    w_plus, w_minus = (wfp + dp) + wfpp + wj + wm, (wfm + dm) + wfpp - wj - wm     # 4.39, 4.40 (W_f = W'_f + dW)
    w1_plus, w1_minus = wfp + wj, wfm - wj                                          # 4.41, 4.42
    return sp.expand(w_plus - w1_plus - w_minus + w1_minus - ((dp - dm) + 2 * wm)) == 0


def check_friction_repeat() -> bool:
    """4.48-4.51: with W'_g = 0 (axis along g) and equal friction changes, W'2 - W2 - W'1 + W1 = Wg1 - Wg2."""
    wf1, wf2, wg1, wg2, d = sp.symbols("Wf1 Wf2 Wg1 Wg2 dW", real=True)
    w1, w2 = wf1 + wg1, wf2 + wg2                       # 4.48
    w1p, w2p = wf1 + d, wf2 + d                          # 4.49 with W'_f = W_f + dW, W'_g = 0
    return sp.expand(w2p - w2 - w1p + w1 - (wg1 - wg2)) == 0


def two_link_pose() -> list[tuple[int, int]]:
    """4.54-4.55: the poses (multiples of 90 deg) of a planar two-link arm with unit links where the
    end-frame forces give tau1 = fx + fy, tau2 = fy; returned as (theta1, theta2) in degrees."""
    t1, t2 = sp.symbols("t1 t2", real=True)
    x = sp.cos(t1) + sp.cos(t1 + t2)
    y = sp.sin(t1) + sp.sin(t1 + t2)
    jac = sp.Matrix([x, y]).jacobian([t1, t2])
    rot = sp.Matrix([[sp.cos(t1 + t2), -sp.sin(t1 + t2)], [sp.sin(t1 + t2), sp.cos(t1 + t2)]])
    jt_end = (jac.T * rot)                               # torques from end-frame forces
    found = []
    for a in range(-180, 180, 90):
        for b in range(-180, 180, 90):
            val = jt_end.subs({t1: sp.rad(a), t2: sp.rad(b)})
            if val == sp.Matrix([[1, 1], [0, 1]]):
                found.append((a, b))
    return found


def force_limit_example() -> dict[str, sp.Expr]:
    """4.53 on 4.55 under both readings of the limit (f_x = F_l, f_y = F_l): its torque t_l = J^T q_l and
    what a force f in x alone and in y alone does to the projection t_a^T t_l / ||t_l||^2."""
    fl, f = sp.symbols("F_l f", positive=True)
    jt = sp.Matrix([[1, 1], [0, 1]])
    out: dict[str, sp.Expr] = {}
    for axis, q_l in (("x", sp.Matrix([fl, 0])), ("y", sp.Matrix([0, fl]))):
        t_l = jt * q_l
        out[f"t_l, limit on f{axis}"] = t_l
        for name, q in (("x", sp.Matrix([f, 0])), ("y", sp.Matrix([0, f]))):
            out[f"{name} alone, limit on f{axis}"] = sp.simplify(((jt * q).T * t_l)[0] / (t_l.T * t_l)[0])
    return out


def check_condition_bound(trials: int = 200) -> bool:
    """4.57: ||dq||/||q|| <= cond(J^T) ||dt||/||t|| for q = J^-T t, at random J, t, dt."""
    rng = np.random.default_rng(_RNG_SEED)
    for _ in range(trials):
        j = rng.normal(size=(6, 6))
        t, dt = rng.normal(size=6), 1e-3 * rng.normal(size=6)
        jt_inv = np.linalg.inv(j.T)
        q, dq = jt_inv @ t, jt_inv @ dt
        lhs = np.linalg.norm(dq) / np.linalg.norm(q)
        if lhs > np.linalg.cond(j.T) * np.linalg.norm(dt) / np.linalg.norm(t) * (1 + 1e-12):
            return False
    return True


def rows(derivations) -> list:
    from derive.compare import Row

    puma = derivations["puma260"].spec.dh
    out: list[Row] = []
    add = lambda *a: out.append(Row(*a))    # noqa: E731
    # --- chapter 1 ---------------------------------------------------------------------------
    add("1.1", "p and R = (n o a)", "as printed", "definition", "names the columns of a transform")
    e = check_homogeneous()
    add("1.2-1.3", "O r = R A r + p as a 4x4 product", "as printed", "derived" if e < 1e-12 else "differs",
        f"(r, 1) mapped by the 4x4 equals R r + p at a random rigid transform (error < 1e-12: {e < 1e-12}); "
        f"rccl.transform.noap builds it ({AUDIT_TEST}::test_noap_and_homogeneous_product_1_3)")
    e = check_similarity()
    add("1.4-1.5", "X A = X^-1 A X; X (X A) = A X", "as printed", "derived" if e < 1e-12 else "differs",
        f"identity checked at random rigid transforms (error < 1e-12: {e < 1e-12})")
    add("1.6", "dc = (dx, dy, dz, dw, dp, dphi)", "as printed", "definition",
        "the order of the differential vector; rccl.transform.delta_vector uses it")
    add("1.7", "dC = C Delta", "as printed", "definition", "defines Delta (change observed in the moved frame)")
    e_print, e_derived = check_delta()
    add("1.8", "Delta from dc", "[[0, -dphi, dp, dx], [dphi, 0, dw, dy], [-dp, dw, 0, dz], 0]", "OCR",
        f"C^-1 dC of a small motion Trans(d) Rot(x, dw) Rot(y, dp) Rot(z, dphi) gives the skew form: the print "
        f"misses the minus of row 2, column 3 (print off by {e_print:.1f}, derived off by < 1e-6: {e_derived < 1e-6}); "
        f"rccl.transform.delta_matrix is the derived form ({AUDIT_TEST}::test_delta_matrix_is_the_derived_1_8)",
        "[[0, -dphi, dp, dx], [dphi, 0, -dw, dy], [-dp, dw, 0, dz], [0, 0, 0, 0]]")
    e = check_similarity()
    add("1.9-1.12", "X dC = X^-1 dC X, ..., X Delta = X^-1 Delta X", "as printed",
        "derived" if e < 1e-12 else "differs",
        "1.9 is 1.4 applied to dC; X^-1 (C Delta) X = (X^-1 C X)(X^-1 Delta X) checked at random transforms "
        f"(error < 1e-12: {e < 1e-12}); 1.12 with 1.6 gives D (1.13, first section)")
    ok = check_virtual_work()
    add("1.14-1.19", "equal virtual work: q1 = J_f^T q2", "as printed", "derived" if ok else "differs",
        "SymPy: for p2 = f(p1) = (r cos phi, r sin phi, z + r^2 phi), q1 = J_f^T q2 gives q1^T dp1 = q2^T J_f dp1 "
        "identically (1.15-1.18)")
    add("1.20", "q = (fx, fy, fz, rx, ry, rz)", "as printed", "definition", "the order of the force vector")
    add("1.21", "X q = D^-1T O q", "as printed", "derived",
        "1.19 with J_f = D_{O,X}; F = D^-T is the 1.22-1.23 row of the first section; rccl.transform.force_map "
        f"({AUDIT_TEST}::test_force_map_is_d_inverse_transpose_1_21)")
    # --- chapter 3 ---------------------------------------------------------------------------
    ratio, res = check_error_expansion()
    add("3.83-3.84", "T6 = prod(A_i + dA_i) = prod A_i + M e", "as printed",
        "derived" if 50 < ratio < 200 else "differs",
        f"the remainder after the first-order terms shrinks as eps^2 (residual ratio {ratio:.0f} for eps 1e-3 vs "
        "1e-4), so to first order T6 = prod A + sum_i A_1..dA_i..A_6, linear in the error parameters (M e); "
        "rcci.calib.kinematics builds M = dT6/de by automatic differentiation and fits e "
        "(tests/test_calib_kinematics.py::test_recovers_identifiable_errors_and_names_the_parallel_axis_pair)")
    # --- chapter 4 ---------------------------------------------------------------------------
    add("4.1-4.3", "tau = k phi i_a; tau_load + tau_friction = sigma i_a", "as printed", "definition",
        "the DC motor model; sigma is the torque sensitivity (Table 4.1): rci.conversions (adc_to_motor_torques) "
        "and the calib sensitivity fit use it")
    add("4.4-4.5", "W = integral i_a dtheta_s / sigma, summed per sample", "W = int i_a dtheta_s / sigma", "erratum",
        "with torque = sigma i_a (4.3) the work is sigma times the integral, not divided by it (a unit check: "
        "N m/A times A rad is J); "
        "rcci.calib.work.window_work integrates torque over angle (trapezoid), verified in tests/test_calib_fits.py::test_window_work_of_linear_torque_is_exact_off_sample",
        "W = sigma int i_a dtheta_s")
    add("4.6", "dynamics: D thdd + c + t_g + f + t_a = t_j", "D(theta) thd + ...", "OCR",
        "the inertia term multiplies the acceleration (thdd), as 'acceleration' in the text says; derived in full "
        "by derive/dynamics.py: each arm's generated inertia_matrix (D), coriolis (c), coriolis_matrix and "
        "inverse_dynamics (D thdd + c + t_g) equal Pinocchio's crba, rnea and computeCoriolisMatrix "
        "(tests/test_dynamics.py); f (4.27) and t_a stay separate terms; simula's world side integrates it with "
        "Pinocchio", "D(theta) thdd + c + t_g + f + t_a = t_j")
    add("4.7", "static: t_g + f + t_a = t_j", "as printed", "definition",
        "the static force control model (D and c dropped); rci.conversions.net_torques solves it for t_a (4.37); "
        "its t_g is inverse_dynamics(q, 0, 0), equal to the gravity kernels of 4.20/4.24 "
        "(tests/test_dynamics.py::test_gravity_is_the_static_case)")
    add("4.8", "tau_gi = sum_k -m_k g^T dT_k/dtheta_i r_k", "as printed", "derived",
        "the gradient of the links' potential energy; with 4.16 (checked below) it becomes 4.20, which equals "
        "Pinocchio's generalised gravity for random masses (first section, reports/crosscheck.md)")
    add("4.9", "T_k = A_1 .. A_k", "as printed", "definition", "derive.forward.link_to_link builds it")
    e = check_partial_derivative(puma)
    add("4.10-4.12", "dT_k = T_k U^-1 Delta_i U; Delta_i = Q_i dtheta_i", "Delta_i^-1 = Q_i dtheta_i", "OCR",
        "the '-1' is the preceding superscript i-1 (Delta observed in frame i-1), not an inverse; checked with 4.16",
        "^(i-1)Delta_i = Q_i dtheta_i")
    ok = check_q_matrices()
    add("4.13-4.14", "Q_i rotary / prismatic", "as printed", "derived" if ok else "differs",
        "1.8 for a unit rotation about z, and a unit translation along z, gives exactly these")
    add("4.15-4.17", "dT_k/dtheta_i = T_(i-1) Q_i A_i .. A_k", "T_k U_k^-1 Q_i U_k", "derived" if e < 1e-6 else "differs",
        f"PUMA A matrices at a random configuration, all 21 (i, k): the formula against a central difference of "
        f"T_k (error < 1e-6: {e < 1e-6}); U_k in 4.11 is A_i .. A_k (the print's A_i .. A_N is its k = N case)")
    add("4.18-4.19", "tau_gi = -g^T T_(i-1) Q_i sum_k m_k U_k r_k; -g^T T Q = -(g.n, g.o, g.a, g.p) Q",
        "T_{t-1} Q_t", "OCR", "'t' is the OCR of subscript i; the algebra is 4.17 with the common factor taken out; "
        "the sum runs from k = i (4.17), the print's k = 1 of 4.18 is a misprint of the limit",
        "-g^T T_(i-1) Q_i sum_{k=i}^N m_k U_k r_k")
    add("4.27", "friction: F_c+ + F_v+ thd (thd > 0), -F_c- + F_v- thd (thd < 0), -F_s- <= f <= F_s+ (rest)",
        "-F_s+ <= f <= F_s+", "OCR",
        "the text defines F_s+ and F_s- for the two directions; the lower bound at rest is -F_s-. "
        "rci.conversions.friction_torque implements the moving branches "
        f"({AUDIT_TEST}::test_friction_model_4_27)", "-F_s- <= f <= F_s+")
    add("4.28, 4.30", "Theta_s = G Theta; e = R Theta", "as printed", "implemented",
        "rci.conversions joint_to_motor_angles, angles_to_counts "
        f"({AUDIT_TEST}::test_drive_train_conversions_4_28_to_4_38)")
    add("4.29", "t_j = G^T t_s", "as printed", "derived",
        "1.19 with J_f = G; rci.conversions.motor_to_joint_torques; same work t_j.dTheta = t_s.dTheta_s "
        f"({AUDIT_TEST}::test_drive_train_conversions_4_28_to_4_38)")
    add("4.31-4.33", "t_s = K_adc v_adc; k_adc = V_g sigma / R; v_dac = K_dac t_s", "as printed", "implemented",
        "rci.conversions (adc_to_motor_torques, motor_torques_to_dac) from the model's constants "
        f"({AUDIT_TEST}::test_drive_train_conversions_4_28_to_4_38)")
    add("4.34", "k_dac from k_adc", "k_dac = kappa k_adc", "erratum",
        "units: K_adc is N m per ADC count (4.31) and K_dac DAC counts per N m (4.33), so the proportionality "
        "that keeps kappa dimensionless (the DAC/ADC count ratio of Appendix D) is k_dac = kappa / k_adc; "
        "rci.conversions uses that (models/puma260.toml, conversion.kappa) "
        f"({AUDIT_TEST}::test_drive_train_conversions_4_28_to_4_38)", "k_dac = kappa / k_adc")
    add("4.35", "v_dac = K_dac G^-T t_j", "K_dac G^-1T e_p", "OCR",
        "'e_p' is t_j (4.29 inverted, then 4.33); rci.conversions.joint_torques_to_dac "
        f"({AUDIT_TEST}::test_drive_train_conversions_4_28_to_4_38)", "v_dac = K_dac G^-T t_j")
    add("4.36-4.38", "t_j = G^T K_adc v_adc; t_a = ... - t_g; v_dac = K_dac G^-T (t_a + t_g) + f_dac",
        "f_dac(Theta)", "OCR", "friction depends on the joint rates (thd), as in 4.37, not on Theta; "
        "rci.conversions adc_to_joint_torques, net_torques, dac_for_net_torques "
        f"({AUDIT_TEST}::test_drive_train_conversions_4_28_to_4_38)", "f_dac(thd)")
    ok = check_sensitivity_algebra()
    add("4.39-4.43", "W+ - W'+ - W- + W'- = (dWf+ - dWf-) + 2 W_mass", "as printed", "derived" if ok else "differs",
        "SymPy: from 4.39-4.42 with equal pulley friction both ways and dW_f = W_f - W'_f; rcci.calib.sensitivity "
        "implements it (tests/test_calib_fits.py::test_sensitivity_recovers_table_4_1_through_the_coupled_wrist)")
    gw = gravity_work()
    m, g, r, p0 = sp.symbols("m g r phi0", real=True)
    reading = ("W_g is the work done against gravity, W_g = -integral of tau with tau = -m g r cos(phi) the "
               "loading (the text's tau0, tau1 and its words; Table 4.8's header (W_g2 - W_g1)/2 = tau0 agrees)")
    add("4.44", "W_g1, W_g2 over the two 90 deg segments", "Wg1 = -mgr(cos - sin), Wg2 = -mgr(cos + sin)", "OCR",
        f"{reading}: Wg2 as printed, Wg1 lost its sign. The other reading (W_g = +integral of tau) keeps Wg1 but "
        "needs four sign errors (Wg2, 4.45, 4.46, tau0) besides 4.47's fraction, so it is not taken",
        f"Wg1 = {gw['Wg1']}, Wg2 = {gw['Wg2']}")
    add("4.45-4.46", "W_g; W_g1 - W_g2", "as printed", "derived",
        f"{reading}: Wg = {gw['Wg']}, Wg1 - Wg2 = {gw['Wg1-Wg2']}, both as printed")
    add("4.47", "tau0, tau1 from the segment works", "tau0 = -2(Wg1 - Wg2), tau1 = 2(Wg1 + Wg2)", "OCR",
        f"tau0 / (Wg1 - Wg2) = {gw['tau0/(Wg1-Wg2)']}, tau1 / (Wg1 + Wg2) = {gw['tau1/(Wg1+Wg2)']}: a '1/2' read "
        "as '2' in both, and tau1's sign lost; calib's fit does not depend on the reading: for the motor's "
        "torque a cos u + b sin u over a + pass its segment works are W1 = a + b, W2 = b - a, so it takes "
        "tau0 = (W1 - W2)/2 (rcci.calib.gravity; "
        "tests/test_calib_fits.py::test_gravity_fit_recovers_table_4_9_and_the_repeat_matters)",
        "tau0 = -(Wg1 - Wg2)/2, tau1 = -(Wg1 + Wg2)/2")
    ok = check_friction_repeat()
    add("4.48-4.51", "W1 - W2 = Wg1 - Wg2 (equal friction); the repeat: W'2 - W2 - W'1 + W1 = Wg1 - Wg2",
        "as printed", "derived" if ok else "differs",
        "SymPy from 4.48-4.50 with W'_g = 0 (axis along g) and equal dW_f; rcci.calib.gravity.gravity_rows applies "
        "the repeat (tests/test_calib_fits.py::test_gravity_fit_recovers_table_4_9_and_the_repeat_matters)")
    add("4.52", "t_a = J^T q", "as printed", "implemented",
        "3.2 again; rccl.adaptive.comply (the force-servoed joints) uses it; the kernels torque_from_force match "
        "Pinocchio (reports/crosscheck.md)")
    fl = force_limit_example()
    add("4.53", "limit exceeded if the normalised projection of t_a on t_l exceeds one",
        "t_a^T t_l / ||t_a||^2 > 1; t_l = (F_l, 0)", "OCR",
        f"the projection normalised by t_l is t_a^T t_l / ||t_l||^2 (the print's ||t_a|| never exceeds one for "
        f"t_a = 2 t_l). The limit read as f_x = F_l (the text prints f_y): 4.55 gives t_l = J^T (F_l, 0) = "
        f"{tuple(fl['t_l, limit on fx'])}, the printed t_l, and a force f in y alone, which the limit ignores, "
        f"projects to {fl['y alone, limit on fx']}, over one once f > F_l: the false alarm the text warns of "
        f"('greater than F_l in the y direction alone'). One symbol changes (f_y for f_x) and the rest stands; read "
        f"as f_y, t_l would be {tuple(fl['t_l, limit on fy'])}, not the printed (F_l, 0), and the false alarm "
        f"would come from x (projection {fl['x alone, limit on fy']}), two changes, so that reading is not taken "
        "(reports/condition.md tabulates both). Not implemented: RCCL uses 4.56, the text's recommendation",
        "t_a^T t_l / ||t_l||^2 > 1, the limit on f_x: t_l = (F_l, 0)")
    poses = two_link_pose()
    add("4.54-4.55", "two-link example: tau1 = fx + fy, tau2 = fy; J^T = [[1, 1], [0, 1]]", "as printed",
        "derived" if poses else "differs",
        f"SymPy: a planar arm with unit links and the forces in the end frame gives this J^T exactly at theta2 = "
        f"{sorted({b for _, b in poses})} deg, any theta1 (searched over multiples of 90 deg; the figure is lost)")
    add("4.56", "q_a = J^-T t_a", "as printed", "implemented",
        "rccl.adaptive.force (frame6_force, tool_force); tests/test_adaptive_pure.py::"
        "test_tool_force_recovers_a_point_force_applied_through_pinocchio")
    ok = check_condition_bound()
    add("4.57", "||dq||/||q|| <= cond(J^T) ||dt||/||t||", "as printed", "derived" if ok else "differs",
        "the standard perturbation bound, checked at 200 random 6x6 J (never exceeded); rccl.adaptive.force "
        "refuses estimates above a condition limit (check_condition, condition_1)")
    # --- chapter 5 ---------------------------------------------------------------------------
    add("5.1-5.3", "Z T6 = B; T6 = Z^-1 B; Z T6 T_L = B", "as printed", "implemented",
        "rccl.position.makeposition / Position.solve (tests/test_rccl_position.py::"
        "test_z_t6_eq_b_gives_t6_equal_zinv_b, ::test_tool_frame_and_t6_on_the_right)")
    add("5.4", "the 5.3.4 example's position", "T_{T_0} = R", "OCR",
        "the program's line 12 is T T6 = R (docs/rccl.md, 'Thesis print vs derivation')", "T T6 = R")
    add("5.5-5.6", "Z T6 = B; R12 Z T6 = B (second robot)", "as printed", "implemented",
        f"makeposition with r12 on the left; solving gives T6 = (R12 Z)^-1 B ({AUDIT_TEST}::test_second_robot_5_6)")
    # --- appendix E --------------------------------------------------------------------------
    add("E.1-E.4", "T6(ta) = Da, T6(tb) = Db; C_drive(ta) = I, C_drive(tb) = Da^-1 Db", "as printed", "implemented",
        f"rccl.trajectory.drive ({AUDIT_TEST}::test_drive_transform_e1_to_e5)")
    add("E.5", "T6(t) = Da C_drive(t)", "as printed", "implemented",
        "rccl.trajectory (Cartesian mode); tests/test_rccl_trajectory.py::"
        "test_cartesian_mode_tool_moves_on_a_straight_line_and_turns_about_a_fixed_axis")
    add("E.6", "T6(t) = Da C_drive(t) C_comply(t)", "as printed", "implemented",
        "rccl.adaptive.comply (tests/test_adaptive_pure.py::test_comply_lock_and_offsets)")
    add("E.7", "Db = D1 D2 .. Dn", "as printed", "implemented",
        "a position equation of several transforms, some functional (rccl.position; tests/test_rccl_position.py::"
        "test_hold_is_frozen_at_snapshot_and_functional_runs)")
    add("E.8", "dtheta = J^-1 dC", "as printed", "implemented",
        "3.1 inverted; rccl.adaptive.functional limits a functional transform's change per sample with it "
        "(tests/test_adaptive_pure.py::test_functional_change_is_limited_through_the_jacobian)")
    return out
