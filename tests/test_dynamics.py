"""The generated dynamics (thesis eq. 4.6, derive.dynamics) against Pinocchio on the URDFs:
rnea, crba, computeCoriolisMatrix, computeGeneralizedGravity, computeJointTorqueRegressor,
on random states of every arm; D symmetric positive definite, D' - 2C skew-symmetric, the
base regressor times the base parameters equal to rnea, and t_g equal to the gravity kernels."""
from __future__ import annotations

import importlib

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings, strategies as st

from rcci.models import available_robots, load_robot

ROBOTS = tuple(available_robots())
REL = 1e-10


def _arm(name: str):
    mod = importlib.import_module(f"rccl.kinematics.{name}")
    model = pin.buildModelFromUrdf(f"models/urdf/{name}.urdf")
    return mod, model


ARMS = {name: _arm(name) for name in ROBOTS}


def _state(mod, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A state from 3 n numbers in [0, 1] (n joints; u has 21, enough for 7): q in the joint
    ranges, qd in +-2, qdd in +-5."""
    lo, hi = np.asarray(mod.LOWER), np.asarray(mod.UPPER)
    n = len(lo)
    return lo + (hi - lo) * u[:n], 4.0 * u[n:2 * n] - 2.0, 10.0 * u[2 * n:3 * n] - 5.0


def _close(a, b, rel: float = REL) -> None:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    scale = max(1.0, float(np.abs(b).max()))
    assert np.abs(a - b).max() <= rel * scale, (np.abs(a - b).max(), scale)


def _full(m: np.ndarray) -> np.ndarray:
    """Pinocchio fills the upper triangle of M."""
    return np.triu(m) + np.triu(m, 1).T


UNIT = st.lists(st.floats(0.0, 1.0), min_size=21, max_size=21).map(np.array)


@pytest.mark.parametrize("robot", ROBOTS)
@settings(max_examples=40, deadline=None)
@given(u=UNIT)
def test_against_pinocchio(robot: str, u: np.ndarray) -> None:
    mod, model = ARMS[robot]
    data = model.createData()
    q, qd, qdd = _state(mod, u)
    _close(mod.inverse_dynamics(q, qd, qdd), pin.rnea(model, data, q, qd, qdd))
    d = mod.inertia_matrix(q)
    _close(d, _full(pin.crba(model, data, q)))
    grav = pin.computeGeneralizedGravity(model, data, q)
    zero = np.zeros(len(q))
    _close(mod.inverse_dynamics(q, zero, zero), grav)
    _close(mod.coriolis(q, qd), pin.rnea(model, data, q, qd, zero) - grav)
    c = mod.coriolis_matrix(q, qd)
    _close(c, pin.computeCoriolisMatrix(model, data, q, qd))
    _close(c @ qd, mod.coriolis(q, qd))
    # D symmetric positive definite
    assert np.array_equal(d, d.T)
    assert np.linalg.eigvalsh(d).min() > 0.0
    # D' - 2C skew: D' by central differences of the generated D along qd
    h = 1e-6
    ddot = (mod.inertia_matrix(q + h * qd) - mod.inertia_matrix(q - h * qd)) / (2 * h)
    n = ddot - 2 * c
    assert np.abs(n + n.T).max() <= 1e-6 * max(1.0, np.abs(ddot).max())


@pytest.mark.parametrize("robot", ROBOTS)
@settings(max_examples=25, deadline=None)
@given(u=UNIT)
def test_base_regressor_reproduces_rnea(robot: str, u: np.ndarray) -> None:
    """Y beta = rnea for the data file's inertials, and for random physical inertials and
    rotor inertias set in Pinocchio (whose own torque regressor must agree as well)."""
    mod, model = ARMS[robot]
    q, qd, qdd = _state(mod, u)
    rm = load_robot(robot)
    masses = np.array([li.mass for li in rm.links])
    coms = np.array([li.com for li in rm.links])
    inertia = np.array([[i[0, 0], i[1, 1], i[2, 2], i[0, 1], i[0, 2], i[1, 2]]
                        for i in (np.asarray(li.inertia) for li in rm.links)])
    y = mod.base_regressor(q, qd, qdd)
    n = len(q)
    assert y.shape == (n, len(mod.BASE_PARAMETERS))
    beta = mod.base_parameters(masses, coms, inertia, np.zeros(n))
    _close(y @ beta, mod.inverse_dynamics(q, qd, qdd))
    # random inertials (DH frame k), moved into Pinocchio's joint frames
    rng = np.random.default_rng(int(u[0] * 2**31))
    other = model.copy()
    m2 = rng.uniform(0.5, 5.0, n)
    c2 = rng.uniform(-0.2, 0.2, (n, 3))
    rows = []
    for k in range(n):
        a = rng.normal(size=(3, 3))
        ic = a @ a.T * 1e-2 + np.eye(3) * 1e-3
        rows.append([ic[0, 0], ic[1, 1], ic[2, 2], ic[0, 1], ic[0, 2], ic[1, 2]])
        f = other.frames[other.getFrameId(f"link{k + 1}")]
        other.inertias[f.parentJoint] = f.placement.act(pin.Inertia(float(m2[k]), c2[k], ic))
    rotor = rng.uniform(0.0, 0.1, n)
    other.armature = rotor
    data = other.createData()
    tau = pin.rnea(other, data, q, qd, qdd)
    beta2 = mod.base_parameters(m2, c2, np.array(rows), rotor)
    _close(y @ beta2, tau)
    reg = pin.computeJointTorqueRegressor(other, data, q, qd, qdd)
    pi = np.concatenate([other.inertias[j].toDynamicParameters() for j in range(1, other.njoints)])
    _close(reg @ pi + rotor * qdd, tau)


@pytest.mark.parametrize("robot", ROBOTS)
def test_gravity_is_the_static_case(robot: str) -> None:
    """t_g of the new model (inverse dynamics at rest) equals the existing gravity kernels
    (4.20 from the link masses and centres of mass, and 4.24 with their coefficients)."""
    mod, _ = ARMS[robot]
    rm = load_robot(robot)
    masses = np.array([li.mass for li in rm.links])
    coms = np.array([li.com for li in rm.links])
    coeffs = mod.coefficients_from_links(masses, coms)
    rng = np.random.default_rng(7)
    for _ in range(50):
        q = rng.uniform(mod.LOWER, mod.UPPER)
        tg = mod.inverse_dynamics(q, np.zeros(len(q)), np.zeros(len(q)))
        _close(tg, mod.gravity_links(q, masses, coms))
        _close(tg, mod.gravity(q, coeffs))


@pytest.mark.parametrize("robot", ROBOTS)
def test_batched_equals_single(robot: str) -> None:
    mod, _ = ARMS[robot]
    rng = np.random.default_rng(1)
    n, nj = 33, len(mod.LOWER)
    q = rng.uniform(mod.LOWER, mod.UPPER, (n, nj))
    qd, qdd = rng.uniform(-2, 2, (n, nj)), rng.uniform(-5, 5, (n, nj))
    tau = mod.inverse_dynamics(q, qd, qdd)
    d = mod.inertia_matrix(q)
    assert tau.shape == (n, nj) and d.shape == (n, nj, nj)
    for i in (0, 17, 32):
        np.testing.assert_array_equal(tau[i], mod.inverse_dynamics(q[i], qd[i], qdd[i]))
        np.testing.assert_array_equal(d[i], mod.inertia_matrix(q[i]))


def test_bad_input_is_named() -> None:
    from rcci.models.kinematics import InvalidInput

    mod, _ = ARMS[ROBOTS[0]]
    with pytest.raises(InvalidInput, match="qd"):
        mod.inverse_dynamics(np.zeros(6), np.zeros(5), np.zeros(6))
    with pytest.raises(InvalidInput, match="not finite"):
        mod.inertia_matrix(np.array([0.0, np.nan, 0, 0, 0, 0]))


@pytest.mark.parametrize("robot", ROBOTS)
def test_drive_terms_are_the_runtime_models(robot: str) -> None:
    """The generated friction(qd) is eq. 4.27 as the runtime integrates it (simula's kinetic friction
    of a warm joint without the Table 4.4 variation; rci.conversions.friction_torque), 0 at rest, in
    every back end (Python one/many, C, CasADi); rotor_torque(qdd) is the data file's G^T diag(J_m) G qdd."""
    import casadi as ca
    from dataclasses import replace

    from rci.conversions import friction_torque
    from rci.simula.friction import FrictionState
    from rci.simula.params import truth_from_model

    mod, _ = ARMS[robot]
    model = load_robot(robot)
    truth = truth_from_model(model)
    truth = replace(truth, variation=np.zeros(model.n_joints), disturbances=replace(truth.disturbances, start_warm=True))
    sim = FrictionState(truth, np.random.default_rng(0))
    rng = np.random.default_rng(3)
    qd = rng.uniform(-2.0, 2.0, (40, model.n_joints))
    qd[1::7, 2] = -1e-9                    # just moving: the Coulomb step
    qd[::5, :] = 0.0                       # at rest: no kinetic friction
    f = mod.friction(qd)
    fr = model.friction
    want = friction_torque(qd, fr.coulomb_pos.values, fr.coulomb_neg.values, fr.viscous_pos.values,
                           fr.viscous_neg.values)
    np.testing.assert_allclose(f, want, rtol=1e-12, atol=1e-12)
    q = rng.uniform(mod.LOWER, mod.UPPER, (40, model.n_joints))
    np.testing.assert_allclose(f, [sim.kinetic(q[k], qd[k]) for k in range(40)], rtol=1e-12, atol=1e-12)
    assert np.all(f[::5] == 0.0)
    cas = ca.Function.load(f"rccl/kinematics/casadi/{robot}/friction.casadi")
    for k in (0, 1, 8, 39):
        np.testing.assert_allclose(mod.friction(qd[k]), f[k], rtol=0, atol=0)
        np.testing.assert_allclose(np.ravel(mod._friction_one(qd[k])), f[k], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(np.asarray(cas(qd[k])).ravel(), f[k], rtol=1e-12, atol=1e-12)
    qdd = rng.uniform(-5.0, 5.0, (40, model.n_joints))
    np.testing.assert_allclose(mod.rotor_torque(qdd), qdd @ model.rotor_matrix().T, rtol=1e-12, atol=1e-14)
    cas = ca.Function.load(f"rccl/kinematics/casadi/{robot}/rotor_torque.casadi")
    np.testing.assert_allclose(np.asarray(cas(qdd[3])).ravel(), model.rotor_matrix() @ qdd[3], rtol=1e-12, atol=1e-14)
