"""Redundancy in RCCL (rccl.redundancy): the free parameter's rules and self-motion, on pure math.

The arm is tests/redundancy_standin.py, a numeric Panda (its published modified-DH table,
checked here against Pinocchio on models/urdf/panda.urdf); both generators run offline, one
``step()`` per sample, as the RCCL unit tests do. The simula runs are in
tests/test_redundancy_simula.py.

Tolerances: the stand-in's inverse kinematics reproduces T6 to 1e-13 (its Newton stop), so a
commanded tool point lies on the straight line to 1e-9 m with the quartic generator (its
Cartesian segment and the transitions from and to rest are poses on the line); Ruckig's
phase-synchronised profile keeps its 6-vector on a line to its own arithmetic, 1e-7 m here.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from rccl import redundancy
from rccl.exceptions import BadRequest, SingularPath, UnreachableTarget
from rccl.jerk import JerkLimitedGenerator
from rccl.planner import Planner
from rccl.position import EQ, TL, makeposition
from rccl.segments import Kinematics
from rccl.trajectory import TrajectoryGenerator
from rccl.transform import T6, Trsf
from tests import redundancy_standin as P

DT = 1.0 / 36.0
GENERATORS = {"quartic": TrajectoryGenerator, "ruckig": JerkLimitedGenerator}
LINE_TOL = {"quartic": 1e-9, "ruckig": 1e-7}
OFFSET = np.array([0.10, 0.05, -0.05])     # m: the straight line from the ready pose's flange


def planner(kind: str, q0=P.READY) -> tuple[Planner, Kinematics]:
    kin = Kinematics(P)
    gen = GENERATORS[kind](kin, P.limits(), DT, np.array(q0, dtype=float))
    return Planner(kin, P.limits(), gen), kin


def run(pl: Planner, request, samples: int = 400) -> np.ndarray:
    """Step the generator until ``request`` is done (and a few samples on): the commanded joints."""
    out = []
    for _ in range(samples):
        out.append(pl.gen.step())
        if request.status != "queued" and request.status != "running" and len(out) > 10:
            break
    pl.check()
    assert request.status == "done", request.error
    return np.array(out)


def line_target(q0=P.READY) -> tuple[np.ndarray, np.ndarray]:
    t0 = P.fk(q0)
    t1 = t0.copy()
    t1[:3, 3] += OFFSET
    return t0, t1


def distance_to_line(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    u = (b - a) / np.linalg.norm(b - a)
    rel = points - a
    return np.linalg.norm(rel - np.outer(rel @ u, u), axis=1)


def cartesian_line(kind: str, **free) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    pl, _ = planner(kind)
    t0, t1 = line_target()
    pl.setmod("c")
    pl.setvel(0.1, 0.5)
    if free:
        pl.setfree(**free)
    qs = run(pl, pl.move(makeposition("B", T6, EQ, Trsf("B", t1), TL, T6)))
    pts = np.array([P.fk(q)[:3, 3] for q in qs])
    return qs, pts, t1


# -- the stand-in is the Panda --------------------------------------------------------------
def test_standin_is_the_panda_of_the_urdf():
    pin = pytest.importorskip("pinocchio")
    from pathlib import Path
    urdf = Path(__file__).resolve().parent.parent / "models" / "urdf" / "panda.urdf"
    model = pin.buildModelFromUrdf(str(urdf))
    data = model.createData()
    fid = model.getFrameId("link7")
    rng = np.random.default_rng(7)
    for _ in range(20):
        q = rng.uniform(P.LOWER, P.UPPER)
        pin.framesForwardKinematics(model, data, q)
        assert np.allclose(data.oMf[fid].homogeneous, P.fk(q), atol=1e-9)


# -- the rules' math ------------------------------------------------------------------------
def test_min_jerk_ramp_ends_at_rest():
    assert redundancy.min_jerk(0.0) == 0.0 and redundancy.min_jerk(1.0) == 1.0
    assert redundancy.min_jerk(-1.0) == 0.0 and redundancy.min_jerk(2.0) == 1.0
    h = 1e-5
    for s in (h, 1.0 - h):   # zero slope at both ends
        assert abs(redundancy.min_jerk(s + h) - redundancy.min_jerk(s - h)) / (2 * h) < 1e-3
    assert redundancy.min_jerk(0.5) == pytest.approx(0.5)
    assert (redundancy.min_jerk(0.5 + h) - redundancy.min_jerk(0.5 - h)) / (2 * h) == pytest.approx(1.875)


def test_limit_cost_is_zero_mid_range_and_one_on_the_limits():
    lo, hi = P.LOWER, P.UPPER
    assert redundancy.limit_cost((lo + hi) / 2, lo, hi) == pytest.approx(0.0, abs=1e-15)
    assert redundancy.limit_cost(hi, lo, hi) == pytest.approx(1.0)
    assert redundancy.limit_cost(lo, lo, hi) == pytest.approx(1.0)


def test_cost_grows_without_bound_towards_a_singularity():
    # from the ready pose, q4 from -2.5 towards -0.467 rad stretches the elbow (with the Panda's
    # 0.0825 m offsets it is straight there: the Jacobian loses rank)
    q = P.READY.copy()
    sig, costs = [], []
    for q4 in np.linspace(-2.5, -0.467, 40):
        q[3] = q4
        j = P.jacobian6(q)
        sig.append(redundancy.sigma_min(j))
        costs.append(redundancy.cost(q, j, P.LOWER, P.UPPER))
    assert sig[-1] < 1e-5
    assert costs[-1] > 1e6 * costs[0]
    assert np.all(np.diff(costs[-10:]) > 0)     # rising all the way into it
    j = P.jacobian6(P.READY)
    j[:, 1] = j[:, 0]                      # two equal columns and a 7th: still rank 6 ...
    j[:, 2] = j[:, 0]                      # ... three equal: rank 5, sigma_min 0
    assert redundancy.sigma_min(j) < 1e-12


def test_setfree_parses_each_rule_and_names_bad_input():
    lo, hi = P.LOWER, P.UPPER
    assert redundancy.rule_of(q7=0.3, lower=lo, upper=hi) == redundancy.Hold(0.3)
    assert redundancy.rule_of(lower=lo, upper=hi) is redundancy.DEFAULT
    assert redundancy.rule_of("hold", lower=lo, upper=hi) is redundancy.DEFAULT
    assert isinstance(redundancy.rule_of(q7=math.sin, lower=lo, upper=hi), redundancy.FollowTime)
    far = redundancy.rule_of("far", lower=lo, upper=hi, step=0.01)
    assert isinstance(far, redundancy.FarFromLimits) and far.step == 0.01
    with pytest.raises(BadRequest, match="joint 7's range"):
        redundancy.rule_of(q7=3.5, lower=lo, upper=hi)
    with pytest.raises(BadRequest, match="not a rule"):
        redundancy.rule_of("nearest", lower=lo, upper=hi)
    with pytest.raises(BadRequest, match="either a rule name or q7"):
        redundancy.rule_of("far", q7=0.1, lower=lo, upper=hi)
    with pytest.raises(BadRequest, match="step"):
        redundancy.rule_of("far", lower=lo, upper=hi, step=2.0)


def test_a_six_joint_arm_refuses_setfree_and_selfmove():
    from rccl.kinematics import load
    from rccl.limits import load_limits
    kin, lim = Kinematics(load("puma260")), load_limits("puma260")
    pl = Planner(kin, lim, TrajectoryGenerator(kin, lim, DT, np.zeros(6)))
    with pytest.raises(BadRequest, match="6 joints and no free parameter"):
        pl.setfree(q7=0.1)
    with pytest.raises(BadRequest, match="no self-motion"):
        pl.selfmove(q7=0.1, duration=1.0)


def test_the_binding_compares_as_its_arm_configuration():
    cfg = P.config_of(P.READY)
    b = redundancy.bind(cfg, None, P.READY, "here")
    assert b == cfg and hash(b) == hash(cfg) and b.rule is redundancy.DEFAULT
    assert redundancy.arm_of(b) is cfg and redundancy.arm_of(cfg) is cfg


# -- a Cartesian straight line with each rule, both generators -----------------------------
@pytest.mark.parametrize("kind", GENERATORS)
def test_line_with_the_default_rule_holds_q7(kind):
    qs, pts, t1 = cartesian_line(kind)
    assert np.max(distance_to_line(pts, P.fk(P.READY)[:3, 3], t1[:3, 3])) < LINE_TOL[kind]
    assert np.allclose(pts[-1], t1[:3, 3], atol=1e-9)
    assert np.all(qs[:, 6] == P.READY[6])             # held exactly: the same float every sample
    assert all(P.limits().out_of_range(q) is None for q in qs)


@pytest.mark.parametrize("kind", GENERATORS)
def test_line_with_q7_held_at_a_value(kind):
    qs, pts, t1 = cartesian_line(kind, q7=float(P.READY[6]))
    assert np.max(distance_to_line(pts, P.fk(P.READY)[:3, 3], t1[:3, 3])) < LINE_TOL[kind]
    assert np.max(np.abs(qs[:, 6] - P.READY[6])) == 0.0


@pytest.mark.parametrize("kind", GENERATORS)
def test_line_with_q7_a_function_of_time(kind):
    q70 = float(P.READY[6])

    def q7(t: float) -> float:
        return q70 + 0.2 * math.sin(1.5 * t)

    qs, pts, t1 = cartesian_line(kind, q7=q7)
    assert np.max(distance_to_line(pts, P.fk(P.READY)[:3, 3], t1[:3, 3])) < LINE_TOL[kind]
    assert np.allclose(pts[-1], t1[:3, 3], atol=1e-9)
    # while the motion runs, sample k after its first is at t = k dt: q7 = f(k dt)
    moving = np.nonzero(np.abs(qs[:, 6] - q70) > 0)[0]
    first = moving[0] - 1                     # the first sample, f(0) = q70
    k = np.arange(first, first + 20)
    assert np.allclose(qs[k, 6], [q7((i - first) * DT) for i in k], atol=1e-12)
    assert all(P.limits().out_of_range(q) is None for q in qs)


@pytest.mark.parametrize("kind", GENERATORS)
def test_line_far_from_limits_moves_q7_continuously_and_lowers_the_cost(kind):
    qs, pts, t1 = cartesian_line(kind, spec="far")
    assert np.max(distance_to_line(pts, P.fk(P.READY)[:3, 3], t1[:3, 3])) < LINE_TOL[kind]
    steps = np.abs(np.diff(qs[:, 6]))
    assert np.max(steps) <= redundancy.FAR_STEP + 1e-12      # continuous: at most one step per sample
    assert np.max(steps) > 0                                  # it did choose
    hold, _, _ = cartesian_line(kind)
    c = [redundancy.cost(q, P.jacobian6(q), P.LOWER, P.UPPER) for q in (hold[-1], qs[-1])]
    assert c[1] < c[0]                          # ends cheaper than holding q7 over the same line
    assert all(P.limits().out_of_range(q) is None for q in qs)


def test_a_rule_that_would_jump_q7_is_refused_before_the_move():
    pl, _ = planner("quartic")
    _, t1 = line_target()
    pl.setmod("c")
    pl.setfree(q7=0.3)
    with pytest.raises(BadRequest, match="q7 cannot jump: selfmove"):
        pl.move(makeposition("B", T6, EQ, Trsf("B", t1), TL, T6))


def test_joint_mode_goes_to_the_held_q7():
    pl, _ = planner("quartic")
    _, t1 = line_target()
    pl.setfree(q7=0.5)
    qs = run(pl, pl.move(makeposition("B", T6, EQ, Trsf("B", t1), TL, T6)))
    assert qs[-1][6] == pytest.approx(0.5, abs=1e-12)
    assert np.allclose(P.fk(qs[-1]), t1, atol=1e-9)


# -- self-motion ----------------------------------------------------------------------------
@pytest.mark.parametrize("kind", GENERATORS)
def test_selfmove_keeps_the_tool_still_while_q7_moves(kind):
    pl, _ = planner(kind)
    t0 = P.fk(P.READY)
    qs = run(pl, pl.selfmove(q7=0.3, duration=1.5))
    poses = np.array([P.fk(q) for q in qs])
    assert np.max(np.abs(poses - t0)) < 1e-9          # the stand-in's IK reproduces T6 to 1e-13
    # q7 goes monotonically to the target, reached at rest (the motion outlasts the ramp)
    assert np.all(np.diff(qs[:, 6]) <= 1e-12)
    assert qs[-1, 6] == pytest.approx(0.3, abs=1e-12)
    assert np.ptp(qs[:, 3]) > 0.0 or np.ptp(qs[:, 0]) > 0.01   # the elbow moved with it
    assert all(P.limits().out_of_range(q) is None for q in qs)


def test_selfmove_out_of_a_joint_range_is_refused_naming_where():
    pl, _ = planner("quartic")
    # from the ready pose (flange fixed) q7 below about -0.68 rad needs the shoulder (joint 2)
    # past -1.7628 rad
    with pytest.raises(UnreachableTarget, match=r"selfmove\(q7=-1\.5000\) at q7 = -0\.\d+ rad \(\d+% of the "
                                                r"self-motion\): joint 2 would be at -1\.\d+ rad, outside its range"):
        pl.selfmove(q7=-1.5, duration=3.0)
    assert len(pl.queue) == 0                      # nothing queued: the arm stays


def test_selfmove_too_fast_or_bad_arguments_is_refused():
    pl, _ = planner("quartic")
    with pytest.raises(BadRequest, match="take at least"):
        pl.selfmove(q7=0.3, duration=0.05)
    with pytest.raises(BadRequest, match="joint 7's range"):
        pl.selfmove(q7=4.0, duration=1.0)
    with pytest.raises(BadRequest, match="positive number of seconds"):
        pl.selfmove(q7=0.3, duration=0.0)


def test_selfmove_through_a_singularity_is_refused():
    # the elbow nearly stretched (q4 = -0.6 rad, straight at -0.467 in this pose): turning q7
    # by 0.5 rad with the tool fixed needs the elbow past straight; the check stops where the
    # reach ends (the singular boundary of the self-motion), naming q7 and the fraction
    q0 = P.READY.copy()
    q0[3] = -0.6
    pl, kin = planner("quartic", q0)
    with pytest.raises((SingularPath, UnreachableTarget), match=r"selfmove\(q7=0\.2854\) at q7 = .* rad "
                                                                r"\(\d+% of the self-motion\)"):
        pl.selfmove(q7=q0[6] - 0.5, duration=2.0)
    assert len(pl.queue) == 0


def test_line_then_selfmove_then_line_on_ruckig_and_quartic_agree():
    ends = {}
    for kind in GENERATORS:
        pl, _ = planner(kind)
        _, t1 = line_target()
        pl.setmod("c")
        pl.setvel(0.1, 0.5)
        pl.move(makeposition("B", T6, EQ, Trsf("B", t1), TL, T6))
        pl.selfmove(q7=0.5, duration=1.0)
        r = pl.move(makeposition("A", T6, EQ, Trsf("A", P.fk(P.READY)), TL, T6))
        qs = run(pl, r, 600)
        assert np.allclose(P.fk(qs[-1]), P.fk(P.READY), atol=1e-9)
        ends[kind] = qs[-1, 6]
    assert ends["quartic"] == pytest.approx(0.5, abs=1e-12) and ends["ruckig"] == pytest.approx(0.5, abs=1e-12)


def test_a_rule_giving_no_number_is_refused_naming_it():
    pl, _ = planner("quartic")
    _, t1 = line_target()
    pl.setmod("c")
    q70 = float(P.READY[6])
    pl.setfree(q7=lambda t: q70 if t < 0.2 else float("nan"))
    # the planning level samples the rule along the path (at the planned times) before the move
    with pytest.raises(UnreachableTarget, match=r"f\(0\.\d+ s\) = nan is not a finite number of radians"):
        pl.move(makeposition("B", T6, EQ, Trsf("B", t1), TL, T6))
    assert len(pl.queue) == 0


@pytest.mark.parametrize("kind", GENERATORS)
def test_a_rule_of_time_blends_into_a_joint_move_without_a_jump(kind):
    pl, _ = planner(kind)
    t0, t1 = line_target()
    pl.setmod("c")
    pl.setvel(0.1, 0.5)
    q70 = float(P.READY[6])
    pl.setfree(q7=lambda t: q70 + 0.3 * math.sin(t))
    pl.move(makeposition("B", T6, EQ, Trsf("B", t1), TL, T6))
    pl.setmod("j")
    pl.setfree()
    qs = run(pl, pl.move(makeposition("A", T6, EQ, Trsf("A", t0), TL, T6)), 600)
    # every step within the joint speed limits (the generators' step check would fault otherwise)
    speed = np.abs(np.diff(qs, axis=0)).max(axis=0) / DT
    assert np.all(speed <= P.VELOCITY * 1.25)
    assert np.allclose(P.fk(qs[-1]), t0, atol=1e-9)


def test_at_rest_the_next_rule_starts_from_where_the_arm_is():
    pl, _ = planner("quartic")
    t0, t1 = line_target()
    pl.setmod("c")
    pl.setvel(0.1, 0.5)
    pl.setfree("far")
    run(pl, pl.move(makeposition("B", T6, EQ, Trsf("B", t1), TL, T6)))
    here = float(pl.gen.q[6])
    pl.setfree(q7=lambda t: here + 0.1 * math.sin(t))    # f(0) is the q7 the arm has, not move()'s guess
    qs = run(pl, pl.move(makeposition("A", T6, EQ, Trsf("A", t0), TL, T6)))
    assert np.allclose(P.fk(qs[-1]), t0, atol=1e-9)


def test_far_rule_picks_the_cheapest_candidate_within_its_window():
    rule = redundancy.FarFromLimits(P.LOWER, P.UPPER, step=0.05)
    rng = np.random.default_rng(3)
    for _ in range(10):
        q = P.READY + rng.uniform(-0.3, 0.3, 7)
        t6 = P.fk(q)
        best = rule.solve(P, t6, P.config_of(q), q, 0.0, q[6])
        assert abs(best[6] - q[6]) <= 0.05 + 1e-12
        assert np.allclose(P.fk(best), t6, atol=1e-9)
        costs = []
        for v in q[6] + np.linspace(-0.05, 0.05, 5):
            c = P.ik(t6, None, q, q7=v)
            costs.append(redundancy.cost(c, P.jacobian6(c), P.LOWER, P.UPPER))
        assert redundancy.cost(best, P.jacobian6(best), P.LOWER, P.UPPER) == pytest.approx(min(costs), rel=1e-9)


# -- the same with the Panda's generated kinematics (rccl.kinematics.panda: closed-form IK) --------
def closed_form():
    """The generated module of the Panda (fk, jacobian6 and the closed-form IK with q7 given);
    its fk and the stand-in's agree to rounding (checked here)."""
    from rccl.kinematics import panda as K
    rng = np.random.default_rng(11)
    for q in rng.uniform(P.LOWER, P.UPPER, (5, 7)):
        assert np.allclose(K.fk(q), P.fk(q), atol=1e-12)
    return K


