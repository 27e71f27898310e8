"""The Stanford arm: the spherical (Stanford) class of the closed-form inverse kinematics
(derive.inverse.spherical_ik), derived from a DH table built here, independently of the
shipped models/stanford.toml, so that variants of the table (d2 = 0, a d4 along the boom,
an offset boom) can be derived too. FK is cross-checked against a
Pinocchio model built from the same table, IK by fk(ik(T)) = T in every configuration.

The table is the Stanford (Scheinman) arm's of Paul 1972, Stanford AI Memo AIM-177,
Figure 2.3, as transcribed in P. Corke's Robotics Toolbox for MATLAB (mdl_stanford.m; not
checked against the memo itself): d1 = 0.412 m, d2 = 0.154 m (shoulder offset), joint 3
prismatic with theta3 = -90 deg, alpha = -90, 90, 0, -90, 90, 0 deg. The toolbox's tool
length d6 = 0.263 m is left out (frame 6 at the wrist centre, as for the PUMA tables) and
joint 3's range is the toolbox's 12-50 in (0.3048-1.27 m).
"""
from __future__ import annotations

import itertools

import numpy as np
import pinocchio as pin
import pytest
import sympy as sp

from derive.dh import DHLink, DHRobot, Q
from derive.forward import t6
from derive.inverse import POSE, OutsideClass, class_reasons, solve_ik
from derive.robots import CONFIG_FIELDS

d1, d2 = sp.symbols("d1 d2", positive=True)  # named and signed as dh_from_model names them
NUMBERS = {d1: 0.412, d2: 0.154}
DEG = sp.pi / 180
STANFORD = DHRobot("stanford", (
    DHLink(d1, Q[0], -90 * DEG, 0),
    DHLink(d2, Q[1], 90 * DEG, 0),
    DHLink(Q[2], -90 * DEG, 0, 0, prismatic=True),
    DHLink(0, Q[3], -90 * DEG, 0),
    DHLink(0, Q[4], 90 * DEG, 0),
    DHLink(0, Q[5], 0, 0)), (d1, d2))
LOWER = np.array([-np.pi, -np.pi, 0.3048, -np.pi, -np.pi / 2, -np.pi])
UPPER = np.array([np.pi, np.pi, 1.27, np.pi, np.pi / 2, np.pi])
CONFIGS = list(itertools.product((1, -1), repeat=3))  # (arm, boom, wrist)
REVOLUTE = [0, 1, 3, 4, 5]


def _wrap(x):
    return (x + np.pi) % (2 * np.pi) - np.pi


@pytest.fixture(scope="module")
def solved():
    """The symbolic inverse and forward kinematics, lambdified with the table's numbers."""
    ik = solve_ik(STANFORD)
    pose, par = list(POSE[:3, :]), list(NUMBERS)
    joints = sp.lambdify([pose, ik.config, par], list(ik.joints), "math", cse=True)
    guards = sp.lambdify([pose, ik.config, par], [g[1] for g in ik.guards], "math", cse=True)
    ind = sp.lambdify([Q[:6], par], list(ik.indicators), "math", cse=True)
    fk = sp.lambdify([Q[:6], par], t6(STANFORD), "numpy", cse=True)
    vals = list(NUMBERS.values())

    def run(f):
        return lambda *args: np.array(f(*args, vals), dtype=float)

    return ik, run(joints), run(guards), run(ind), run(fk)


def _random_q(rng, n):
    """Joint vectors in range, away from the singularities (sin theta2, sin theta5 = 0)."""
    out = []
    while len(out) < n:
        q = rng.uniform(LOWER, UPPER)
        if abs(np.sin(q[1])) > 0.05 and abs(np.sin(q[4])) > 0.05:
            out.append(q)
    return out


