"""The thesis's printed equations, typed in as far as the OCR can be read.

Each entry is what the print says, in a small notation: S1 = sin(theta1), C23 =
cos(theta2 + theta3) (the print's "S_ij = sin theta_i + sin theta_j" is itself OCR damage
for sin(theta_i + theta_j)), nx..pz the entries of T6, a2 d3 d4 the PUMA's lengths, d2
d3 the Microbo's prismatic joint variables. Where a symbol is unreadable the entry says
what was assumed in ``note``. Nothing here feeds the derivation: derive/report.py
compares these strings with the derived expressions and writes the verdicts.
"""
from __future__ import annotations

# -- A matrices (3.4-3.15), rows as printed -------------------------------------------
A_PUMA = {
    "3.4": [["C1", "0", "S1", "0"], ["S1", "0", "-C1", "0"], ["0", "1", "0", "0"]],
    "3.5": [["C2", "-S2", "0", "a2*C2"], ["S2", "C2", "0", "a2*S2"], ["0", "0", "1", "0"]],
    "3.6": [["C3", "0", "-S3", "0"], ["S3", "0", "C3", "0"], ["0", "-1", "0", "d3"]],
    "3.7": [["C4", "0", "S4", "0"], ["S4", "0", "-C4", "0"], ["0", "1", "0", "d4"]],
    "3.8": [["C5", "0", "-S5", "0"], ["S5", "0", "C5", "0"], ["0", "-1", "0", "0"]],
    "3.9": [["C6", "-S6", "0", "0"], ["S6", "C6", "0", "0"], ["0", "0", "1", "0"]],
}
A_MICROBO = {
    "3.10": [["C1", "-S1", "0", "0"], ["S1", "C1", "0", "0"], ["0", "0", "1", "0"]],
    "3.11": [["0", "0", "1", "0"], ["1", "0", "0", "0"], ["0", "1", "0", "d2"]],
    "3.12": [["1", "0", "0", "0"], ["0", "1", "0", "0"], ["0", "0", "1", "d3"]],
    "3.13": [["C4", "0", "S4", "0"], ["S4", "0", "-C4", "0"], ["0", "1", "0", "0"]],
    "3.14": [["C5", "0", "S5", "0"], ["S5", "0", "-C5", "0"], ["0", "1", "0", "0"]],
    "3.15": [["C6", "-S6", "0", "0"], ["S6", "C6", "0", "0"], ["0", "0", "1", "0"]],
}

# -- forward kinematics (3.17, 3.18): entry -> printed expression -----------------------
T6_PUMA = {
    "nx": "C1*(-C23*S4*S6 - C6*S23*S5 + C23*C4*C5*C6) + S1*(-C4*S6 - C5*C6*S4)",
    "ny": "S1*(-C23*S4*S6 - C6*S23*S5 + C23*C4*C5*C6) - C1*(-C4*S6 - C5*C6*S4)",
    "nz": "-S23*S4*S6 + C23*C6*S5 + C4*C5*C6*S23",
    "ox": "C1*((S23*S5 - C23*C4*C5)*S6 - C23*C6*S4) + S1*(C5*S4*S6 - C4*C6)",
    "oy": "S1*((S23*S5 - C23*C4*C5)*S6 - C23*C6*S4) - C1*(C5*S4*S6 - C4*C6)",
    "oz": "-(C23*S5 + C4*C5*S23)*S6 - C6*S23*S4",
    "ax": "-C1*(C23*C4*S5 + C5*S23) + S1*S4*S5",
    "ay": "-S1*(C23*C4*S5 + C5*S23) - C1*S4*S5",
    "az": "C23*C5 - C4*S23*S5",
    "px": "C1*(a2*C2 - d4*S23) + d3*S1",
    "py": "S1*(a2*C2 - d4*S23) - C1*d3",
    "pz": "a2*S2 + C23*d4",
}
T6_MICROBO = {
    "nx": "C1*C6*S5 - S1*(S4*S6 + C4*C5*C6)",
    "ny": "C1*(S4*S6 + C4*C5*C6) - C6*S1*S5",
    "nz": "C5*C6*S4 - C4*S6",
    "ox": "-S1*(C6*S4 - C4*C5*S6) - C1*S5*S6",
    "oy": "C1*(C6*S4 - C4*C5*S6) - S1*S5*S6",
    "oz": "-C5*S4*S6 - C4*C6",
    "ax": "-C4*S1*S5 - C1*C5",
    "ay": "C1*C4*S5 - C5*S1",
    "az": "S4*S5",
    "px": "C1*d3",
    "py": "d3*S1",
    "pz": "d2",
}
T6_ORDER = ["nx", "ny", "nz", "ox", "oy", "oz", "ax", "ay", "az", "px", "py", "pz"]

