"""Unit tests of rccl.adaptive's pure parts: force estimation (4.37, 4.56), deviation (E.2), limits,
monitors, comply joint selection and servo law (E.6, 4.38), functional-transform limiting (E.8)."""
from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

from rccl.adaptive.comply import Compliance, select_joints, servo_dac
from rccl.adaptive.deviation import deviation, tool_to_frame6
from rccl.adaptive.exceptions import ForceEstimateError, FunctionalError, MonitorError, SpecError
from rccl.adaptive.force import ForceEstimator, JointModel
from rccl.adaptive.functional import FunctionalUpdater, differential, interpolate, step_scale
from rccl.adaptive.limit import Limit
from rccl.adaptive.monitor import Monitor, Sample
from rccl.kinematics import puma260 as kin
from rccl.position import EQ, TL, makeposition
from rccl.transform import T6, Trsf, diff_map, inverse, trsl
from rcci.models import load_robot

PUMA = load_robot("puma260")
MODEL = JointModel.for_robot("puma260")
PM = pin.buildModelFromUrdf(str(PUMA.urdf_path))
PD = PM.createData()
TOOL = trsl(0.0, 0.0, 0.05)                 # a 5 cm probe along z6
RNG = np.random.default_rng(7)


def random_q(n):
    """Configurations inside the joint ranges, away from the wrist singularity."""
    out = []
    while len(out) < n:
        q = RNG.uniform(PUMA.lower, PUMA.upper)
        if abs(math.sin(q[4])) > 0.3 and np.linalg.cond(kin.jacobian6(q)) < 200:
            out.append(q)
    return out


def pin_tool_point(q):
    """Tool point and its base-frame 3x6 Jacobian, by Pinocchio on the URDF (independent of the generated code)."""
    fid = PM.getFrameId("link6")
    pin.forwardKinematics(PM, PD, q)
    pin.updateFramePlacements(PM, PD)
    m = PD.oMf[fid]
    j = pin.computeFrameJacobian(PM, PD, q, fid, pin.LOCAL_WORLD_ALIGNED)
    r = m.rotation @ TOOL[:3, 3]
    return m.translation + r, m.rotation, j[:3] + np.cross(j[3:].T, r).T


# --- force estimation -------------------------------------------------------------------
@pytest.mark.parametrize("q", random_q(20))
def test_tool_force_recovers_a_point_force_applied_through_pinocchio(q):
    est = ForceEstimator(kin, MODEL)
    f_world = RNG.normal(size=3) * 10.0                     # N the tool exerts, base frame
    _, rot6, jp = pin_tool_point(q)
    t_a = jp.T @ f_world                                     # 4.52 by Pinocchio
    f_tool = est.tool_force(q, t_a, TOOL)
    r_tool = rot6 @ TOOL[:3, :3]
    np.testing.assert_allclose(f_tool[:3], r_tool.T @ f_world, atol=1e-8)
    np.testing.assert_allclose(f_tool[3:], 0.0, atol=1e-8)   # a pure force at the tool origin


def test_net_torques_inverts_adc_with_gravity_and_friction():
    est = ForceEstimator(kin, MODEL)
    q = random_q(1)[0]
    qd = np.array([0.2, -0.1, 0.0, 0.3, -0.05, 0.0])
    t_a = np.array([0.5, -1.0, 0.3, 0.02, -0.01, 0.005])
    t_g = kin.gravity(q, MODEL.gravity_coeffs)
    adc = MODEL.conv.joint_torques_to_adc(t_a + t_g + MODEL.friction(qd))
    np.testing.assert_allclose(est.net_torques(q, qd, adc), t_a, atol=1e-9)


def test_force_estimate_refused_at_a_singularity():
    q = np.array(PUMA.poses["ready"], float)
    q[4] = 0.0                                               # wrist singular: theta5 = 0
    with pytest.raises(ForceEstimateError, match="condition number"):
        ForceEstimator(kin, MODEL).tool_force(q, np.ones(6), TOOL)