def test_the_stanford_arm_is_in_the_spherical_class(solved):
    ik = solved[0]
    reasons = class_reasons(STANFORD)
    assert reasons["spherical (Stanford class)"] == []
    assert reasons["articulated (PUMA class)"] and reasons["cylindrical (Microbo class)"]
    assert ik.kind == "spherical"
    assert tuple(map(str, ik.config)) == CONFIG_FIELDS["spherical (Stanford class)"] == ("arm", "boom", "wrist")
    assert [g[0] for g in ik.guards] == ["guard_arm_reach", "guard_boom", "guard_wrist"]


def test_every_configuration_round_trips_and_q_is_among_them(solved):
    _, joints, guards, ind, fk = solved
    worst = 0.0
    for q in _random_q(np.random.default_rng(7), 40):
        t = fk(q)
        flat = list(t[:3, :].ravel())
        own = tuple(int(s) for s in np.sign(ind(q)))
        in_range = 0
        for cfg in CONFIGS:
            assert (guards(flat, cfg) >= 0).all(), cfg
            qs = joints(flat, cfg)
            worst = max(worst, np.abs(fk(qs) - t).max())
            # each solution is in the configuration it is named by
            assert tuple(int(s) for s in np.sign(ind(qs))) == cfg
            # boom = -1 is the boom reversed through the shoulder: negative extension
            assert (qs[2] > 0) == (cfg[1] == 1)
            in_range += bool(LOWER[2] <= qs[2] <= UPPER[2])
            if cfg == own:
                d = qs - q
                d[REVOLUTE] = _wrap(d[REVOLUTE])
                assert np.abs(d).max() < 1e-9, (q, qs)
        assert in_range == 4  # arm right/left x wrist noflip/flip with the boom out
    assert worst < 1e-12


def test_the_shipped_model_file_has_this_table():
    """models/stanford.toml (what `make derive` reads) is the table derived here, numbers and
    joint-3 stroke included."""
    from derive.dh import dh_from_model
    from rcci.models import load_robot

    model = load_robot("stanford")
    robot, params = dh_from_model(model)
    assert robot.links == STANFORD.links and params == NUMBERS
    assert model.lower[2] == LOWER[2] and model.upper[2] == UPPER[2]


def test_arm_sign_means_what_it_means_on_the_puma(solved):
    """arm = +1 (right): seen from above, the shoulder offset d2 lies to the right of the
    wrist centre's horizontal reach, as the PUMA's right arm has its offset d3."""
    _, joints, _, _, fk = solved
    for q in _random_q(np.random.default_rng(3), 10):
        t = fk(q)
        for cfg in CONFIGS:
            qs = joints(list(t[:3, :].ravel()), cfg)
            offset = NUMBERS[d2] * np.array([-np.sin(qs[0]), np.cos(qs[0])])  # d2 along z1
            reach = t[:2, 3] - offset
            assert np.sign(reach[0] * offset[1] - reach[1] * offset[0]) == -cfg[0]


def _pinocchio_model(masses=None, coms=None) -> tuple[pin.Model, int]:
    """Pinocchio model of the table: joint i (RZ or PZ) about / along z_{i-1}, then the
    fixed rest of A_i = Rz(theta) Tz(d) Tx(a) Rx(alpha) as the next joint's placement; link
    i (frame i) sits at that placement, with mass masses[i] at coms[i] (frame i) if given."""
    model = pin.Model()
    model.gravity.linear = np.array([0.0, 0.0, -9.81])
    parent, placement = 0, pin.SE3.Identity()
    for i, link in enumerate(STANFORD.links):
        joint = pin.JointModelPZ() if link.prismatic else pin.JointModelRZ()
        parent = model.addJoint(parent, joint, placement, f"j{i + 1}")
        theta = 0.0 if not link.prismatic else float(link.theta)
        d = 0.0 if link.prismatic else float(sp.sympify(link.d).subs(NUMBERS))
        placement = (pin.SE3(pin.utils.rotate("z", theta), np.array([0.0, 0.0, d]))
                     * pin.SE3(pin.utils.rotate("x", float(link.alpha)), np.array([float(link.a), 0.0, 0.0])))
        if masses is not None:
            inertia = pin.Inertia(masses[i], coms[i], 0.01 * np.eye(3))
            model.appendBodyToJoint(parent, inertia, placement)
    frame = model.addFrame(pin.Frame("link6", parent, 0, placement, pin.FrameType.OP_FRAME))
    return model, frame


