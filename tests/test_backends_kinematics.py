"""The generated back ends of both arms agree: compiled C, generated Python, CasADi, and Pinocchio on the URDF."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest

import rccl.kinematics
from rccl.kinematics import backend

ROOT = Path(__file__).resolve().parent.parent
ROBOTS = ("puma260", "microbo", "puma560", "stanford")
TOL = 1e-9  # the derivation's cross-check tolerance for kinematic quantities


def _mod(robot):
    return rccl.kinematics.load(robot)


def _c(robot):
    cm = backend.c_module(robot)
    if cm is None:
        pytest.fail(f"the compiled {robot} kernels are missing or stale: run `pip install -e .` after `make derive`")
    return cm


def _casadi(robot, name):
    return ca.Function.load(str(ROOT / "rccl" / "kinematics" / "casadi" / robot / f"{name}.casadi"))


def _qs(mod, n, seed):
    rng = np.random.default_rng(seed)
    lo, hi = np.asarray(mod.LOWER), np.asarray(mod.UPPER)
    return rng.uniform(lo, hi, size=(n, 6))


def _inputs(mod, name, qs, rng):
    """Batched inputs for a kernel, from its signature in the generated module."""
    k = mod._KERNELS[name]
    args = []
    for arg_name, shape in k.inputs:
        if arg_name == "q":
            args.append(qs)
        elif arg_name == "T":
            args.append(_c(mod.ROBOT).fk(qs)[0])
        elif arg_name == "config":
            args.append(rng.choice([-1.0, 1.0], size=(len(qs),) + shape))
        else:
            args.append(rng.uniform(0.1, 1.0, size=(len(qs),) + shape))
    return args


@pytest.mark.parametrize("robot", ROBOTS)
def test_public_module_uses_the_c_kernels(robot):
    mod = _mod(robot)
    cm = _c(robot)
    assert mod._KERNELS["fk"].one is cm.fk
    assert set(cm.kernels()) >= set(mod._KERNELS)


@pytest.mark.parametrize("robot", ROBOTS)
def test_c_equals_generated_python_for_every_kernel(robot):
    mod = _mod(robot)
    cm = _c(robot)
    rng = np.random.default_rng(11)
    qs = _qs(mod, 64, 5)
    for name in mod._KERNELS:
        args = _inputs(mod, name, qs, rng)
        c_out = getattr(cm, name)(*args)
        with np.errstate(all="ignore"):
            py_out = getattr(mod, f"_{name}_many")(*args)
        assert len(c_out) == len(py_out), name
        for a, b in zip(c_out, py_out):
            a, b = np.asarray(a), np.asarray(b)
            ok = np.isfinite(b)
            scale = 1 + np.abs(b[ok])
            assert np.all(np.abs(a[ok] - b[ok]) <= TOL * scale), f"{robot}.{name}"
            assert np.array_equal(np.isfinite(a), ok), f"{robot}.{name}: NaN/inf pattern differs"


@pytest.mark.parametrize("robot", ROBOTS)
def test_single_and_batched_c_calls_agree(robot):
    mod = _mod(robot)
    cm = _c(robot)
    rng = np.random.default_rng(12)
    qs = _qs(mod, 75, 6)  # whole blocks of rows, then a part (kin_runtime.h CHUNK, emit_c.TRIG_BLOCK: 32)
    for name in mod._KERNELS:
        args = _inputs(mod, name, qs, rng)
        batch = getattr(cm, name)(*args)
        for i in (0, 5, 63, 64, 74):
            single = getattr(cm, name)(*[a[i] for a in args])
            for s, b in zip(single, batch):
                np.testing.assert_array_equal(s, b[i], err_msg=f"{robot}.{name}")


_FOUR_LANES = """
import sys, numpy as np
sys.path.insert(0, sys.argv[1])
import tests.test_backends_kinematics as t
for robot in t.ROBOTS:
    mod, cm = t._mod(robot), t._c(robot)
    rng = np.random.default_rng(13)
    qs = t._qs(mod, 75, 7)
    for name in mod._KERNELS:
        for j, a in enumerate(getattr(cm, name)(*t._inputs(mod, name, qs, rng))):
            np.save(f"{sys.argv[2]}/{robot}.{name}.{j}.npy", a)