def test_force_bound_is_the_worst_case_of_torque_errors():
    q = random_q(1)[0]
    est = ForceEstimator(kin, MODEL)
    err = MODEL.coulomb_uncertainty()
    bound = est.force_bound(kin.jacobian6(q), TOOL, err)
    for _ in range(200):
        dt = RNG.uniform(-1, 1, 6) * err
        assert np.all(np.abs(est.tool_force(q, dt, TOOL, check=False)) <= bound + 1e-12)


# --- deviation ----------------------------------------------------------------------------
@pytest.mark.parametrize("q", random_q(10))
def test_deviation_matches_the_tool_frame_displacement(q):
    dq = RNG.normal(size=6) * 1e-5
    x0 = kin.fk(q) @ TOOL
    x1 = kin.fk(q + dq) @ TOOL
    dev = deviation(kin.jacobian6(q), dq, TOOL)
    np.testing.assert_allclose(dev, differential(x0, x1), atol=1e-8)
    # and back: tool_to_frame6 inverts the map
    np.testing.assert_allclose(tool_to_frame6(TOOL) @ diff_map(TOOL) @ dev, dev, atol=1e-12)


# --- limits -------------------------------------------------------------------------------
def test_limit_parse_and_check():
    lim = Limit.parse("fz, dx", 10.0, 0.005)
    assert lim.needs_force and lim.needs_deviation
    assert lim.check(np.array([50, 50, 9.9, 5, 5, 5]), np.array([0.004, 1, 1, 1, 1, 1])) is None
    end = lim.check(np.array([0, 0, -10.5, 0, 0, 0]), np.zeros(6), t=1.5, sample=54)
    assert (end.reason, end.what, end.value, end.bound, end.sample) == ("limit", "fz", -10.5, 10.0, 54)
    assert lim.check(np.zeros(6), np.array([-0.006, 0, 0, 0, 0, 0])).what == "dx"
    assert lim.check(np.array([0, 0, np.nan, 0, 0, 0]), None).what == "fz"   # NaN never passes silently
    assert not Limit.parse("rx", 0.1).needs_force


@pytest.mark.parametrize("spec,values,match", [
    ("fq", (1.0,), "not a tool-frame component"),
    ("fz dx", (1.0,), "2 component"),
    ("fz", (-1.0,), "positive"),
    ("fz", (float("nan"),), "positive"),
    ("fz fz", (1.0, 2.0), "twice"),
    ("", (), "empty"),
    (3, (1.0,), "must be a string"),
    ("fz", ("a lot",), "not a number"),
])
def test_limit_rejects_bad_specs(spec, values, match):
    with pytest.raises(SpecError, match=match):
        Limit.parse(spec, *values)


# --- monitors -----------------------------------------------------------------------------
def _sample():
    z = np.zeros(6)
    return Sample(t=0.5, sample=18, q=z, qd=z, q_command=z, torque=None, force=None, deviation=None)


def test_monitor_codes():
    assert Monitor(lambda s: None)(_sample()) is None
    assert Monitor(lambda s: 0)(_sample()) is None
    assert Monitor(lambda s: False)(_sample()) is None

    def found_it(s):
        return "seen" if s.sample >= 18 else None

    end = Monitor(found_it)(_sample())
    assert (end.reason, end.what, end.code, end.sample) == ("monitor", "found_it", "seen", 18)
    with pytest.raises(MonitorError, match="raised ZeroDivisionError"):
        Monitor(lambda s: 1 / 0)(_sample())
    with pytest.raises(MonitorError, match="NaN"):
        Monitor(lambda s: float("nan"))(_sample())
    with pytest.raises(MonitorError, match="not callable"):
        Monitor(3)