def test_fk_matches_pinocchio(solved):
    fk = solved[4]
    model, frame = _pinocchio_model()
    data = model.createData()
    worst = 0.0
    for q in np.random.default_rng(11).uniform(LOWER, UPPER, (100, 6)):
        pin.framesForwardKinematics(model, data, q)
        worst = max(worst, np.abs(fk(q) - data.oMf[frame].homogeneous).max())
    assert worst < 1e-12


def _failing(solved, q) -> list[tuple[str, str, str]]:
    """(name, error, message) of the guards that reject pose fk(q) (or q itself when a pose)
    in the configuration of q (+1 where its indicator is 0)."""
    ik, _, guards, ind, fk = solved
    t = q if np.shape(q) == (4, 4) else fk(q)
    cfg = (1, 1, 1) if np.shape(q) == (4, 4) else tuple(np.where(ind(q) >= 0, 1, -1))
    values = guards(list(np.asarray(t)[:3, :].ravel()), cfg)
    return [(g[0], g[2], g[3]) for g, v in zip(ik.guards, values) if v < 0]


def test_guards_name_the_problem(solved):
    fk = solved[4]
    q = np.array([0.4, 0.9, 0.7, 0.3, 0.8, -0.2])
    assert _failing(solved, q) == []
    # the wrist centre on the joint-1 axis: inside the d2 = 0.154 m cylinder, unreachable
    on_axis = fk(q)
    on_axis[:3, 3] = [0.0, 0.0, 1.0]
    [(name, error, message)] = _failing(solved, on_axis)
    assert (name, error) == ("guard_arm_reach", "Unreachable") and "cylinder of radius d2" in message
    # no extension: the wrist centre at the shoulder, theta2 undetermined
    folded = q.copy()
    folded[2] = 0.0
    failing = _failing(solved, folded)
    assert [(n, e) for n, e, _ in failing] == [("guard_boom", "Singular")], failing
    # sin(theta5) = 0: only theta4 + theta6 determined
    flat = q.copy()
    flat[4] = 0.0
    failing = _failing(solved, flat)
    assert [(n, e) for n, e, _ in failing] == [("guard_wrist", "Singular")]
    assert "sin(theta5) = 0" in failing[0][2]


def test_outside_the_class_is_refused_naming_why():
    # the Stanford arm with an offset a3 on the boom: its wrist leaves the boom's axis
    a3 = sp.Symbol("a3", positive=True)
    links = list(STANFORD.links)
    links[2] = DHLink(Q[2], -90 * DEG, 0, a3, prismatic=True)
    r = DHRobot("offset_boom", tuple(links), (d1, d2, a3))
    assert class_reasons(r)["spherical (Stanford class)"] == ["a3 = 0 and alpha3 = 0 (joint 4 on the boom's axis)"]
    with pytest.raises(OutsideClass, match="not spherical .Stanford class.: needs a3 = 0 and alpha3 = 0"):
        solve_ik(r)