"""


def test_batches_give_the_same_bits_four_and_eight_rows_at_a_time(tmp_path):
    """RCCL_KINEMATICS_AVX512=0 computes a batch's rows four at a time (AVX2), the default
    eight at a time where the CPU has AVX-512F: every kernel's results are the same bits."""
    env = dict(os.environ, RCCL_KINEMATICS_AVX512="0")
    subprocess.run([sys.executable, "-c", _FOUR_LANES, str(ROOT), str(tmp_path)], env=env, check=True)
    for robot in ROBOTS:
        mod, cm = _mod(robot), _c(robot)
        rng = np.random.default_rng(13)
        qs = _qs(mod, 75, 7)
        for name in mod._KERNELS:
            for j, a in enumerate(getattr(cm, name)(*_inputs(mod, name, qs, rng))):
                np.testing.assert_array_equal(a, np.load(tmp_path / f"{robot}.{name}.{j}.npy"),
                                              err_msg=f"{robot}.{name} output {j}")


@pytest.mark.parametrize("robot", ROBOTS)
def test_casadi_equals_c(robot):
    mod = _mod(robot)
    cm = _c(robot)
    rng = np.random.default_rng(13)
    qs = _qs(mod, 3, 7)
    for name in list(mod._KERNELS) + ["ik_all"]:
        f = _casadi(robot, name)
        args = _inputs(mod, name, qs, rng) if name != "ik_all" else [cm.fk(qs)[0]]
        for i in range(len(qs)):
            row = [a[i] for a in args]
            c_out = getattr(cm, name)(*row)
            ca_out = f(*[np.asarray(r, dtype=float) for r in row])
            ca_out = ca_out if isinstance(ca_out, tuple) else (ca_out,)
            for a, b in zip(c_out, ca_out):
                a = np.asarray(a, dtype=float)
                b = np.array(b, dtype=float).reshape(a.shape)
                ok = np.isfinite(a)
                np.testing.assert_allclose(b[ok], a[ok], atol=TOL, rtol=TOL, err_msg=f"{robot}.{name}")


@pytest.mark.parametrize("robot", ROBOTS)
def test_c_agrees_with_pinocchio(robot):
    mod = _mod(robot)
    cm = _c(robot)
    model = pin.buildModelFromUrdf(str(ROOT / "models" / "urdf" / f"{robot}.urdf"))
    data = model.createData()
    fid = model.getFrameId("link6")
    qs = _qs(mod, 40, 8)
    t_batch = cm.fk(qs)[0]
    j_batch = cm.jacobian6(qs)[0]
    for q, t, j in zip(qs, t_batch, j_batch):
        pin.framesForwardKinematics(model, data, q)
        np.testing.assert_allclose(t, data.oMf[fid].homogeneous, atol=TOL)
        np.testing.assert_allclose(j, pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL), atol=TOL)


@pytest.mark.parametrize("robot", ROBOTS)
def test_c_gravity_agrees_with_pinocchio(robot):
    """gravity_links with the URDF's own link masses and centres of mass (DH frames) against Pinocchio."""
    mod = _mod(robot)
    cm = _c(robot)
    model = pin.buildModelFromUrdf(str(ROOT / "models" / "urdf" / f"{robot}.urdf"))
    data = model.createData()
    # total mass and centre of mass of the bodies moving with joint k, in DH frame k
    masses, coms = np.zeros(6), np.zeros((6, 3))
    for k in range(1, 7):
        f = model.frames[model.getFrameId(f"link{k}")]
        inertia = model.inertias[f.parentJoint]
        masses[k - 1] = inertia.mass
        coms[k - 1] = f.placement.actInv(inertia.lever) if inertia.mass > 0 else 0.0
    for q in _qs(mod, 20, 9):
        np.testing.assert_allclose(cm.gravity_links(q, masses, coms)[0],
                                   pin.computeGeneralizedGravity(model, data, q), atol=1e-8)