# -- Paul's-method element equations: (eq, premultiplied, column, lhs rows, rhs rows, note)
FA = {"fa1": "(ay*C1 - ax*S1)", "fa2": "(ay*S1 + ax*C1)", "f61": "(oy*C1 - ox*S1)", "f62": "(oy*S1 + ox*C1)"}
ELEMENT_EQS_PUMA = [
    ("3.23", 1, 4, ["C1*px + S1*py", "pz", "S1*px - C1*py"], ["a2*C2 - d4*S23", "a2*S2 + d4*C23", "d3"], ""),
    ("3.29", 3, 4, ["S23*pz + C23*(S1*py + C1*px) - a2*C3", "C1*py - S1*px + d3",
                    "-S23*(S1*py + C1*px) + C23*pz + a2*S3"], ["0", "0", "d4"],
     "row 1 prints '& a2C3': the '&' is read as the minus it replaced"),
    ("3.31", 3, 3, ["S23*az + C23*(S1*ay + C1*ax)", "C1*ay - S1*ax", "-S23*(S1*ay + C1*ax) + C23*az"],
     ["C4*S5", "S4*S5", "C5"], "'a_v' read as a_y"),
    ("3.33", 4, 3, ["fa1*S4 + C4*(az*S23 + fa2*C23)", "fa2*S23 + az*C23", "(az*S23 + fa2*C23)*S4 - C4*fa1"],
     ["S5", "C5", "0"], "f_a1 = ay C1 - ax S1, f_a2 = ay S1 + ax C1 ('a_v' read as a_y)"),
    ("3.35", 5, 2, ["S5*(-f62*S23 + oz*C23) + C5*(f61*S4 + C4*(oz*S23 + f62*C23))",
                    "C4*f61 - S4*(oz*S23 + f62*C23)",
                    "C5*(-f62*S23 + oz*C23) - S5*(f61*S4 + C4*(oz*S23 + f62*C23))"],
     ["S6", "C6", "0"], "f_61 = oy C1 - ox S1, f_62 = oy S1 + ox C1"),
]
ELEMENT_EQS_MICROBO = [
    ("3.45", 1, 3, ["ay*S1 + ax*C1", "ay*C1 - ax*S1", "az"], ["C5", "C4*S5", "S4*S5"],
     "the text says 'the equation defined by (3.28)', but these are the elements of A1^-1 T6 = U2 "
     "(i = 2); '&' read as minus"),
    ("3.46", 4, 3, ["az*S4 + C4*(ay*C1 - ax*S1)", "ay*S1 + ax*C1", "(ay*C1 - ax*S1)*S4 - az*C4"],
     ["S5", "C5", "0"], "'&' read as minus"),
    ("3.47", 5, 2, ["(ay*S1 + C1*ax)*S5 + C5*(az*S4 + C4*(C1*ay - ax*S1))", "(C1*ay - ax*S1)*S4 - C4*az",
                    "(az*S4 + C4*(C1*ay - ax*S1))*S5 - C5*(ay*S1 + C1*ax)"], ["S6", "C6", "0"],
     "printed with the approach vector a; the second column of the equation holds o"),
]

# -- Jacobians ---------------------------------------------------------------------------
J4R_PUMA = [  # 3.67, columns (dth1, dth2, dth2 + dth3, dth4, dth5, dth6)
    ["(C2*a2 - S23*d4)*S4 + C23*C4*d3", "a2*C4*S3", "C4*d4", "0", "0", "0"],
    ["d3*S23", "a2*C3", "0", "0", "0", "0"],
    ["C23*d3*S4 + C4*(C2*a2 - S23*d4)", "a2*S3*S4 - d4*S4", "0", "0", "0", "0"],
    ["C4*S23", "0", "S4", "0", "0", "S5"],
    ["C23", "0", "0", "1", "0", "C5"],
    ["S23*S4", "0", "C4", "0", "1", "0"],
]
J4R_PUMA_NOTE = ("the print's rows 1 and 3 put d4 in column 3 of row 1 only and a2 S3 S4 - d4 S4 "
                 "in column 2 of row 3: a column of row 3 has slipped")