# --- compliance ---------------------------------------------------------------------------
def test_comply_selects_the_joint_with_the_largest_share():
    q = np.array(PUMA.poses["ready"], float) + np.array([0.1, 0.2, -0.3, 0.2, 0.4, 0.1])
    jt = diff_map(TOOL) @ kin.jacobian6(q)
    shares = jt * np.linalg.inv(jt).T                        # [i, j] = J[i, j] Jinv[j, i]
    np.testing.assert_allclose(shares.sum(axis=1), 1.0, atol=1e-9)
    sel = select_joints(jt, [2])
    assert sel[2] == int(np.argmax(np.abs(shares[2])))
    sel2 = select_joints(jt, [0, 1, 2, 3, 4, 5])
    assert sorted(sel2.values()) == list(range(6))           # each joint at most once


def test_comply_lock_and_offsets():
    c = Compliance()
    c.comply("fz mx", -8.0, 0.0)
    assert c.forces == {2: -8.0, 3: 0.0} and c.active
    c.absorb(np.array([0.1, 0.2, 0.003, 0.01, 0.02, 0.03]))
    np.testing.assert_allclose(c.offset, [0, 0, 0.003, 0.01, 0, 0])
    c.lock("mx")
    assert c.forces == {2: -8.0}
    c.absorb(np.array([0, 0, 0.004, 0.5, 0, 0]))
    np.testing.assert_allclose(c.offset, [0, 0, 0.004, 0.01, 0, 0])   # locked axis keeps its offset
    q = random_q(1)[0]
    j6 = kin.jacobian6(q)
    dq = c.joint_offsets(j6, tool_to_frame6(TOOL))
    np.testing.assert_allclose(deviation(j6, dq, TOOL), c.offset, atol=1e-12)
    with pytest.raises(SpecError):
        c.comply("dz", 1.0)                                  # only forces/torques can comply
    with pytest.raises(SpecError):
        c.lock("fw")


def test_servo_dac_is_4_38_for_the_chosen_joint():
    q = random_q(1)[0]
    jt = diff_map(TOOL) @ kin.jacobian6(q)
    c = Compliance()
    c.comply("fz", 12.0)
    joint = c.select(jt)[2]
    t_a = c.net_torques(jt)
    t_g = kin.gravity(q, MODEL.gravity_coeffs)
    for qd_j, sign in ((0.0, np.sign(t_a[joint])), (0.3, 1.0), (-0.3, -1.0)):
        qd = np.zeros(6)
        qd[joint] = qd_j
        dac = servo_dac(MODEL, [joint], t_a, t_g, qd)
        # back through the conversions: the joint torque the DAC commands (others at gravity only)
        tj = MODEL.conv.dac_to_joint_torques(dac)
        fr = MODEL.friction(qd)[joint] if qd_j else sign * (MODEL.coulomb_pos if sign > 0 else MODEL.coulomb_neg)[joint]
        assert tj[joint] == pytest.approx(t_a[joint] + t_g[joint] + fr, abs=1e-9)


# --- functional transforms ------------------------------------------------------------------
def test_functional_called_once_per_sample_even_in_two_positions():
    calls = []

    def f(t):
        calls.append(1)
        t.p = t.p + np.array([0.001, 0, 0])

    t = Trsf.trsl("T", 0.2, 0.0, 0.2, kind="variable")
    t.bind(f)
    b = Trsf.rot("B", "y", math.pi)
    p1 = makeposition("P1", t, T6, EQ, b, TL, T6)
    p2 = makeposition("P2", T6, EQ, t, b, TL, T6)
    up = FunctionalUpdater(np.full(6, 2.0), 1 / 36)
    up.update([p1, p2, p1], None)
    assert len(calls) == 1