def test_ik_all_kernel_matches_ik_per_configuration():
    mod = _mod("puma260")
    cm = _c("puma260")
    qs = _qs(mod, 50, 10)
    poses = cm.fk(qs)[0]
    q_all, g_all = cm.ik_all(poses)
    assert q_all.shape == (50, len(mod.CONFIGS), 6)
    for j, cfg in enumerate(mod.CONFIGS):
        signs = np.broadcast_to(np.array(cfg.signs, dtype=float), (50, 3))
        q_one, *guards = cm.ik(poses, signs)
        np.testing.assert_allclose(q_all[:, j], q_one, atol=1e-12)
        np.testing.assert_allclose(g_all[:, j], np.stack(guards, axis=1), atol=1e-12)
    valid = (g_all >= 0).all(axis=2)
    back = cm.fk(q_all[valid])[0]
    np.testing.assert_allclose(back, np.repeat(poses[:, None], len(mod.CONFIGS), axis=1)[valid], atol=TOL)


@pytest.mark.parametrize("robot", ROBOTS)
def test_bad_input_to_c_kernels(robot):
    cm = _c(robot)
    with pytest.raises(ValueError, match=r"fk: input 'q' has shape \(5,\), need \(6,\) or \(N, 6\)"):
        cm.fk(np.zeros(5))
    with pytest.raises(ValueError, match=r"input 'q' row 2 element 4 is NaN"):
        q = np.zeros((3, 6))
        q[2, 4] = np.nan
        cm.jacobian6(q)
    with pytest.raises(ValueError, match=r"input 'T' has shape \(3, 4\)"):
        cm.ik_all(np.eye(4)[:3])


@pytest.mark.parametrize("robot", ROBOTS)
def test_bad_input_through_public_api(robot):
    mod = _mod(robot)
    with pytest.raises(ValueError):
        mod.fk(np.zeros(7))
    with pytest.raises(ValueError):
        mod.fk(np.full(6, np.nan))
    with pytest.raises(ValueError):
        mod.jacobian6(np.zeros((2, 5)))


# -- the public fast entries and ik_all on the compiled kernel ---------------------------

_SINGLE = {  # public function -> (kernel, second argument or None)
    "fk": ("fk", None), "jacobian4": ("jacobian4", None), "jacobian6": ("jacobian6", None),
    "gravity_regressor": ("gravity_regressor", None),
}


@pytest.mark.parametrize("robot", ROBOTS)
def test_public_fast_entry_equals_the_python_runtime(robot):
    import types
    mod = _mod(robot)
    _c(robot)
    assert not isinstance(mod.fk, types.FunctionType), "fk should be the compiled fast entry"
    rng = np.random.default_rng(21)
    for q in _qs(mod, 20, 11):
        for public, (kernel, _) in _SINGLE.items():
            np.testing.assert_array_equal(getattr(mod, public)(q), mod._ROBOT.call(kernel, q)[0])
        c = rng.uniform(0.1, 1.0, len(mod.GRAVITY_COEFFS))
        np.testing.assert_array_equal(mod.gravity(q, c), mod._ROBOT.call("gravity", q, c)[0])
        np.testing.assert_array_equal(mod.gravity(q, dict(zip(mod.GRAVITY_COEFFS, c))), mod.gravity(q, c))
        v = rng.uniform(-1, 1, 6)
        for base in ("cartesian_from_joint", "torque_from_force", "joint_from_cartesian", "force_from_torque"):
            for frame in (4, 6):
                np.testing.assert_array_equal(getattr(mod, base)(q, v, frame=frame),
                                              mod._ROBOT.call(f"{base}{frame}", q, v)[0])
    q = _qs(mod, 1, 12)[0]
    # every other form of call still goes through the runtime: lists, keywords, ints, batches
    np.testing.assert_array_equal(mod.fk(list(q)), mod.fk(q))
    np.testing.assert_array_equal(mod.fk(q=q), mod.fk(q))
    assert mod.fk(np.zeros(6, dtype=int)).shape == (4, 4)
    assert mod.fk(np.stack([q, q])).shape == (2, 4, 4)
    out1, out2 = mod.fk(q), mod.fk(q)
    assert out1 is not out2  # a new array per call, never a shared buffer