_h = "(C2*a2 - S23*d4)"
_k = f"(C3*d4*{_h})"
_J = {
    "J41": "(C23*C3*d4*S4*S5 - C2*C5*d3*S4**2 + a2*C2*C3*C4*C5*S4)",
    "J43": "(C23*C3*C4*d4*S5 - a2*C2*C3*C5*S4**2 - C2*C4*C5*d3*S4 + C3*C5*d4*S23)",
    "J51": "(C2*C4*d3*S4 + C3*d4*S23 - a2*C2*C3*C4**2)",
    "J53": "(a2*C2*C3*C4*S4 + C2*C4**2*d3)",
    "J61": "(C2*d3*S4**2 - a2*C2*C3*C4*S4)",
    "J63": "(a2*C2*C3*S4**2 + C2*C4*d3*S4 - C3*d4*S23)",
}
J4R_INV_PUMA = [  # 3.68
    [f"S4/{_h}", "0", f"C4/{_h}", "0", "0", "0"],
    [f"d3*S23*S4/(a2*C3*{_h})", "1/(a2*C3)", f"C4*d3*S23/(a2*C3*{_h})", "0", "0", "0"],
    [f"(C2*d3*S4 - C3*C4*{_h})/{_k}", "S3/(C3*d4)", f"(C3*{_h}*S4 + C2*C4*d3)/{_k}", "0", "0", "0"],
    [f"{_J['J41']}/({_k}*S5)", "C5*S3*S4/(C3*d4*S5)", f"{_J['J43']}/({_k}*S5)", "C5/S5", "1", "0"],
    [f"{_J['J51']}/{_k}", "C4*S3/(C3*d4)", f"{_J['J53']}/{_k}", "0", "0", "1"],
    [f"{_J['J61']}/({_k}*S5)", "S3*S4/(C3*d4*S5)", f"{_J['J63']}/({_k}*S5)", "1/S5", "0", "0"],
]
J4R_INV_NOTE = "J51 prints a trailing d3 after a2 C2 C3 C4^2, read as OCR noise"
J4_MICROBO = [  # 3.69
    ["C4*d3", "S4", "0", "0", "0", "0"],
    ["0", "0", "1", "0", "0", "0"],
    ["d3*S4", "-C4", "0", "0", "0", "0"],
    ["S4", "0", "0", "0", "0", "S5"],
    ["0", "0", "0", "1", "0", "-C5"],
    ["C4", "0", "0", "0", "1", "0"],
]
J4_INV_MICROBO = [  # 3.70
    ["C4/d3", "0", "S4/d3", "0", "0", "0"],
    ["S4", "0", "-C4", "0", "0", "0"],
    ["0", "1", "0", "0", "0", "0"],
    ["-C4*C5*S4/(d3*S5)", "0", "C5*S4**2/(d3*S5)", "C5/S5", "-1", "0"],
    ["C4**2/d3", "0", "C4*S4/d3", "0", "0", "1"],
    ["-C4*S4/(d3*S5)", "0", "-S4**2/(d3*S5)", "1/S5", "0", "0"],
]
B_PUMA = [["C5*C6", "S5*C6", "-S6"], ["-C5*S6", "-S5*S6", "-C6"], ["-S5", "C5", "0"]]  # 3.81
B_MICROBO = [["C5*C6", "S5*C6", "S6"], ["-C5*S6", "-S5*S6", "C6"], ["S5", "-C5", "0"]]  # 3.82