def test_functional_change_is_limited_through_the_jacobian():
    q = np.array(PUMA.poses["ready"], float) + np.array([0.1, 0.2, -0.3, 0.2, 0.4, 0.1])
    t6 = kin.fk(q)
    t = Trsf("T", t6, kind="variable")

    def wild(tr):
        tr.p = tr.p + np.array([0.5, 0.0, 0.0])          # 50 cm in one sample

    t.bind(wild)
    pos = makeposition("P", T6, EQ, t, TL, T6)
    vmax = np.array(PUMA.max_velocity, float)
    dt = 1 / 36
    up = FunctionalUpdater(vmax, dt, share=0.5)
    j6 = kin.jacobian6(q)
    info = up.update([pos], j6)
    assert 0 < info.scale < 0.1 and up.limited == 1
    dc = differential(t6, pos.solve())
    dtheta = np.linalg.solve(j6, dc)
    assert np.max(np.abs(dtheta) / (0.5 * vmax * dt)) == pytest.approx(1.0, rel=0.05)
    # a gentle change passes untouched
    t.bind(lambda tr: tr.set(tr.matrix @ trsl(1e-5, 0, 0)))
    before = t.matrix.copy()
    info = up.update([pos], j6)
    assert info.scale == 1.0
    np.testing.assert_allclose(t.matrix, before @ trsl(1e-5, 0, 0), atol=1e-15)


def test_functional_refused_near_singularity_and_bad_values():
    q = np.array(PUMA.poses["ready"], float)
    q[4] = 1e-9
    t = Trsf("T", kin.fk(q), kind="variable")
    t.bind(lambda tr: tr.set(tr.matrix @ trsl(0.001, 0, 0)))
    pos = makeposition("P", T6, EQ, t, TL, T6)
    before = t.matrix.copy()
    info = FunctionalUpdater(np.full(6, 2.0), 1 / 36).update([pos], kin.jacobian6(q))
    assert info.scale == 0.0
    np.testing.assert_allclose(t.matrix, before)

    def broken(tr):
        raise KeyError("sensor 3")

    t.bind(broken)
    with pytest.raises(FunctionalError, match="'T'.*KeyError"):
        FunctionalUpdater(np.full(6, 2.0), 1 / 36).update([pos], None)


def test_interpolate_and_step_scale():
    m0 = Trsf.rpy("A", 0.1, 0.2, 0.3, 0.4, 0.5, 0.6).matrix.copy()
    m1 = Trsf.rpy("B", 0.2, 0.1, 0.3, 0.1, 0.7, 0.2).matrix.copy()
    np.testing.assert_allclose(interpolate(m0, m1, 0.0), m0, atol=1e-12)
    np.testing.assert_allclose(interpolate(m0, m1, 1.0), m1, atol=1e-12)
    half = interpolate(m0, m1, 0.5)
    np.testing.assert_allclose(interpolate(m0, half, 2.0), m1, atol=1e-12)
    j = np.eye(6)
    s, dth = step_scale(j, np.array([0.2, 0, 0, 0, 0, 0.05]), np.full(6, 0.1))
    assert s == pytest.approx(0.5) and dth[0] == pytest.approx(0.2)
    assert inverse(m0) @ m0 == pytest.approx(np.eye(4))


def test_conditional_matching():
    from rccl.conditional import Conditional, choose
    from rccl.ending import MotionEnd

    end = MotionEnd("limit", "fz", 12.0, 10.0)
    branches = [Conditional("dz", "A"), Conditional("fz", "B"), Conditional("limit", "C")]
    assert choose(branches, end).request == "B"
    assert choose([Conditional("monitor", "A")], end) is None
    assert choose([Conditional(lambda e: e.value > 11, "D")], end).request == "D"
    assert Conditional("7", "E").matches(MotionEnd("monitor", "m", code=7))
    from rccl.exceptions import BadRequest
    with pytest.raises(BadRequest, match="cond: the condition must be a string"):
        Conditional(3, "F")