@pytest.mark.parametrize("robot", ROBOTS)
def test_public_fast_entry_keeps_every_error(robot):
    from rccl.kinematics import exceptions as errors
    mod = _mod(robot)
    with pytest.raises(errors.InvalidInput, match="not finite"):
        mod.fk(np.full(6, np.nan))
    with pytest.raises(errors.InvalidInput, match="has shape"):
        mod.jacobian6(np.zeros(5))
    with pytest.raises(errors.InvalidInput, match="frame must be 4 or 6"):
        mod.cartesian_from_joint(np.zeros(6), np.zeros(6), frame=5)
    with pytest.raises(errors.InvalidInput, match="coefficients"):
        mod.gravity(np.zeros(6), {})
    # q = 0 is singular for both arms (sin theta5 = 0; for the Microbo also d3 = 0): the
    # guard fails in C and the runtime names the problem
    with pytest.raises(errors.Singular, match="guard_"):
        mod.joint_from_cartesian(np.zeros(6), np.ones(6))
    with pytest.raises(errors.Singular):
        mod.force_from_torque(np.zeros(6), np.ones(6), frame=4)


def _ik_all_by_loop(mod, t, q_ref=None):
    """The previous ik_all: ik per configuration, unreachable ones left out, duplicates dropped."""
    from rccl.kinematics import exceptions as errors, runtime
    found = []
    for cfg in mod.CONFIGS:
        try:
            q = mod.ik(t, cfg, q_ref)
        except errors.Unreachable:
            continue
        if not any(np.all(np.abs(np.where(mod._ROBOT.revolute, runtime._wrap(q - o), q - o)) < 1e-6) for _, o in found):
            found.append((cfg, q))
    return found


@pytest.mark.parametrize("robot", ROBOTS)
def test_ik_all_on_the_kernel_equals_the_loop_over_ik(robot):
    from rccl.kinematics import runtime
    mod = _mod(robot)
    assert mod._ROBOT.ik_all_kernel is not None
    qs = _qs(mod, 30, 13)
    poses = mod.fk(qs)
    batch = mod.ik_all(poses, q_ref=qs)
    assert len(batch) == len(qs)
    for t, q, sols in zip(poses, qs, batch):
        want = _ik_all_by_loop(mod, t, q)
        assert [c for c, _ in sols] == [c for c, _ in want]
        for (_, a), (_, b) in zip(sols, want):
            # equal up to 2 pi on revolute joints (a joint half a turn from q_ref is a tie)
            d = np.where(mod._ROBOT.revolute, runtime._wrap(a - b), a - b)
            np.testing.assert_allclose(d, 0, atol=1e-9)
        assert any(np.allclose(s, q, atol=1e-7) for _, s in sols)
        single = mod.ik_all(t, q_ref=q)
        assert [c for c, _ in single] == [c for c, _ in sols]


def test_ik_all_wrist_singular_and_unreachable():
    from rccl.kinematics import exceptions as errors
    mod = _mod("puma260")
    q = np.array([0.3, -0.5, 0.4, 0.7, 0.0, 0.2])  # theta5 = 0: wrist singular
    t = mod.fk(q)
    with pytest.raises(errors.Singular, match="sin\\(theta5\\) = 0"):
        mod.ik_all(t)
    sols = mod.ik_all(t, q_ref=q)
    assert sols and all(np.allclose(mod.fk(s), t, atol=1e-9) for _, s in sols)
    assert any(np.allclose(s, q, atol=1e-7) for _, s in sols)
    far = np.eye(4)
    far[:3, 3] = [5.0, 0.0, 0.0]
    assert mod.ik_all(far) == []
    assert mod.ik_all(np.stack([far, mod.fk(np.full(6, 0.3))]))[0] == []


# -- ik, ik_all, config_of, gravity mappings and batches in the fast entries -------------

