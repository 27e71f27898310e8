"""The SymPy derivation: A matrices, T6, gravity grouping, D/F maps, the Python emitter."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

from derive import thesis_print as tp
from derive.dh import MICROBO, PUMA260, Q, a_matrices
from derive.emit_python import _function, _lower
from derive.forward import t6
from derive.gravity import gravity_model
from derive.robots import load_spec
from derive.jacobian import d_map, f_map
from derive.kernel import Arg, Guard, Kernel
from derive.compare import equal, namespace, parse, verdict

ROOT = Path(__file__).resolve().parent.parent


def test_a_matrices_are_the_printed_ones():
    for robot, printed in ((PUMA260, tp.A_PUMA), (MICROBO, tp.A_MICROBO)):
        ns = namespace(robot.name)
        for a, rows in zip(a_matrices(robot), printed.values()):
            want = sp.Matrix([[parse(x, ns) for x in row] for row in rows] + [[0, 0, 0, 1]])
            assert sp.simplify(a - want) == sp.zeros(4, 4)


def test_puma_t6_matches_print_3_17():
    ns = namespace("puma260")
    t = t6(PUMA260)
    for key, text in tp.T6_PUMA.items():
        col, row = "noap".index(key[0]), "xyz".index(key[1])
        assert equal(parse(text, ns), t[row, col]), key


def test_microbo_t6_print_lost_one_sign():
    ns = namespace("microbo")
    t = t6(MICROBO)
    verdicts = {key: verdict(parse(text, ns), t["xyz".index(key[1]), "noap".index(key[0])])
                for key, text in tp.T6_MICROBO.items()}
    assert verdicts.pop("ny") == "sign"  # printed - C6 S1 S5, derived + C6 S1 S5
    assert set(verdicts.values()) == {"confirmed"}


def puma_gravity():
    return gravity_model(load_spec("puma260"))


def microbo_gravity():
    return gravity_model(load_spec("microbo"))


def test_puma_gravity_groups_into_4_24():
    gm = puma_gravity()
    ns = {**namespace("puma260"), **{n: s for n, s in zip(gm.coeff_names, gm.coeff_symbols)}}
    tau = gm.regressor * sp.Matrix(gm.coeff_symbols)
    for text, derived in zip(tp.GRAVITY_PUMA, tau):
        assert equal(parse(text, ns), derived)
    # 4.25 and 4.26
    assert equal(tau[1], tau[2] + sp.cos(Q[1]) * gm.coeff_symbols[0])
    assert [str(x) for x in gm.tool_update] == ["a2*g*m_t", "-d4*g*m_t", "-d_t*g*m_t"]


def test_microbo_gravity_uses_prismatic_h():
    gm = microbo_gravity()
    assert gm.coeff_names == ("c12", "c15")
    assert gm.regressor[1, :] == sp.Matrix([[1, 0]])  # joint 2 carries the lift force
    assert gm.regressor[0, :] == sp.zeros(1, 2) and gm.regressor[2, :] == sp.zeros(1, 2)


def test_f_map_is_inverse_transpose_of_d_map():
    rng = np.random.default_rng(3)
    qm, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    x = sp.eye(4)
    x[:3, :3] = sp.Matrix(qm)
    x[:3, 3] = sp.Matrix(rng.normal(size=3))
    err = np.abs(np.array(f_map(x) - d_map(x).inv().T, dtype=float)).max()
    assert err < 1e-12


def _toy_kernel() -> Kernel:
    """A two-link planar arm: position of the tip and a reach guard."""
    q1, q2 = Q[:2]
    l1, l2 = sp.symbols("l1 l2", positive=True)
    x = sp.Symbol("x", real=True)
    tip = sp.Matrix([l1 * sp.cos(q1) + l2 * sp.cos(q1 + q2), l1 * sp.sin(q1) + l2 * sp.sin(q1 + q2)])
    return Kernel("toy", "tip", "tip position", (Arg("q", sp.Matrix([q1, q2])), Arg("x", sp.Matrix([x]))),
                  (Arg("p", tip * x),), (Guard("guard_x", x, "Unreachable", "x < 0"),), {l1: 0.3, l2: 0.2})


def test_python_emitter_scalar_and_batched_agree():
    k = _toy_kernel()
    lowered = _lower(k)
    src = _function(k, lowered, many=False) + "\n\n" + _function(k, lowered, many=True)
    assert src == _function(k, _lower(k), many=False) + "\n\n" + _function(k, _lower(k), many=True)
    assert "c1 = math.cos(q1)" in src and "s12 = math.sin(q1 + q2)" in src  # trig computed once
    env = {"math": math, "numpy": np, "L1": 0.3, "L2": 0.2}
    exec(src, env)  # noqa: S102 - generated code under test
    q = np.array([0.4, -1.1])
    p, g = env["_tip_one"](q, 2.0)
    want = 2.0 * np.array([0.3 * math.cos(0.4) + 0.2 * math.cos(-0.7), 0.3 * math.sin(0.4) + 0.2 * math.sin(-0.7)])
    assert np.abs(p - want).max() < 1e-15 and g == 2.0
    qs = np.array([q, q + 0.3])
    pb, gb = env["_tip_many"](qs, np.array([2.0, -1.0]))
    assert pb.shape == (2, 2) and np.abs(pb[0] - p).max() < 1e-15 and list(gb) == [2.0, -1.0]


def test_thesis_report_names_command_and_errata():
    text = (ROOT / "reports" / "thesis-equations.md").read_text()
    assert "make derive" in text.splitlines()[2]
    for eq in ("| 3.61 |", "| 3.80 |", "| 3.40 |", "| 3.53 |", "| 4.24 | coefficient c13"):
        assert eq in text, eq


@pytest.mark.slow  # derives both arms (~1 min); the C-vs-Python back-end tests check the same on every run
def test_structure_hints_equal_their_outputs():
    """The structure hints the C lowering may use (T6 one run of A matrices at a time, the
    Jacobian computations by substitution in 4J' and, in frame 6, one map of 3.79) have
    the values of the kernels' outputs; a stage may use the stages before it. The dynamics
    kernels are straight-line programs whose outputs are written in their stages: there the
    hint must be the output itself."""
    from derive.derivation import derive_robot
    from derive.kernels import build_kernels

    rng = np.random.default_rng(5)
    for robot in ("microbo", "puma260"):
        kernels = [k for k in build_kernels(derive_robot(robot)) if k.stages]
        assert {k.name for k in kernels} >= {"fk"} | {f"{b}{f}" for f in (4, 6) for b in (
            "cartesian_from_joint", "torque_from_force", "joint_from_cartesian", "force_from_torque")}
        for k in kernels:
            defined = {sym for sym, _ in k.stages}
            if any(out.value.free_symbols & defined for out in k.outputs):
                # a straight-line program (the dynamics, derive.dynamics): its outputs are
                # written in its stages, so the hint is the output itself, not a second form
                assert all(sp.Matrix(h) == sp.Matrix(out.value) for h, out in zip(k.staged, k.outputs)), \
                    f"{robot}.{k.name}: staged outputs differ from the program's outputs"
                continue
            for _ in range(3):
                subs = {s: float(rng.uniform(0.2, 1.2)) for a in k.inputs for s in a.value.free_symbols}
                subs.update({s: float(v) for s, v in k.params.items()})
                stage: dict = {}
                for sym, v in k.stages:  # in order: later stages use earlier ones
                    stage[sym] = float(sp.sympify(v).xreplace({**subs, **stage}))
                for staged, out in zip(k.staged, k.outputs):
                    got = np.array(staged.xreplace({**subs, **stage}), dtype=float)
                    want = np.array(out.value.xreplace(subs), dtype=float)
                    np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-12, err_msg=f"{robot}.{k.name}")


def test_substitution_solves_triangular_systems():
    """derive.jacobian.substitute: definitions in solving order that satisfy m x = rhs."""
    from derive.jacobian import substitute, triangular_pivots

    a, b, c = sp.symbols("a b c", positive=True)
    m = sp.Matrix([[1, c, 3], [0, a, 0], [b, 2, 0]])  # triangular after permuting
    rhs = list(sp.symbols("r0:3"))
    x = list(sp.symbols("x0:3"))
    assert triangular_pivots(m) == [(1, 1), (2, 0), (0, 2)]
    defs = substitute(m, rhs, x)
    sol: dict = {}
    for sym, v in defs:
        assert v.free_symbols & set(x) <= set(sol), "a definition uses an unknown not yet defined"
        sol[sym] = v.xreplace(sol)
    assert sp.simplify(m * sp.Matrix([sol[s] for s in x]) - sp.Matrix(rhs)) == sp.zeros(3, 1)
    assert triangular_pivots(sp.Matrix([[1, 1], [1, 1]])) is None


def test_block_substitution_solves_a_coupled_pair():
    """derive.jacobian.substitute with a 2x2 block (the PUMA 560's wrist-centre Jacobian M:
    its elbow offset a3 couples joints 2 and 3): one reciprocal of the block's determinant,
    the unknowns from the adjugate, and the system solved."""
    from derive.jacobian import block_pivots, substitute, triangular_pivots

    h, a2, a3, d4, s3, c3 = sp.symbols("h a2 a3 d4 s3 c3", positive=True)
    m = sp.Matrix([[c3, a2 * s3, -d4], [h, 0, 0], [-s3, a2 * c3, a3]])  # shape of M (derive/jacobian.py)
    assert triangular_pivots(m) is None
    assert block_pivots(m) == [((1,), (0,)), ((0, 2), (1, 2))]
    assert block_pivots(sp.Matrix([[1, 1], [1, 1]])) is None  # singular: no block to solve
    rhs = list(sp.symbols("r0:3"))
    x = list(sp.symbols("x0:3"))
    defs = substitute(m, rhs, x, sp.numbered_symbols("w"))
    divides = [sym for sym, v in defs if any(p.is_Pow and p.exp < 0 for p in sp.preorder_traversal(v))]
    assert divides == [x[0], next(sp.numbered_symbols("w"))]  # x0 = r1 / h, then one reciprocal
    sol: dict = {}
    for sym, v in defs:
        sol[sym] = v.xreplace(sol)
    assert sp.simplify(m * sp.Matrix([sol[s] for s in x]) - sp.Matrix(rhs)) == sp.zeros(3, 1)
    with pytest.raises(ValueError, match="needs names"):
        substitute(m, rhs, x)


def test_puma_a_y_has_only_negative_terms():
    """Why forward kinematics spends one sign change (reports/opcounts.md, section 6.1 row):
    in the PUMA 260's frames every term of a_y is negative, while a_x and a_z mix signs."""
    t = t6(PUMA260)
    signs = {key: {sp.sign(term.as_coeff_Mul()[0]) for term in sp.Add.make_args(sp.expand(t[row, 2]))}
             for key, row in (("a_x", 0), ("a_y", 1), ("a_z", 2))}
    assert signs == {"a_x": {1, -1}, "a_y": {-1}, "a_z": {1, -1}}