def test_locked_offsets_return_to_the_path_at_bounded_speed():
    from rccl.adaptive.comply import RETURN_SPEED

    c = Compliance()
    c.comply("fz fx", 5.0, 1.0)
    c.absorb(np.array([0.004, 0.0, -0.012, 0.0, 0.0, 0.0]))
    c.lock("fz")
    dt = 1 / 36
    steps = 0
    while c.offset[2] != 0.0:
        before = c.offset[2]
        c.release(dt)
        assert abs(c.offset[2] - before) <= RETURN_SPEED[2] * dt + 1e-15
        steps += 1
    assert steps == int(np.ceil(0.012 / (RETURN_SPEED[2] * dt)))
    assert c.offset[0] == 0.004                                   # still compliant: untouched


def test_functional_jump_is_spread_with_bounded_acceleration():
    q = np.array(PUMA.poses["ready"], float) + np.array([0.1, 0.2, -0.3, 0.2, 0.4, 0.1])
    t6 = kin.fk(q)
    target = t6 @ trsl(0.03, 0.0, 0.0)                       # the function jumps 3 cm at once and stays
    t = Trsf("T", t6, kind="variable")
    t.bind(lambda tr: tr.set(target))
    pos = makeposition("P", T6, EQ, t, TL, T6)
    vmax = np.array(PUMA.max_velocity, float)
    amax = vmax / 0.25
    dt = 1 / 36
    up = FunctionalUpdater(vmax, dt, share=0.5, qdd_max=amax)
    j6 = kin.jacobian6(q)
    steps = []
    prev = pos.solve()
    for _ in range(60):
        up.update([pos], j6)
        now = pos.solve()
        steps.append(np.linalg.solve(j6, differential(prev, now)))
        prev = now
    steps = np.array(steps)
    np.testing.assert_allclose(pos.solve(), target, atol=1e-9)               # it got there
    assert np.all(np.abs(steps) <= 0.5 * vmax * dt + 1e-9)                    # velocity share
    dv = np.abs(np.diff(np.vstack([np.zeros(6), steps]), axis=0))
    ratio = dv / (0.5 * amax * dt ** 2)
    assert ratio.max() <= 1.1, ratio.max(axis=1)   # share of the acceleration limit (E.8 is first order)


def test_functional_refuses_a_non_finite_value_set_behind_the_setters():
    t = Trsf("T", trsl(0.1, 0.0, 0.0), kind="variable")
    pos = makeposition("P", T6, EQ, t, Trsf("X", trsl(0.2, 0.0, 0.3)), TL, T6)

    def sneaky(tr):
        m = np.eye(4)
        m[0, 3] = np.nan
        tr._m = m                      # bypasses Trsf.set's checks

    t.bind(sneaky)
    q = np.radians([10.0, 80.0, -170.0, 10.0, -60.0, 5.0])
    for jac in (None, kin.jacobian6(q)):
        with pytest.raises(FunctionalError, match="'T'.*non-finite"):
            FunctionalUpdater(np.full(6, 2.0), 1 / 36).update([pos], jac)
        t._m = trsl(0.1, 0.0, 0.0)