def _same_solutions(a, b):
    assert [c for c, _ in a] == [c for c, _ in b]
    for (_, x), (_, y) in zip(a, b):
        np.testing.assert_array_equal(x, y)


@pytest.mark.parametrize("robot", ROBOTS)
def test_ik_fast_entries_equal_the_python_runtime(robot):
    import types
    mod = _mod(robot)
    _c(robot)
    for name in ("ik", "ik_all", "config_of"):
        assert not isinstance(getattr(mod, name), types.FunctionType), f"{name} should be the compiled fast entry"
    rb = mod._ROBOT
    for q in _qs(mod, 60, 31):
        t = mod.fk(q)
        cfg = mod.config_of(q)
        assert cfg == rb.config_of(q) and type(cfg) is mod.Config
        np.testing.assert_array_equal(mod.ik(t, cfg), rb.ik(t, cfg))
        np.testing.assert_array_equal(mod.ik(t, cfg, q), rb.ik(t, cfg, q))
        np.testing.assert_array_equal(mod.ik(t, cfg, q_ref=q + 6.0), rb.ik(t, cfg, q + 6.0))
        _same_solutions(mod.ik_all(t), rb.ik_all(t))
        _same_solutions(mod.ik_all(t, q_ref=q), rb.ik_all(t, q))
        _same_solutions(mod.ik_all(t, q), rb.ik_all(t, q))
    qs = _qs(mod, 50, 38)
    poses = mod.fk(qs)
    for got, want in zip(mod.ik_all(poses, q_ref=qs), rb.ik_all(poses, qs)):
        _same_solutions(got, want)
    for got, want in zip(mod.ik_all(poses), rb.ik_all(poses)):
        _same_solutions(got, want)
    far = np.eye(4)
    far[:3, 3] = [5.0, 0.0, 0.0]
    mixed = mod.ik_all(np.concatenate([poses[:3], far[None]]))  # one pose for the Python path: all of them go
    assert mixed[3] == [] and all(len(m) > 0 for m in mixed[:3])
    # other call forms still work through the runtime: a config as signs, a list pose
    q = _qs(mod, 1, 32)[0]
    t = mod.fk(q)
    cfg = mod.config_of(q)
    np.testing.assert_array_equal(mod.ik(t.tolist(), list(cfg.signs)), mod.ik(t, cfg))
    sols = mod.ik_all(t)
    assert sols[0][1] is not sols[-1][1] and all(s.flags.writeable for _, s in sols)


@pytest.mark.parametrize("robot", ROBOTS)
def test_ik_fast_entries_keep_every_error(robot):
    from rccl.kinematics import exceptions as errors
    mod = _mod(robot)
    q = _qs(mod, 1, 33)[0]
    t = mod.fk(q)
    cfg = mod.config_of(q)
    skew = t.copy()
    skew[0, 1] += 1e-5  # off orthonormal by more than the tolerance
    for bad, match in ((skew, "rigid"), (np.full((4, 4), np.nan), "not finite"), (t[:3], "shape")):
        with pytest.raises(errors.InvalidInput, match=match):
            mod.ik(bad, cfg)
        with pytest.raises(errors.InvalidInput, match=match):
            mod.ik_all(bad)
    mirrored = t.copy()
    mirrored[:3, 0] *= -1  # orthonormal but a reflection
    with pytest.raises(errors.InvalidInput, match="rigid"):
        mod.ik(mirrored, cfg)
    bottom = t.copy()
    bottom[3, 0] = 1e-3
    with pytest.raises(errors.InvalidInput, match="rigid"):
        mod.ik(bottom, cfg)
    with pytest.raises(errors.InvalidInput, match="q_ref"):
        mod.ik(t, cfg, q_ref=np.full(6, np.nan))
    with pytest.raises(errors.InvalidInput, match="configuration"):
        mod.ik(t, "right")
    far = np.eye(4)
    far[:3, 3] = [5.0, 0.0, 0.0]
    with pytest.raises(errors.Unreachable, match="pose T"):
        mod.ik(far, cfg)
    assert mod.ik_all(far) == []
    with pytest.raises(errors.InvalidInput, match="not finite"):
        mod.config_of(np.full(6, np.inf))