# -- the four computations (3.71-3.78) as printed, as ordered assignments -----------------
# dc = (dx, dy, dz, dpsi, drho, dphi) = (dx, dy, dz, delta_x, delta_y, delta_z);
# forces (fx, fy, fz, tx, ty, tz); joint torques t1..t6; joint differentials dth1..dth6
COMP_PUMA = {
    "3.71": ("forward", [
        ("h", "C2*a2 - S23*d4"),
        ("kc", "C23*d3*dth1 + a2*S3*dth2 - d4*(dth2 + dth3)"),
        ("out1", "h*S4*dth1 + C4*kc"),
        ("out2", "-d3*S23*dth1 + a2*C23*dth2"),
        ("out3", "-C4*h*dth1 + S4*kc"),
        ("out4", "C4*S23*dth1 - S4*(dth2 + dth3) - S5*dth6"),
        ("out5", "C23*dth1 + dth4 + C5*dth6"),
        ("out6", "S23*S4*dth1 + C4*(dth2 + dth3) + dth5"),
    ], "row 4 prints 'dx' for the rotation d-psi (OCR)"),
    "3.72": ("torque", [
        ("h", "C2*a2 - S23*d4"),
        ("kt", "C4*fx + S4*fz"),
        ("out3", "-d4*kt - S4*tx + C4*tz"),
        ("out1", "h*(S4*fx - C4*fz) + C23*(d3*kt + ty) + S23*(C4*tx - d3*fy + S4*tz)"),
        ("out2", "out3 + a2*(S3*kt + C3*fy)"),
        ("out4", "ty"),
        ("out5", "tz"),
        ("out6", "-tx*S5 + C5*ty"),
    ], "the moments print as tau_x, tau_y, tau_z"),
    "3.73": ("joint", [
        ("h", "C2*a2 - S23*d4"),
        ("out1", "(dx*S4 - C4*dz)/h"),
        ("out2", "(dy + out1*d3*S23)/(a2*C3)"),
        ("dth23", "(-S4*dz - C4*dx + a2*out2*S3 + out1*C23*d3)/d4"),
        ("out3", "dth23 - out2"),
        ("out6", "(-dpsi - dth23*S4 + out1*C4*S23)/S5"),
        ("out4", "drho - out6*C5 - out1*C23"),
        ("out5", "dphi - out1*S23*S4 - dth23*C4"),
    ], "the print lists dth4 before dth6 although dth4 uses dth6"),
    "3.74": ("force", [
        ("h", "C2*a2 - S23*d4"),
        ("tx", "-(t6 - C5*t4)/S5"),
        ("kf2", "(-C4*t5 + t3 + tx*S4)/d4"),
        ("out2", "(t2 - t3 + a2*S3*kf2)/(a2*C3)"),
        ("kf1", "-(S23*S4*t5 + C23*t4 - t1 - C23*d3*kf2 + (C4*tx - d3*out2)*S23)/h"),
        ("out1", "S4*kf1 - C4*kf2"),
        ("out3", "-S4*kf2 - C4*kf1"),
        ("out4", "tx"),
        ("out5", "t4"),
        ("out6", "t5"),
    ], "the first line prints 'fz' for fx and the fourth 'tau_2' for tau_x (OCR); fy uses kf2 and kf1 uses fy and tau_x, so they are evaluated in that order"),
}
COMP_MICROBO = {
    "3.75": ("forward", [
        ("out1", "S4*dth2 + C4*d3*dth1"),
        ("out2", "dth3"),
        ("out3", "d3*S4*dth1 - C4*dth2"),
        ("out4", "S5*dth6 + S4*dth1"),
        ("out5", "dth4 - C5*dth6"),
        ("out6", "dth5 - C4*dth1"),
    ], "dd2, dd3 (prismatic) written dth2, dth3 here"),
    "3.76": ("torque", [
        ("out1", "(tx + d3*fz)*S4 + C4*(d3*fz - tz)"),
        ("out2", "S4*fx - C4*fz"),
        ("out3", "fy"),
        ("out4", "ty"),
        ("out5", "tz"),
        ("out6", "tz*S5 - C5*ty"),
    ], ""),
    "3.77": ("joint", [
        ("out1", "(dx*S4 + C4*dx)/d3"),
        ("out2", "dx*S4 - C4*dz"),
        ("out3", "dy"),
        ("out4", "(drho*S5 - C5*out1*S4 + C5*dpsi)/S5"),
        ("out5", "(-out2*S4 + d3*dphi + dx)/d3"),
        ("out6", "(dpsi - out1*S4)/S5"),
    ], "dth5 line is garbled in the print ('-d theta_2 S4 + d3 dphi + dx' over d3), typed as read"),
    "3.78": ("force", [
        ("tx", "(t6 + C5*t4)/S5"),
        ("kf", "(C4*t5 + t1 - tx*S4)/d3"),
        ("out1", "S4*t2 + C4*kf"),
        ("out2", "t3"),
        ("out3", "S4*kf - C4*t2"),
        ("out4", "tx"),
        ("out5", "t4"),
        ("out6", "t5"),
    ], "f2, f3 (prismatic joint forces) written t2, t3"),
}

#: classification of computation lines that differ by more than signs: eq -> {line: (status, note)}
COMP_FIXES = {
    "3.71": {2: ("OCR", "C23 printed for C3 in the dth2 term (3.67 row 2 prints a2 C3)")},
    "3.76": {1: ("OCR", "fz printed for fx in the C4 term: C4 (d3 fx - tz)"),
             6: ("OCR", "tau_z printed for tau_x: S5 tau_x - C5 tau_y")},
    "3.77": {1: ("OCR", "dx printed twice: (C4 dx + S4 dz) / d3")},
}

# -- gravity (4.24) ----------------------------------------------------------------------
GRAVITY_PUMA = ["0", "(C23*C4*S5 + C5*S23)*c15 + S23*c13 + C2*c12", "(C23*C4*S5 + C5*S23)*c15 + S23*c13",
                "-S23*S4*S5*c15", "(C23*S5 + C4*C5*S23)*c15", "0"]
COEFFS_PUMA = {
    "c12": "g*(m2*x2 + a2*(m6 + m5 + m4 + m3 + m2))",
    "c13": "-g*(m3*x3 + m4*y4 + d4*(m6 + m5 + m4))",
    "c15": "-g*(m6*z6 + m5*z5)",
}
TOOL_PUMA = {"c15": "-g*m_t*d_t", "c13": "-g*m_t*d4", "c12": "g*m_t*a2"}  # 4.26 increments