@pytest.mark.slow  # derives the whole arm (Jacobians, gravity, kernels: ~25 s)
def test_kernel_pipeline_emits_a_working_module(tmp_path, solved):
    """build_kernels and the Python back end on the Stanford arm: the emitted module's ik,
    ik_all and config_of agree with the symbolic inverse; the runtime's range check is what
    leaves the reversed boom out."""
    import importlib.util
    import warnings

    from derive import emit_python
    from derive.derivation import parallel_23
    from derive.gravity import g0, gravity_model
    from derive.jacobian import differential
    from derive.kernels import Derivation, build_kernels
    from derive.robots import RobotSpec
    from rccl.kinematics import exceptions as errors
    from rccl.kinematics import runtime

    _, joints, _, _, fk = solved
    spec = RobotSpec(name="stanford", dh=STANFORD, params={g0: 9.81, **NUMBERS},
                     kinds=("revolute", "revolute", "prismatic", "revolute", "revolute", "revolute"),
                     lower=tuple(map(float, LOWER)), upper=tuple(map(float, UPPER)),
                     config_fields=("arm", "boom", "wrist"),
                     gravity_coeffs=(), model_path="models/stanford.toml")
    d = Derivation(spec, t6(STANFORD), solve_ik(STANFORD),
                   differential(STANFORD, reduce_23=parallel_23(STANFORD)), gravity_model(spec))
    path = tmp_path / "stanford.py"
    path.write_text(emit_python.module_source(build_kernels(d), spec))
    module_spec = importlib.util.spec_from_file_location("stanford_emitted", path)
    mod = importlib.util.module_from_spec(module_spec)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # no compiled kernels: the Python code
        module_spec.loader.exec_module(mod)
    assert mod.Config is runtime.BoomConfig and len(mod.CONFIGS) == 8
    for q in _random_q(np.random.default_rng(5), 20):
        t = mod.fk(q)
        assert np.abs(t - fk(q)).max() < 1e-13
        sols = mod.ik_all(t)
        assert len(sols) == 4 and all(c.boom == 1 for c, _ in sols)
        for cfg, qs in sols:
            assert np.abs(qs - joints(list(t[:3, :].ravel()), cfg.signs)).max() < 1e-12
            assert mod.config_of(qs) == cfg
            assert np.abs(mod.fk(qs) - t).max() < 1e-13
        with pytest.raises(errors.Unreachable, match="prismatic joint 3 would need"):
            mod.ik(t, runtime.BoomConfig(1, -1, 1))
    # a boom that may run back through the shoulder: the reversed solutions count too
    lower = LOWER.copy()
    lower[2] = -UPPER[2]
    robot = runtime.Robot("stanford", mod._KERNELS, mod.JOINT_KINDS, lower, mod.UPPER, mod.Config,
                          mod.GRAVITY_COEFFS)
    q = np.array([0.4, 0.9, 0.7, 0.3, 0.8, -0.2])
    assert len(robot.ik_all(mod.fk(q))) == 8
    with pytest.raises(errors.Singular, match="sin.theta5. = 0"):
        mod.ik(mod.fk(np.array([0.4, 0.9, 0.7, 0.3, 0.0, -0.2])), mod.Config(-1, 1, 1))
    with pytest.raises(errors.Singular, match="sin.theta2. = 0"):
        mod.joint_from_cartesian(np.array([0.4, 0.0, 0.7, 0.3, 0.8, -0.2]), np.ones(6))
    from derive.crosscheck import conditioning  # the sweep's distance from the singularities

    assert conditioning(mod, np.array([0.4, 0.0, 0.7, 0.3, 0.8, -0.2]))[0] == 0.0
    assert conditioning(mod, np.array([0.4, 0.9, 0.7, 0.3, 0.8, -0.2]))[0] == pytest.approx(0.7)
    # gravity with a prismatic joint (the minimal identifiable set, 4.20) against Pinocchio;
    # masses and centres of mass illustrative
    rng = np.random.default_rng(9)
    masses, coms = rng.uniform(0.5, 9.0, 6), rng.uniform(-0.2, 0.2, (6, 3))
    model, _ = _pinocchio_model(masses, coms)
    data = model.createData()
    coeffs = mod.coefficients_from_links(masses, coms)
    assert mod.GRAVITY_COEFFS == ("cx2", "cz2", "cx4", "cz4", "cx5", "cz5", "cx6", "cy6", "cm3")
    for q in rng.uniform(LOWER, UPPER, (20, 6)):
        g = pin.computeGeneralizedGravity(model, data, q)
        assert np.abs(mod.gravity_links(q, masses, coms) - g).max() < 1e-12
        assert np.abs(mod.gravity(q, coeffs) - g).max() < 1e-12
        assert np.abs(mod.jacobian6(q) - _pinocchio_jacobian6(q)).max() < 1e-12