def test_ik_fast_entry_wrist_singular_goes_to_the_runtime():
    from rccl.kinematics import exceptions as errors
    mod = _mod("puma260")
    q = np.array([0.3, -0.5, 0.4, 0.7, 0.0, 0.2])  # theta5 = 0: wrist singular
    t = mod.fk(q)
    cfg = mod.config_of(q)
    with pytest.raises(errors.Singular, match="theta5"):
        mod.ik(t, cfg)
    np.testing.assert_allclose(mod.fk(mod.ik(t, mod.config_of(q), q_ref=q)), t, atol=1e-12)


@pytest.mark.parametrize("robot", ROBOTS)
def test_gravity_takes_mappings_and_records_in_the_fast_entry(robot):
    from types import MappingProxyType

    from rccl.kinematics import exceptions as errors
    from rcci.models import load_robot
    mod = _mod(robot)
    model = load_robot(robot)
    c = np.array([model.gravity_coeffs[n].value for n in mod.GRAVITY_COEFFS])
    for q in _qs(mod, 10, 34):
        want = mod._ROBOT.call("gravity", q, c)[0]
        np.testing.assert_array_equal(mod.gravity(q, c), want)
        np.testing.assert_array_equal(mod.gravity(q, dict(zip(mod.GRAVITY_COEFFS, c))), want)
        np.testing.assert_array_equal(mod.gravity(q, model.gravity_coeffs), want)          # Value records
        np.testing.assert_array_equal(mod.gravity(q, MappingProxyType(dict(zip(mod.GRAVITY_COEFFS, c)))), want)
        np.testing.assert_array_equal(mod.gravity(q, model), want)                           # a RobotModel
    name = mod.GRAVITY_COEFFS[0]
    with pytest.raises(errors.InvalidInput, match=name):
        mod.gravity(np.zeros(6), {n: 1.0 for n in mod.GRAVITY_COEFFS[1:]})
    with pytest.raises(errors.InvalidInput, match="not finite"):
        mod.gravity(np.zeros(6), {n: float("nan") for n in mod.GRAVITY_COEFFS})
    qs = _qs(mod, 5, 35)
    np.testing.assert_array_equal(mod.gravity(qs, model.gravity_coeffs), mod._ROBOT.call("gravity", qs, c)[0])


_BATCHED = {  # public function -> number of vector arguments after q
    "fk": 0, "jacobian4": 0, "jacobian6": 0, "gravity_regressor": 0,
    "cartesian_from_joint": 1, "torque_from_force": 1, "joint_from_cartesian": 1, "force_from_torque": 1,
}


@pytest.mark.parametrize("robot", ROBOTS)
def test_batched_public_calls_and_out(robot):
    mod = _mod(robot)
    rng = np.random.default_rng(36)
    qs = _qs(mod, 40_000, 36)  # more rows than one thread takes: the split is exercised
    v = rng.uniform(-1, 1, (len(qs), 6))
    for name, extra in _BATCHED.items():
        fn = getattr(mod, name)
        args = (qs,) + (v,) * extra
        kernel = name if name in _SINGLE else f"{name}6"
        want = mod._ROBOT.call(kernel, *args)[0]
        got = fn(*args)
        np.testing.assert_array_equal(got, want)
        out = np.empty_like(want)
        assert fn(*args, out=out) is out
        np.testing.assert_array_equal(out, want)
        for i in (0, 19_999, 20_000, len(qs) - 1):  # rows on both sides of the thread boundary
            np.testing.assert_allclose(got[i], fn(*(a[i] for a in args)), rtol=0, atol=1e-12)
    c = rng.uniform(0.1, 1.0, len(mod.GRAVITY_COEFFS))
    out = np.empty((len(qs), 6))
    assert mod.gravity(qs, c, out=out) is out
    np.testing.assert_array_equal(out, mod._ROBOT.call("gravity", qs, c)[0])
    single = np.empty((4, 4))
    assert mod.fk(qs[0], out=single) is single
    np.testing.assert_array_equal(single, mod.fk(qs[0]))
    # the Python path honours out= too (a list input)
    small = np.empty((3, 4, 4))
    assert mod.fk(qs[:3].tolist(), out=small) is small
    np.testing.assert_array_equal(small, mod.fk(qs[:3]))


