"""The C and CasADi back ends on kernels built here (PUMA A-matrix product, a 2-link arm), independent of the derivation."""
from __future__ import annotations

import importlib.util
import math
import re
import shutil
import subprocess
import sys
import sysconfig
import warnings
from pathlib import Path

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest
import sympy as sp

from derive import emit_c, emit_casadi, opcount
from derive.kernel import Arg, Guard, Kernel
from derive.lowering import shared_reciprocal

RUNTIME_DIR = Path(__file__).resolve().parent.parent / "rccl" / "kinematics" / "_c"  # kin_prelude.h, kin_runtime.h
A2, D3, D4 = 0.2032, 0.12624, 0.2032  # Table 3.1, metres
ALPHA = np.deg2rad([90, 0, -90, 90, -90, 0])  # signs from the A matrices 3.4-3.9
D = [0, 0, D3, D4, 0, 0]
A = [0, A2, 0, 0, 0, 0]


def _dh(theta, d, a, alpha) -> sp.Matrix:
    ct, st = sp.cos(theta), sp.sin(theta)
    ca_, sa = sp.nsimplify(sp.cos(alpha)), sp.nsimplify(sp.sin(alpha))
    return sp.Matrix([[ct, -st * ca_, st * sa, a * ct], [st, ct * ca_, -ct * sa, a * st], [0, sa, ca_, d], [0, 0, 0, 1]])


def puma_fk_kernel(robot: str = "testarm") -> Kernel:
    q = sp.Matrix(sp.symbols("q1:7", real=True))
    a2, d3, d4 = sp.symbols("a2 d3 d4", positive=True)
    alpha = [sp.pi / 2, 0, -sp.pi / 2, sp.pi / 2, -sp.pi / 2, 0]
    d, a = [0, 0, d3, d4, 0, 0], [0, a2, 0, 0, 0, 0]
    t = sp.eye(4)
    for i in range(6):
        t = t * _dh(q[i], d[i], a[i], alpha[i])
    t = t.applyfunc(sp.expand)
    return Kernel(robot, "fk", "T6 of the PUMA 260 (A1..A6 of 3.4-3.9).", (Arg("q", q),), (Arg("T", t),),
                  params={a2: A2, d3: D3, d4: D4}, source="3.16-3.17")


def two_link_ik_kernel(robot: str = "testarm") -> Kernel:
    x, y = sp.symbols("x y", real=True)
    l1, l2 = sp.symbols("l1 l2", positive=True)
    c2 = (x**2 + y**2 - l1**2 - l2**2) / (2 * l1 * l2)
    s2 = sp.sqrt(1 - c2**2)
    q = sp.Matrix([sp.atan2(y, x) - sp.atan2(l2 * s2, l1 + l2 * c2), sp.atan2(s2, c2)])
    return Kernel(robot, "ik2", "Planar 2-link inverse kinematics, elbow down.", (Arg("p", sp.Matrix([x, y])),),
                  (Arg("q", q),), guards=(Guard("guard_reach", 1 - c2**2, "Unreachable", "out of reach"),),
                  params={l1: 0.3, l2: 0.2})


def scale_kernel(robot: str = "testarm") -> Kernel:
    u = sp.Matrix(sp.symbols("u1:4", real=True))
    k = sp.Symbol("k", real=True)
    return Kernel(robot, "scale", "y = k u and s = u1 + u2.", (Arg("u", u), Arg("k", sp.Matrix([[k]]))),
                  (Arg("y", u * k), Arg("s", sp.Matrix([[u[0] + u[1]]]))))