def _pinocchio_jacobian6(q) -> np.ndarray:
    """6J: link 6's motion observed in frame 6 (Pinocchio's LOCAL frame Jacobian)."""
    model, frame = _pinocchio_model()
    data = model.createData()
    return pin.computeFrameJacobian(model, data, q, frame, pin.ReferenceFrame.LOCAL)


@pytest.mark.slow  # a second derivation of the class (~6 s)
def test_variant_without_shoulder_offset_and_with_d4():
    """d2 = 0: every wrist centre off the joint-1 axis is reachable and the axis itself is a
    singularity (theta1 undetermined), not a cylinder the arm cannot enter; d4 = 0.1 m: the
    wrist centre 0.1 m beyond the boom's zero, the boom's length q3 + d4."""
    d4 = sp.Symbol("d4", positive=True)
    links = list(STANFORD.links)
    links[1] = DHLink(0, Q[1], 90 * DEG, 0)
    links[3] = DHLink(d4, Q[3], -90 * DEG, 0)
    r = DHRobot("stanford_variant", tuple(links), (d1, d4))
    ik = solve_ik(r)
    assert [(g[0], g[2]) for g in ik.guards] == [("guard_axis", "Singular"), ("guard_boom", "Singular"),
                                                  ("guard_wrist", "Singular")]
    pose, par, vals = list(POSE[:3, :]), [d1, d4], [0.412, 0.1]
    joints = sp.lambdify([pose, ik.config, par], list(ik.joints), "math", cse=True)
    guards = sp.lambdify([pose, ik.config, par], [g[1] for g in ik.guards], "numpy", cse=True)
    ind = sp.lambdify([Q[:6], par], list(ik.indicators), "math", cse=True)
    fk = sp.lambdify([Q[:6], par], t6(r), "numpy", cse=True)
    for q in _random_q(np.random.default_rng(2), 10):
        t = np.array(fk(q, vals))
        own = tuple(int(s) for s in np.sign(ind(q, vals)))
        assert own[1] == 1  # q3 + d4 > 0
        for cfg in CONFIGS:
            qs = np.array(joints(list(t[:3, :].ravel()), cfg, vals))
            assert np.abs(np.array(fk(qs, vals)) - t).max() < 1e-12
            assert tuple(int(s) for s in np.sign(ind(qs, vals))) == cfg
            if cfg == own:
                d = qs - q
                d[REVOLUTE] = _wrap(d[REVOLUTE])
                assert np.abs(d).max() < 1e-9
    # the first guard that fails names the problem (the later ones may be NaN there)
    t[:3, 3] = [0.0, 0.0, 1.0]  # above the shoulder, on the joint-1 axis
    with np.errstate(all="ignore"):
        values = guards(list(t[:3, :].ravel()), (1, 1, 1), vals)
    assert values[0] < 0
    # q3 = -d4: the wrist centre at the shoulder, 0.412 m above the base on the joint-1 axis;
    # off the axis by 1 mm the boom's length is 1 mm
    t[:3, 3] = [0.0, 0.0, 0.412]
    with np.errstate(all="ignore"):
        values = guards(list(t[:3, :].ravel()), (1, 1, 1), vals)
    assert values[0] < 0
    t[:3, 3] = [1e-3, 0.0, 0.412]
    with np.errstate(all="ignore"):
        values = guards(list(t[:3, :].ravel()), (1, 1, 1), vals)
    assert values[0] >= 0 and values[1] >= 0
    q = np.array([0.4, 0.9, -0.1, 0.3, 0.8, -0.2])
    assert np.abs(np.array(fk(q, vals))[:3, 3] - [0.0, 0.0, 0.412]).max() < 1e-15