@pytest.mark.parametrize("robot", ROBOTS)
def test_batched_public_calls_keep_every_error(robot):
    from rccl.kinematics import exceptions as errors
    mod = _mod(robot)
    qs = _qs(mod, 50_000, 37)
    for bad_out, what in ((np.empty((len(qs), 4)), "shape"), (np.empty((len(qs), 4, 4), dtype=np.float32), "float32"),
                          ([0.0] * 16, "list"), (np.empty((4, 4)), "shape")):
        with pytest.raises(errors.InvalidInput, match="out must be"):
            mod.fk(qs, out=bad_out)
    ro = np.empty((len(qs), 4, 4))
    ro.flags.writeable = False
    with pytest.raises(errors.InvalidInput, match="read-only"):
        mod.fk(qs, out=ro)
    # a non-contiguous out of the right shape is fine (through the Python path)
    wide = np.empty((len(qs), 4, 8))[:, :, ::2]
    np.testing.assert_array_equal(mod.fk(qs, out=wide), mod.fk(qs))
    # out= sharing memory with the input: the Python path computes first, then writes
    q6 = qs[:10].copy()
    want = mod.fk(q6)
    buf = np.zeros((10, 4, 4))
    buf.reshape(10, 16)[:, :6] = q6
    alias = buf.reshape(10, 16)[:, :6]  # q read from the very memory the result goes to
    assert not alias.flags.c_contiguous
    np.testing.assert_array_equal(mod.fk(alias, out=buf), want)
    buf2 = np.zeros(16)
    buf2[:6] = q6[0]
    np.testing.assert_array_equal(mod.fk(buf2[:6], out=buf2.reshape(4, 4)), want[0])  # contiguous, overlapping
    bad = qs.copy()
    bad[31_234, 2] = np.nan
    with pytest.raises(errors.InvalidInput, match="not finite .*31234"):
        mod.fk(bad)
    sing = qs.copy()
    sing[45_678] = 0.0  # singular for both arms
    with pytest.raises(errors.Singular, match="batch row 45678"):
        mod.joint_from_cartesian(sing, np.ones((len(qs), 6)))


@pytest.mark.parametrize("robot", ROBOTS)
def test_generated_module_holds_kernels_and_binds_the_runtime_api(robot):
    """The public functions live in rccl.kinematics.runtime; the generated module only binds them."""
    import ast

    from rccl.kinematics import runtime
    mod = _mod(robot)
    tree = ast.parse(Path(mod.__file__).read_text())
    funcs = [n for n in tree.body if isinstance(n, ast.FunctionDef)]
    # the dynamics entries (issue 27) are bound by one generated binder that only hands each
    # kernel to rccl.kinematics.backend.public (no arithmetic); every other function is a kernel
    binders = [n for n in funcs if n.name == "_dynamics_entry"]
    assert all("_backend.public(" in ast.unparse(n) for n in binders), "a binder that does more than bind"
    kernels = [n.name for n in funcs if n not in binders]
    assert kernels and all(f.startswith("_") and f.endswith(("_one", "_many")) for f in kernels), kernels
    for name in runtime.PUBLIC:
        assert getattr(mod, name) is getattr(mod._API, name)