@pytest.mark.parametrize("kind", GENERATORS)
@pytest.mark.parametrize("rule", ["hold", "time", "far", "selfmove"])
def test_each_rule_with_the_generated_closed_form_ik(kind, rule):
    kin = Kinematics(closed_form())
    pl = Planner(kin, P.limits(), GENERATORS[kind](kin, P.limits(), DT, P.READY.copy()))
    t0, t1 = line_target()
    pl.setmod("c")
    pl.setvel(0.1, 0.5)
    q70 = float(P.READY[6])
    if rule == "selfmove":
        qs = run(pl, pl.selfmove(q7=q70 - 0.4, duration=1.0))
        assert max(float(np.abs(kin.fk(q) - t0).max()) for q in qs) < 1e-9
        assert qs[-1, 6] == pytest.approx(q70 - 0.4, abs=1e-12)
    else:
        pl.setfree(**{"hold": {"spec": "hold"}, "far": {"spec": "far"},
                      "time": {"q7": lambda t: q70 + 0.2 * math.sin(1.5 * t)}}[rule])
        qs = run(pl, pl.move(makeposition("B", T6, EQ, Trsf("B", t1), TL, T6)))
        pts = np.array([kin.fk(q)[:3, 3] for q in qs])
        assert np.max(distance_to_line(pts, t0[:3, 3], t1[:3, 3])) < LINE_TOL[kind]
        assert np.allclose(kin.fk(qs[-1]), t1, atol=1e-9)
        if rule == "hold":
            assert np.all(qs[:, 6] == q70)
        elif rule == "far":
            assert 0 < np.max(np.abs(np.diff(qs[:, 6]))) <= redundancy.FAR_STEP + 1e-12
    assert all(P.limits().out_of_range(q) is None for q in qs)


@pytest.mark.parametrize("kind", GENERATORS)
def test_a_selfmove_queued_behind_a_joint_move_starts_at_its_corner(kind):
    # (found by bench/redundancy.py: the quartic joins the joint move into the self-motion while
    # the arm still moves; the rule must ramp from the corner's q7, not the moving arm's)
    from rccl.position import joint_position
    q1 = P.READY + np.array([0.2, 0.1, 0.0, 0.1, 0.0, 0.0, 0.15])
    pl, _ = planner(kind)
    pl.setmod("j")
    pl.move(joint_position("q1", pl.kin, q1))
    qs = run(pl, pl.selfmove(q7=float(q1[6]) - 0.3, duration=1.0), 600)
    speed = np.abs(np.diff(qs, axis=0)).max(axis=0) / DT
    assert np.all(speed <= P.VELOCITY * 1.25)
    assert qs[-1, 6] == pytest.approx(q1[6] - 0.3, abs=1e-12)
    assert np.allclose(P.fk(qs[-1]), P.fk(q1), atol=1e-9)
