"""The URDFs against the data files: two parsers, DH frames, and the thesis gravity vector."""
from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
import yourdfpy

from rcci.models import RobotModel, load_robot

ROBOTS = ("puma260", "microbo", "stanford", "panda")  # every URDF is also cross-checked in tests/test_crosscheck.py
N_SAMPLES = 300


def _pinocchio(model: RobotModel) -> tuple[pin.Model, pin.Data]:
    pm = pin.buildModelFromUrdf(str(model.urdf_path))
    pm.gravity.linear = np.array([0.0, 0.0, -model.gravity])  # z0 up (thesis eq. 4.22)
    return pm, pm.createData()


def _samples(model: RobotModel, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).uniform(model.lower, model.upper, size=(N_SAMPLES, model.n_joints))


# ----------------------------------------------------------------------------- parsing, limits

@pytest.mark.parametrize("name", ROBOTS)
def test_pinocchio_loads_with_data_file_limits(name: str) -> None:
    model = load_robot(name)
    pm, _ = _pinocchio(model)
    assert pm.nq == pm.nv == model.n_joints
    assert [pm.names[i] for i in range(1, pm.njoints)] == [j.name for j in model.joints]
    assert np.allclose(pm.lowerPositionLimit, model.lower, rtol=0, atol=1e-12)
    assert np.allclose(pm.upperPositionLimit, model.upper, rtol=0, atol=1e-12)
    assert np.allclose(pm.velocityLimit, model.max_velocity, rtol=0, atol=1e-12)
    for i, joint in enumerate(model.joints, start=1):
        short = pm.joints[i].shortname()
        assert ("P" in short.replace("JointModel", "")[:1]) == (joint.kind == "prismatic"), short
    for k in range(1, model.n_joints + 1):
        assert pm.existFrame(f"link{k}")
    assert pm.existFrame("base_link")
    assert sum(pm.inertias[i].mass for i in range(pm.njoints)) == pytest.approx(sum(li.mass for li in model.links))


@pytest.mark.parametrize("name", ROBOTS)
def test_yourdfpy_loads_with_data_file_limits(name: str) -> None:
    model = load_robot(name)
    robot = yourdfpy.URDF.load(str(model.urdf_path), load_meshes=False, build_scene_graph=True)
    assert robot.validate()
    assert list(robot.actuated_joint_names) == [j.name for j in model.joints]
    for j, lo, hi, vmax in zip(model.joints, model.lower, model.upper, model.max_velocity):
        urdf_joint = robot.joint_map[j.name]
        assert urdf_joint.type == j.kind
        assert urdf_joint.limit.lower == pytest.approx(lo, abs=1e-12)
        assert urdf_joint.limit.upper == pytest.approx(hi, abs=1e-12)
        assert urdf_joint.limit.velocity == pytest.approx(vmax, abs=1e-12)
        assert urdf_joint.limit.effort > 0
    for li in model.links:
        inertial = robot.link_map[f"link{li.index}"].inertial
        assert inertial.mass == pytest.approx(li.mass, abs=1e-12)
        assert np.allclose(inertial.origin[:3, 3], li.com, atol=1e-12)
        assert np.allclose(inertial.inertia, li.inertia, atol=1e-12)


@pytest.mark.parametrize("name", ROBOTS)
def test_yourdfpy_frames_match_dh(name: str) -> None:
    """A second parser's forward kinematics agrees with the A-matrix product."""
    model = load_robot(name)
    robot = yourdfpy.URDF.load(str(model.urdf_path), load_meshes=False, build_scene_graph=True)
    for q in _samples(model, 7)[:20]:
        robot.update_cfg(q)
        dh = model.base_to_link(q)
        for k in range(model.n_joints):
            base_to_link = robot.get_transform(f"link{k + 1}", "base_link")
            assert np.max(np.abs(base_to_link - dh[k])) < 1e-12


# ----------------------------------------------------------------------------- DH frames

@pytest.mark.parametrize("name", ROBOTS)
def test_pinocchio_frames_are_dh_frames(name: str) -> None:
    """oMf(link k) = A_1 ... A_k (thesis eqs. 3.3, 4.9) for random q, to 1e-12."""
    model = load_robot(name)
    pm, pd = _pinocchio(model)
    frame_ids = [pm.getFrameId(f"link{k}") for k in range(1, model.n_joints + 1)]
    worst = 0.0
    for q in _samples(model, 11):
        pin.framesForwardKinematics(pm, pd, q)
        dh = model.base_to_link(q)
        for k, fid in enumerate(frame_ids):
            worst = max(worst, float(np.max(np.abs(pd.oMf[fid].homogeneous - dh[k]))))
    assert worst < 1e-12


def test_puma_zero_pose_geometry() -> None:
    """At q = 0 the wrist centre is at (a2, -d3, d4): upper arm along x0, forearm up z0."""
    model = load_robot("puma260")
    pm, pd = _pinocchio(model)
    pin.framesForwardKinematics(pm, pd, np.zeros(6))
    p = pd.oMf[pm.getFrameId("link6")].translation
    assert p == pytest.approx([0.2032, -0.12624, 0.2032], abs=1e-12)


# ----------------------------------------------------------------------------- gravity