@pytest.mark.parametrize("robot", ROBOTS)
def test_fast_entries_take_good_input_without_the_runtime(robot):
    """Well-formed calls stay in C: the fallback (here a recorder) is never called."""
    cm, mod = _c(robot), _mod(robot)
    calls = []

    def record(*args, **kwargs):
        calls.append(args)

    qs = _qs(mod, 50, 39)
    poses = mod.fk(qs)
    cm.public("ik_all", record)(poses)
    cm.public("ik_all", record)(poses, q_ref=qs)
    cm.public("ik_all", record)(poses[0], qs[0])
    for q, t in zip(qs, poses):
        cm.public("ik", record)(t, mod.config_of(q), q_ref=q)
        cm.public("config_of", record)(q)
    cm.public("fk", record)(qs)
    cm.public("fk", record)(qs, out=np.empty((len(qs), 4, 4)))
    cm.public("fk", record)(qs[0], out=np.empty((4, 4)))
    c = dict(zip(mod.GRAVITY_COEFFS, np.linspace(0.1, 0.5, len(mod.GRAVITY_COEFFS))))
    cm.public("gravity", record, mod.GRAVITY_COEFFS)(qs[0], c)
    cm.public("gravity", record, mod.GRAVITY_COEFFS)(qs, c, out=np.empty((len(qs), 6)))
    assert calls == []


@pytest.mark.parametrize("robot", ROBOTS)
def test_results_not_finite_by_construction_are_still_scanned(robot):
    """J dq can overflow (dq is used bare); its results are checked, single and batched."""
    from rccl.kinematics import exceptions as errors
    mod = _mod(robot)
    qs = _qs(mod, 5000, 38)
    huge = np.full(6, np.finfo(float).max) * np.sign(mod.jacobian6(qs[0])[0])  # the first row's terms add up
    with pytest.raises(errors.KinematicsError, match="non-finite result"):
        mod.cartesian_from_joint(qs[0], huge)
    dq = np.ones((len(qs), 6))
    dq[4321] = np.full(6, np.finfo(float).max) * np.sign(mod.jacobian6(qs[4321])[0])
    with pytest.raises(errors.KinematicsError, match="non-finite result; at batch row 4321"):
        mod.cartesian_from_joint(qs, dq)


def test_vector_sincos_within_one_and_a_half_ulp():
    """The batched rows' own vector sine/cosine (kin_prelude.h) against long double."""
    cm = _c("puma260")
    rng = np.random.default_rng(39)
    half_pi = np.pi / 2
    x = np.concatenate([
        rng.uniform(-2 * np.pi, 2 * np.pi, 60_000),      # joint angles
        rng.uniform(-1e5, 1e5, 20_000),                   # far turns
        np.arange(-400, 401) * half_pi,                   # next to multiples of pi/2 (rounded)
        np.nextafter(np.arange(-400, 401) * half_pi, np.inf),
        [0.0, 1e-300, -1e-300, 5e-324, 1e-8, np.pi / 4, -np.pi / 4],
        rng.uniform(2.0**20, 1e9, 37),                    # beyond the reduction's range: libm lanes
    ])
    got = cm.vector_sincos(x.tolist())
    if got is None:
        pytest.skip("this CPU has no AVX2/FMA: the batched rows use libm")  # not on the CI machine
    s, c = (np.array(v) for v in got)
    xl = x.astype(np.longdouble)
    for name, y, exact in (("sin", s, np.sin(xl)), ("cos", c, np.cos(xl))):
        ulp = np.spacing(np.abs(exact).astype(np.float64))
        err = np.abs((y.astype(np.longdouble) - exact) / ulp.astype(np.longdouble)).astype(np.float64)
        worst = int(np.argmax(err))
        assert err[worst] <= 1.5, f"{name}({x[worst]!r}) off by {err[worst]:.3f} ulp"
        assert err[:60_000].max() <= 1.4  # joint angles
    # every lane count: the tails of a vector are padded, not read past the end
    for n in range(1, 9):
        sn, cn = cm.vector_sincos(x[:n].tolist())
        np.testing.assert_array_equal(sn, s[:n])
        np.testing.assert_array_equal(cn, c[:n])
    # one row's 5-8 angles (both vectors at once) with a lane beyond the reduction's range
    for n in range(5, 9):
        idx = np.r_[np.arange(n - 1), len(x) - 1]
        sn, cn = cm.vector_sincos(x[idx].tolist())
        np.testing.assert_array_equal(sn, s[idx])
        np.testing.assert_array_equal(cn, c[idx])