KERNELS = [puma_fk_kernel(), two_link_ik_kernel(), scale_kernel()]


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """Emit and compile the test kernels into a fresh extension module."""
    if shutil.which("gcc") is None:
        pytest.skip("no C compiler on this machine")
    d = tmp_path_factory.mktemp("cext")
    path, programs = emit_c.write("testarm", KERNELS, d, command="tests/test_backends_emit.py")
    so = d / ("testarm" + sysconfig.get_config_var("EXT_SUFFIX"))
    cmd = ["gcc", "-O2", "-fno-math-errno", "-shared", "-fPIC", "-Wall", "-Werror", "-Wno-unused-variable",
           "-I", sysconfig.get_paths()["include"], "-I", str(RUNTIME_DIR), str(path), "-o", str(so)]
    r = subprocess.run(cmd, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    spec = importlib.util.spec_from_file_location("testarm", so)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    cas = emit_casadi.write("testarm", KERNELS, d / "casadi", programs)
    return mod, path, programs, cas


def _sympy_eval(kernel: Kernel, *inputs: np.ndarray) -> list[np.ndarray]:
    syms = [s for a in kernel.inputs for s in a.value]
    vals = [float(v) for x in inputs for v in np.ravel(x)]
    subs = dict(zip(syms, vals)) | {k: v for k, v in kernel.params.items()}
    return [np.array(a.value.xreplace(subs).evalf(), dtype=float).reshape(a.shape) for a in kernel.outputs]


def _pinocchio_puma() -> tuple[pin.Model, int]:
    """A Pinocchio model built directly from the DH rows (Rz(q) Tz(d) Tx(a) Rx(alpha))."""
    model = pin.Model()
    parent, placement = 0, pin.SE3.Identity()
    for i in range(6):
        parent = model.addJoint(parent, pin.JointModelRZ(), placement, f"j{i + 1}")
        rot_x = pin.utils.rotate("x", ALPHA[i])
        placement = pin.SE3(np.eye(3), np.array([0, 0, D[i]])) * pin.SE3(rot_x, np.array([A[i], 0, 0]))
    fid = model.addFrame(pin.Frame("link6", parent, 0, placement, pin.FrameType.OP_FRAME))
    return model, fid


def test_c_fk_matches_sympy_and_pinocchio(built):
    mod = built[0]
    model, fid = _pinocchio_puma()
    data = model.createData()
    rng = np.random.default_rng(1)
    for q in rng.uniform(-np.pi, np.pi, (20, 6)):
        (t,) = mod.fk(q)
        pin.framesForwardKinematics(model, data, q)
        np.testing.assert_allclose(t, data.oMf[fid].homogeneous, atol=1e-12)
    q = rng.uniform(-np.pi, np.pi, 6)
    np.testing.assert_allclose(mod.fk(q)[0], _sympy_eval(KERNELS[0], q)[0], atol=1e-12)


def test_batched_equals_single(built):
    mod = built[0]
    rng = np.random.default_rng(2)
    qs = rng.uniform(-np.pi, np.pi, (50, 6))
    (tb,) = mod.fk(qs)
    assert tb.shape == (50, 4, 4)
    for i in (0, 17, 49):
        np.testing.assert_array_equal(tb[i], mod.fk(qs[i])[0])
    ps = rng.uniform(-0.3, 0.3, (30, 2))
    qb, gb = mod.ik2(ps)
    for i in range(30):
        q1, g1 = mod.ik2(ps[i])
        assert isinstance(g1, float) and g1 == gb[i]
        np.testing.assert_array_equal(q1, qb[i])
    assert mod.fk(np.empty((0, 6)))[0].shape == (0, 4, 4)


def test_ik_guard_and_values(built):
    mod = built[0]
    q, g = mod.ik2([0.3, 0.2])
    assert g >= 0
    np.testing.assert_allclose(q, _sympy_eval(KERNELS[1], np.array([0.3, 0.2]))[0], atol=1e-12)
    # forward check: the solution reaches the point
    x = 0.3 * np.cos(q[0]) + 0.2 * np.cos(q[0] + q[1])
    y = 0.3 * np.sin(q[0]) + 0.2 * np.sin(q[0] + q[1])
    np.testing.assert_allclose([x, y], [0.3, 0.2], atol=1e-12)
    _, g_far = mod.ik2([1.0, 0.0])
    assert g_far < 0  # out of reach is flagged by the guard, never silently


def test_broadcast_unbatched_input(built):
    mod = built[0]
    y, s = mod.scale(np.arange(12.0).reshape(4, 3), 2.0)
    np.testing.assert_array_equal(y, 2 * np.arange(12.0).reshape(4, 3))
    np.testing.assert_array_equal(s, [1, 7, 13, 19])
    y1, s1 = mod.scale([1, 2, 3], [[0.5]] if False else 0.5)
    assert s1 == 3.0 and isinstance(s1, float)


@pytest.mark.parametrize("bad, words", [
    (np.zeros(5), ["fk", "'q'", "(5,)", "(6,)"]),
    (np.zeros((3, 5)), ["(3, 5)", "(N, 6)"]),
    (np.zeros((2, 2, 6)), ["(2, 2, 6)"]),
    (np.array([0, 0, np.nan, 0, 0, 0]), ["'q'", "element 2", "NaN"]),
    (np.array([[0.0] * 6, [0, 0, 0, np.inf, 0, 0]]), ["row 1", "element 3", "infinite"]),
])
def test_bad_input_errors(built, bad, words):
    mod = built[0]
    with pytest.raises(ValueError) as e:
        mod.fk(bad)
    for w in words:
        assert w in str(e.value)


def test_mismatched_rows_and_arity(built):
    mod = built[0]
    with pytest.raises(ValueError, match="3 rows, an earlier input has 4"):
        mod.scale(np.ones((4, 3)), np.ones(3))
    with pytest.raises(TypeError, match="takes 2 inputs"):
        mod.scale(np.ones(3))


def test_non_float64_inputs_are_converted(built):
    mod = built[0]
    q = np.arange(6) / 10
    np.testing.assert_allclose(mod.fk(q.astype(np.float32))[0], mod.fk(q)[0], atol=1e-7)
    np.testing.assert_array_equal(mod.fk(list(q))[0], mod.fk(q)[0])
    strided = np.zeros((6, 2))
    strided[:, 0] = q
    np.testing.assert_array_equal(mod.fk(strided[:, 0])[0], mod.fk(q)[0])


def test_casadi_matches_c(built):
    mod, _, _, cas = built
    fk = ca.Function.load(str(cas[0]))
    ik = ca.Function.load(str(cas[1]))
    rng = np.random.default_rng(3)
    for q in rng.uniform(-np.pi, np.pi, (5, 6)):
        np.testing.assert_allclose(np.array(fk(q)), mod.fk(q)[0], atol=1e-12)
    p = np.array([0.1, -0.25])
    q_ca, g_ca = ik(p)
    q_c, g_c = mod.ik2(p)
    np.testing.assert_allclose(np.array(q_ca).ravel(), q_c, atol=1e-12)
    assert abs(float(g_ca) - g_c) < 1e-12
    assert fk.name_in() == ["q"] and ik.name_out() == ["q", "guard_reach"]


def test_emitted_c_has_no_pow_and_no_allocation(built):
    text = built[1].read_text()
    body = "".join(m["body"] for m in opcount._KERNEL.finditer(text))
    assert "pow(" not in body and "malloc" not in text and "alloc(" not in body
    # sin and cos of each angle are computed once
    for j in range(6):
        assert body.count(f"sin(in0[{j}])") <= 1 and body.count(f"cos(in0[{j}])") <= 1


def test_fk_op_count_and_cross_product(built):
    rows = {r["kernel"]: r for r in opcount.count_file(built[1])}
    fk = rows["fk"]
    assert fk["mul_div"] <= 41  # section 6.1: RCCL's forward kinematics, 41 multiplications
    prog = next(p for p, _ in built[2] if p.kernel.name == "fk")
    assert "cross" in prog.variant  # one rotation column rebuilt from the other two (3.3)


def test_guarded_divisions_share_one_reciprocal():
    """derive.lowering.shared_reciprocal through emit_c.best_program: a guarded solve that
    divides by three bounded divisors (polynomials in sines and cosines) divides once and
    gives the same quotients; a divisor that is an input (unbounded) is left alone."""
    q = sp.Matrix(sp.symbols("q1:4", real=True))
    b = sp.Matrix(sp.symbols("b1:4", real=True))
    s1, c2, s3 = sp.sin(q[0]), sp.cos(q[1]), sp.sin(q[2])
    x1 = b[0] / (0.5 * s1 - 0.25)
    x2 = (b[1] - s1 * x1) / c2        # a chain of dependent quotients, as 3.73 is
    x3 = (b[2] + c2 * x2) / s3
    guards = tuple(Guard(f"guard_{i}", sp.Abs(d) - 1e-9, "Singular", "singular")
                   for i, d in enumerate((0.5 * s1 - 0.25, c2, s3)))
    k = Kernel("testarm", "solve3", "a guarded triangular solve", (Arg("q", q), Arg("b", b)),
               (Arg("x", sp.Matrix([x1, x2, x3])),), guards)
    prog, body = emit_c.best_program(k)
    assert opcount.divisions(opcount.without_guards(body)) == 1, body
    assert "shared reciprocal" in prog.variant
    assert opcount.cycles(body) < opcount.cycles(emit_c.kernel_body(emit_c.lower(k, factor="")))
    env = {"sin": math.sin, "cos": math.cos, "fabs": abs}
    for qv, bv in (((0.3, -1.1, 2.0), (1.0, -2.0, 0.5)), ((-2.5, 0.4, -0.7), (0.1, 3.0, -4.0))):
        names = {f"in0[{i}]": v for i, v in enumerate(qv)} | {f"in1[{i}]": v for i, v in enumerate(bv)}
        got = _run_body(body, names, env)
        subs = dict(zip(list(q) + list(b), qv + bv))
        want = [float(e.subs(subs)) for e in (x1, x2, x3)]
        np.testing.assert_allclose([got[f"out0[{i}]"] for i in range(3)], want, rtol=1e-13)
    unbounded = Kernel("testarm", "solve2", "divides by an input", (Arg("q", q), Arg("b", b)),
                       (Arg("x", sp.Matrix([b[0] / q[2], b[1] / s3])),), guards[2:])
    assert shared_reciprocal(emit_c.lower(unbounded, factor="")) is None


def _run_body(body: str, names: dict[str, float], env: dict) -> dict[str, float]:
    """Evaluate the straight-line C statements of a kernel body in Python (assignments of
    arithmetic expressions; in0[1] is read as in0_1)."""
    flat = lambda text: re.sub(r"\b(in\d+|out\d+)\[(\d+)\]", r"\1_\2", text)  # noqa: E731
    values = {flat(k): v for k, v in names.items()}
    for line in body.splitlines():
        line = line.strip()
        if line and not line.startswith("/*"):
            lhs, rhs = flat(line.removeprefix("const double ").rstrip(";")).split(" = ", 1)
            values[lhs] = eval(rhs, dict(env), dict(values))
    return {re.sub(r"^(in\d+|out\d+)_(\d+)$", r"\1[\2]", k): v for k, v in values.items()}


def test_opcount_tokeniser():
    c = opcount.count_ops("    const double t0 = -a*b + 1e-05*c/(d - e);\n    out0[3] = sin(t0) + sqrt(x) - atan2(y, -z);")
    assert c == {"mul_div": 3, "add_sub": 6, "neg": 2, "trig": 2, "sqrt": 1, "other": 0}
    with pytest.raises(ValueError, match="unknown function"):
        opcount.count_ops("t = pow(a, 2);")


def test_c_printer_without_pow():
    x, y = sp.symbols("x y")
    pr = emit_c.CPrinter({})
    assert pr.expr(x**3) == "x*x*x"
    assert pr.expr(1 / x**2) == "1.0/(x*x)"
    assert pr.expr(sp.sqrt(x + y)) == "sqrt(x + y)"
    assert pr.expr(x - 2 * y) == "x - 2.0*y"
    with pytest.raises(ValueError, match="pow"):
        pr.expr(x ** sp.Rational(1, 3))


def test_loader_falls_back_with_one_warning(monkeypatch):
    from rccl.kinematics import backend
    monkeypatch.setattr(backend, "_warned", False)
    monkeypatch.setattr(backend, "_modules", {})
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        assert backend.kernel("no_such_robot", "fk", ((6,),), ((4, 4),)) is None
        assert backend.kernel("no_such_robot_either", "fk", ((6,),), ((4, 4),)) is None
    msgs = [str(x.message) for x in w if issubclass(x.category, RuntimeWarning)]
    assert len(msgs) == 1 and "Python code" in msgs[0]
    monkeypatch.setenv("RCCL_KINEMATICS", "python")
    monkeypatch.setattr(backend, "_modules", {})
    assert backend.c_module("puma260") is None


def test_emission_is_deterministic(built, tmp_path):
    a = built[1]            # the same kernels emitted once already (the fixture)
    b, _ = emit_c.write("testarm", KERNELS, tmp_path / "b", command="tests/test_backends_emit.py")
    assert a.read_text() == b.read_text()
    # the shared runtime is included, not copied into every generated file
    text = a.read_text()
    assert '#include "kin_prelude.h"' in text and '#include "kin_runtime.h"' in text
    assert "static PyObject *call_kernel" not in text and "RCCL_SOURCE_HASH" not in text


def test_finite_by_construction_marks_only_polynomials_in_sines_and_cosines(built):
    programs = built[2]
    flags = {p.kernel.name: emit_c.finite_by_construction(p) for p, _ in programs}
    # T6 is a polynomial in sines and cosines; ik2 has guards and atan2; scale uses its inputs bare
    assert flags == {"fk": True, "ik2": False, "scale": False}