def _tau_g_424(q: np.ndarray, c12: float, c13: float, c15: float) -> np.ndarray:
    """Thesis eq. 4.24 (PUMA 260 gravity loading vector), written out independently."""
    _, t2, t3, t4, t5, _ = q
    s23, c23 = math.sin(t2 + t3), math.cos(t2 + t3)
    common = (c23 * math.cos(t4) * math.sin(t5) + math.cos(t5) * s23) * c15 + s23 * c13
    return np.array([
        0.0,
        common + math.cos(t2) * c12,
        common,
        -s23 * math.sin(t4) * math.sin(t5) * c15,
        (c23 * math.sin(t5) + math.cos(t4) * math.cos(t5) * s23) * c15,
        0.0,
    ])


def _tau_g_420(model: RobotModel, q: np.ndarray) -> np.ndarray:
    """Thesis eq. 4.20: tau_i = -h_i sum_{k>=i} m_k U_k r_k, with U_k = A_i ... A_k,
    h_i = (g.o_{i-1}, -g.n_{i-1}, 0, 0) (revolute) or (0, 0, 0, g.a_{i-1}) (prismatic),
    and g the gravity acceleration in the base frame, (0, 0, -g) with z0 up."""
    n = model.n_joints
    A = [j.transform(float(qi)) for j, qi in zip(model.joints, q)]
    g = np.array([0.0, 0.0, -model.gravity])
    tau = np.zeros(n)
    base_to_prev = np.eye(4)  # T_{i-1}
    for i in range(n):
        nn, oo, aa = base_to_prev[:3, 0], base_to_prev[:3, 1], base_to_prev[:3, 2]
        if model.joints[i].kind == "revolute":
            h = np.array([g @ oo, -(g @ nn), 0.0, 0.0])
        else:
            h = np.array([0.0, 0.0, 0.0, g @ aa])
        total = np.zeros(4)
        U = np.eye(4)
        for k in range(i, n):
            U = U @ A[k]
            link = model.links[k]
            total += link.mass * (U @ np.append(link.com, 1.0))
        tau[i] = -h @ total
        base_to_prev = base_to_prev @ A[i]
    return tau


def test_puma_gravity_is_eq_4_24_with_table_4_9() -> None:
    model = load_robot("puma260")
    coeffs = {k: v.value for k, v in model.gravity_coeffs.items()}
    assert coeffs == {"c12": 5.509, "c13": -1.762, "c15": -1.192}
    pm, pd = _pinocchio(model)
    worst = 0.0
    for q in _samples(model, 424):
        tau_pin = pin.computeGeneralizedGravity(pm, pd, q)
        worst = max(worst, float(np.max(np.abs(tau_pin - _tau_g_424(q, **coeffs)))))
    assert worst < 1e-8  # N*m; the URDF's com values are written to 1e-11 m


def test_puma_gravity_at_table_4_7_poses() -> None:
    """Table 4.7 start poses with the swept joint moved back 90 deg (the phi_0 of Table 4.8):
    eq. 4.24 reduces to a single coefficient there, and so must the URDF's gravity."""
    model = load_robot("puma260")
    pm, pd = _pinocchio(model)
    c = {k: v.value for k, v in model.gravity_coeffs.items()}
    q = model.poses["j2"].copy()
    q[1] -= math.pi / 2  # joint 2 moved back 90 deg: upper arm horizontal, forearm vertical
    assert pin.computeGeneralizedGravity(pm, pd, q)[1] == pytest.approx(c["c12"], abs=1e-8)
    q = model.poses["j3B"].copy()
    q[2] -= math.pi / 2  # theta2 + theta3 = -90 deg, theta5 = 90 deg: tau_3 = -c13 by eq. 4.24
    assert pin.computeGeneralizedGravity(pm, pd, q)[2] == pytest.approx(-c["c13"], abs=1e-8)


@pytest.mark.parametrize("name", ROBOTS)
def test_gravity_is_eq_4_20(name: str) -> None:
    model = load_robot(name)
    pm, pd = _pinocchio(model)
    worst = 0.0
    for q in _samples(model, 420):
        worst = max(worst, float(np.max(np.abs(pin.computeGeneralizedGravity(pm, pd, q) - _tau_g_420(model, q)))))
    assert worst < 1e-10


def test_puma_eq_4_20_reproduces_4_24() -> None:
    """The data-file inertials turn eq. 4.20 into eq. 4.24 with the Table 4.9 values."""
    model = load_robot("puma260")
    coeffs = {k: v.value for k, v in model.gravity_coeffs.items()}
    for q in _samples(model, 5)[:50]:
        assert np.allclose(_tau_g_420(model, q), _tau_g_424(q, **coeffs), atol=1e-8)


def test_microbo_gravity_closed_form() -> None:
    """tau_g = (0, c12, 0, -c15 C4 S5, -c15 S4 C5, 0) with the data file's c12, c15."""
    model = load_robot("microbo")
    c12, c15 = model.gravity_coeffs["c12"].value, model.gravity_coeffs["c15"].value
    assert model.gravity_coeffs["c12"].unit == "N" and model.gravity_coeffs["c15"].unit == "N*m"
    pm, pd = _pinocchio(model)
    for q in _samples(model, 3):
        want = np.array([0.0, c12, 0.0, -c15 * math.cos(q[3]) * math.sin(q[4]),
                         -c15 * math.sin(q[3]) * math.cos(q[4]), 0.0])
        assert np.allclose(pin.computeGeneralizedGravity(pm, pd, q), want, atol=1e-9)