def test_control_fast_path_matches_the_reference_force_estimate_and_condition():
    """AdaptiveControl's per-sample path (kernel inverse, 1-norm condition, J^-T through it) gives the
    force ForceEstimator.tool_force gives, and its condition is cond_1 by numpy."""
    from rccl.adaptive.control import AdaptiveControl
    from rccl.adaptive.force import condition_1
    from rccl.adaptive.generator import AdaptiveGenerator
    from rccl.limits import load_limits
    from rccl.planner import Planner
    from rccl.session import load_kinematics

    k = load_kinematics("puma260")
    q0 = np.radians([10.0, 80.0, -170.0, 10.0, -60.0, 5.0])
    gen = AdaptiveGenerator(k, load_limits("puma260"), 1 / 36, q0)
    ctl = AdaptiveControl(k.module, MODEL)
    arm = Planner(k, load_limits("puma260"), gen)
    tool = Trsf("TOOL", TOOL)
    target = kin.fk(q0) @ TOOL
    target[0, 3] += 0.03
    seen = []
    gen.queue.pending.append(Limit.parse("fz", 1e6))
    gen.queue.pending.append(Monitor(lambda s: seen.append(s) and None, ("force",)))
    arm.setmod("cartesian")
    arm.move(makeposition("P", T6, tool, EQ, Trsf("X", target), TL, tool))
    est = ForceEstimator(kin, MODEL)
    for _ in range(20):
        q = gen.q + RNG.normal(0, 1e-4, 6)
        adc = MODEL.conv.joint_torques_to_adc(kin.gravity(q, MODEL.gravity_coeffs) + RNG.normal(0, 0.3, 6))
        ctl.before(gen, q, np.zeros(6), adc)
        gen.step()
        ctl.after(gen.q)
    assert len(seen) >= 15
    for s in seen[-5:]:
        ref = est.tool_force(s.q, s.torque, TOOL)
        np.testing.assert_allclose(s.force, ref, atol=1e-9)
    j = kin.jacobian6(seen[-1].q)
    assert ctl.condition == pytest.approx(float(np.linalg.norm(j, 1) * np.linalg.norm(np.linalg.inv(j), 1)))
    assert condition_1(j, np.linalg.inv(j)) == pytest.approx(ctl.condition)


class WaistPast:
    """A motion check of the test's own (not one of the thesis's): ends the motion once joint 1 passes an angle."""

    from rccl.adaptive.check import Estimate
    estimates = Estimate.NONE

    def __init__(self, angle: float) -> None:
        self.angle = angle
        self.seen: list[Sample] = []

    def ends(self, s: Sample):
        from rccl.ending import MotionEnd
        self.seen.append(s)
        if s.q[0] > self.angle:
            return MotionEnd("monitor", "waist past", code=7, t=s.t, sample=s.sample)
        return None


def test_a_new_motion_check_plugs_in_through_the_protocol_alone():
    """A class with ``estimates`` and ``ends`` is attached to the next motion and ends it; nothing
    it did not ask for is estimated; objects that are not checks are refused by name."""
    from rccl.adaptive.check import MotionCheck, as_check
    from rccl.adaptive.control import AdaptiveControl
    from rccl.adaptive.generator import AdaptiveGenerator
    from rccl.limits import load_limits
    from rccl.planner import Planner
    from rccl.session import load_kinematics

    k = load_kinematics("puma260")
    q0 = np.radians([10.0, 80.0, -170.0, 10.0, -60.0, 5.0])
    gen = AdaptiveGenerator(k, load_limits("puma260"), 1 / 36, q0)
    ctl = AdaptiveControl(k.module, MODEL)
    arm = Planner(k, load_limits("puma260"), gen)
    check = WaistPast(q0[0] + math.radians(5.0))
    assert isinstance(check, MotionCheck)
    gen.queue.pending.append(check)
    req = arm.move(makeposition("P", T6, EQ, Trsf("X", kin.fk(q0 + np.radians([20.0, 0, 0, 0, 0, 0]))), TL, T6))
    for _ in range(36 * 5):
        ctl.before(gen, gen.q.copy(), np.zeros(6), np.zeros(6))
        gen.step()
        if req.status in ("done", "failed"):
            break
    assert req.checks == [check]
    assert req.ended is not None and req.ended.what == "waist past" and req.ended.code == 7
    assert check.seen[-1].q[0] > check.angle >= check.seen[-2].q[0]       # ended on the first sample past
    assert all(s.torque is None and s.force is None and s.deviation is None for s in check.seen)
    with pytest.raises(SpecError, match="not a motion check"):
        as_check(object(), "add_check()")

    class Greedy(WaistPast):
        estimates = frozenset({"jerk"})

    with pytest.raises(SpecError, match=r"Greedy.estimates is frozenset\(\{'jerk'\}\), not an rccl.adaptive.check.Estimate"):
        as_check(Greedy(0.0), "add_check()")
