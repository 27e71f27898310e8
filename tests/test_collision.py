"""Collision-aware motion (issue 28 item 4): the geometry files, distances, path refusal, the per-cycle stop on simula.

The planning-level tests step the real generated kinematics of the PUMA 260 through the
``Planner`` (no simula needed: the path check runs before anything is queued); the per-cycle
test runs a functional target into a plane on a lockstep simula process that has the same
plane in its environment.
"""
from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from rcci.models import load_robot
from rccl.collision import CollisionGuard, CollisionWorld, geometry_path, load_geometry
from rccl.collision.path import path_joints
from rccl.collision.show import enclosure_gaps, skeleton_gaps
from rccl.exceptions import BadRequest, CollisionFileError, PathCollision, TrajectoryFault
from rccl.limits import load_limits
from rccl.planner import Planner
from rccl.position import EQ, TL, makeposition
from rccl.session import load_kinematics
from rccl.trajectory import TrajectoryGenerator
from rccl.transform import T6, Trsf

ARMS = ("puma260", "microbo", "puma560", "stanford", "panda")
START = np.radians([10.0, 80.0, -170.0, 10.0, -60.0, 5.0])     # the composition matrix's PUMA 260 start
MARGIN = 0.01

with warnings.catch_warnings():
    warnings.simplefilter("ignore", RuntimeWarning)     # Python kinematics when the C kernels are not built
    KIN = load_kinematics("puma260")
LIM = load_limits("puma260")


def planner(env: tuple[str, ...] = (), q0: np.ndarray = START, every_cycle: str = "functional"):
    gen = TrajectoryGenerator(KIN, LIM, 1.0 / 36.0, np.array(q0, dtype=float))
    p = Planner(KIN, LIM, gen)
    p.collision_guard = CollisionGuard(CollisionWorld("puma260", env), MARGIN, every_cycle)
    return gen, p


def to(t6: np.ndarray, name: str):
    return makeposition(name, T6, EQ, Trsf(name.upper(), t6), TL, T6)


FOREARM_ON = ("link3", "link4", "link5", "link6")     # the links that go down with the tool


def lowest_point(world: CollisionWorld, q: np.ndarray) -> tuple[str, float]:
    """(shape, z m) of the lowest capsule surface point of the forearm and wrist at q, from the capsule poses alone."""
    best = ("", math.inf)
    for sp in world.shape_poses(q):
        if sp.kind == "capsule" and sp.frame in FOREARM_ON:
            half = sp.pose[:3, 2] * sp.size[0] / 2
            z = min(sp.pose[2, 3] - half[2], sp.pose[2, 3] + half[2]) - sp.size[1]
            best = min(best, (sp.name, z), key=lambda b: b[1])
    return best


# --- the geometry files -------------------------------------------------------------------------
@pytest.mark.parametrize("robot", ARMS)
def test_shipped_geometry_encloses_every_urdf_visual_and_explains_its_pairs(robot):
    geo = load_geometry(geometry_path(robot))
    assert geo.robot == robot and len(geo.capsules) >= 3
    assert all(len(geo.reasons[p].split()) >= 3 for p in geo.allowed)
    world = CollisionWorld(robot)
    q = load_robot(robot).poses["ready"]
    gaps = enclosure_gaps(world, q)
    assert gaps, "the URDF has visuals"
    worst = max(gaps, key=lambda g: g[3])
    assert worst[3] <= 1e-4, worst             # every visual's sample points inside some shape (0.1 mm rounding)
    skeleton = skeleton_gaps(world, q)         # the DH offsets joint to joint, and every centre of mass
    assert len(skeleton) >= 10 and max(g for _, g in skeleton) <= 1e-4, max(skeleton, key=lambda g: g[1])
    # what a viewer draws: every shape, capsules with a unit z axis along their segment
    from rccl.collision import shape_poses
    drawn = shape_poses(robot, q)
    assert [d.name for d in drawn] == [c.name for c in world.shapes]
    assert all(np.allclose(d.pose[:3, :3].T @ d.pose[:3, :3], np.eye(3)) and len(d.size) in (2, 3) for d in drawn)
    # the ready pose is free of self-collision (within 0.5 mm: the PUMA 260's flange sits 0.9 mm from its forearm)
    assert world.nearest(q)[0] > 0.0


def test_malformed_geometry_files_are_named_with_their_key(tmp_path):
    good = geometry_path("puma260").read_text()
    cases = {
        "radius": (good.replace('radius = { value = 0.0', 'radius = { value = -0.0', 1), "capsules[0].radius (trunk_top)"),
        "why": (good.replace('a = { value = [0.0, 0.0086, 0.0], unit = "m", source = "encloses the URDF visual 0 of link1 '
                             '(cylinder r 0.075 m, length 0.14 m at [0.0, -0.04, 0.0]), 3 mm margin" }',
                             'a = { value = [0.0, 0.0086, 0.0], unit = "m", source = "estimate" }'),
                "capsules[0].a (trunk_top): an estimate needs a 'why'"),
        "unit": (good.replace('unit = "m"', 'unit = "inch"', 1), "unit 'inch'"),
        "pair": (good.replace('pair = ["base_link", "link1"]', 'pair = ["base_link", "elbow_x"]'), "allowed[0].pair"),
        "toml": (good + "\n[[capsules]\n", "not valid TOML"),
    }
    for label, (text, expected) in cases.items():
        path = tmp_path / f"{label}.toml"
        path.write_text(text)
        with pytest.raises(CollisionFileError) as err:
            load_geometry(path)
        assert str(path) in str(err.value) and expected in str(err.value), (label, str(err.value))
    path = tmp_path / "frame.toml"
    path.write_text(good.replace('frame = "link6"', 'frame = "link66"', 1))
    with pytest.raises(CollisionFileError, match=r"frame: 'link66' is not a link of puma260's URDF"):
        CollisionWorld("puma260", geometry=str(path))
    with pytest.raises(CollisionFileError, match="no such collision geometry file"):
        load_geometry(tmp_path / "absent.toml")


# --- distances, cross-checked ---------------------------------------------------------------------
def test_capsule_to_plane_and_wall_distances_match_the_analytic_ones():
    world = CollisionWorld("puma260", ("plane:z=-0.30", "box:x0=0.36"))
    rng = np.random.default_rng(3)
    lo, hi = world.model.lowerPositionLimit, world.model.upperPositionLimit
    for _ in range(20):
        q = lo + (hi - lo) * rng.random(6)
        d = world.distances(q)
        poses = {sp.name: sp for sp in world.shape_poses(q)}
        for k, (a, b) in enumerate(world.pairs):
            if not b.startswith("env:"):
                continue
            sp = poses[a]
            half = sp.pose[:3, 2] * sp.size[0] / 2
            ends = np.array([sp.pose[:3, 3] - half, sp.pose[:3, 3] + half])
            if b == "env:plane:z=-0.30":     # solid below z = -0.30: the lower end cap's height above it
                expected = ends[:, 2].min() - sp.size[1] + 0.30
            else:                            # solid beyond x = 0.36
                expected = 0.36 - ends[:, 0].max() - sp.size[1]
            assert d[k] == pytest.approx(expected, abs=1e-6), (a, b)


def test_sampling_is_dense_enough_for_the_margin():
    gen, p = planner()
    q1 = START.copy()
    q1[0] += 1.0
    p.setmod("joint")
    req = p.move(makeposition("swing", T6, EQ, Trsf("SWING", KIN.fk(q1)), TL, T6))
    world = p.collision_guard.world
    s, qs = path_joints(world, MARGIN, KIN, LIM, req, req.profile)
    steps = [world.displacement(b - a) for a, b in zip(qs[:-1], qs[1:])]
    assert 2 * max(steps) <= MARGIN * (1 + 1e-9)                   # two bodies' relative motion per interval
    assert len(s) == p.collision_guard.samples_checked > 100      # 1 rad of the waist at a 0.65 m lever
    fine = CollisionGuard(world, 1e-5)                            # a margin the sampling cannot guarantee
    with pytest.raises(BadRequest, match=r"move\(swing\): checking this path for a 0.01 mm clearance margin"):
        fine.check_plan(req, req.profile, KIN, LIM)


# --- the planned path -----------------------------------------------------------------------------
def test_path_down_through_a_plane_is_refused_naming_link_plane_and_where():
    world = CollisionWorld("puma260")
    name, z_low = lowest_point(world, START)
    plane = f"plane:z={z_low - 0.15:.3f}"
    gen, p = planner((plane,))
    goal = KIN.fk(START)
    goal[2, 3] -= 0.25
    p.setmod("cartesian")
    p.setvel(0.05, 0.5)
    with pytest.raises(PathCollision) as err:
        p.move(to(goal, "below"))
    e = err.value
    assert e.pair[1] == f"env:{plane}" and e.pair[0] == name, e.pair
    assert f"env:{plane}" in str(e) and f"{name} (on " in str(e) and "% of the path" in str(e)
    # where: the lowest point goes down 0.25 m along the line and meets the margin after 0.14 m
    assert e.fraction == pytest.approx(0.14 / 0.25, abs=0.03)
    assert e.time == pytest.approx(e.fraction * 0.25 / 0.05, rel=0.05)
    assert e.distance < MARGIN and lowest_point(world, e.q)[1] - (z_low - 0.15) == pytest.approx(e.distance, abs=2e-3)
    assert not gen.busy and len(gen.queue) == 0                  # nothing was queued


def test_path_into_a_box_is_refused():
    world = CollisionWorld("puma260")
    t6 = KIN.fk(START)
    x, y, z = t6[:3, 3]
    box = f"box:x0={x - 0.02:.3f},x1={x + 0.02:.3f},y0={y + 0.08:.3f},y1={y + 0.12:.3f},z0={z - 0.3:.3f},z1={z + 0.3:.3f}"
    gen, p = planner((box,))
    assert world.nearest(START)[0] > MARGIN
    goal = t6.copy()
    goal[1, 3] += 0.2
    p.setmod("cartesian")
    with pytest.raises(PathCollision) as err:
        p.move(to(goal, "through_box"))
    assert err.value.pair[1] == f"env:{box}" and 0.0 < err.value.fraction < 0.6


def test_self_colliding_path_is_refused_naming_both_links():
    gen, p = planner()
    q1 = START.copy()
    q1[4] = math.radians(-100.0)                # the wrist bends the flange into the forearm
    p.setmod("joint")
    with pytest.raises(PathCollision) as err:
        p.move(makeposition("bent", T6, EQ, Trsf("BENT", KIN.fk(q1)), TL, T6))
    e = err.value
    assert set(e.pair) == {"forearm", "flange"}
    assert "forearm (on link3)" in str(e) and "flange (on link6)" in str(e)
    # where, independently: the first q5 on the joint line at which this pair is inside the margin
    world = p.collision_guard.world
    k = world.pairs.index(e.pair)
    s = np.linspace(0, 1, 2001)
    d = np.array([world.distances(START + f * (q1 - START))[k] for f in s])
    first = s[np.argmax(d < MARGIN)]
    spacing = 1.0 / (p.collision_guard.samples_checked - 1)      # the refusal is the first sample past it
    assert first - 1e-9 <= e.fraction <= first + spacing


def test_clear_path_is_accepted_and_one_near_contact_may_be_left():
    gen, p = planner(("plane:z=-0.60",))
    goal = KIN.fk(START)
    goal[:3, 3] += [0.02, -0.02, 0.02]
    p.setmod("cartesian")
    req = p.move(to(goal, "clear"))
    assert req.status == "queued" and p.collision_guard.samples_checked >= 2
    # from the ready pose (flange 0.9 mm from the forearm, inside the margin) the wrist may move away
    ready = load_robot("puma260").poses["ready"]
    gen, p = planner(q0=ready)
    q1 = ready.copy()
    q1[4] = math.radians(-60.0)
    p.setmod("joint")
    assert p.move(makeposition("away", T6, EQ, Trsf("AWAY", KIN.fk(q1)), TL, T6)).status == "queued"
    q2 = ready.copy()
    q2[4] = math.radians(-95.0)
    with pytest.raises(PathCollision):          # but not closer
        p.move(makeposition("closer", T6, EQ, Trsf("CLOSER", KIN.fk(q2)), TL, T6))


# --- the per-cycle check on simula ---------------------------------------------------------------------
def test_functional_target_into_a_plane_is_stopped_and_the_arm_holds():
    import rccl
    from rci.simula.process import SimulaProcess

    world = CollisionWorld("puma260")
    _, z_low = lowest_point(world, START)
    plane = f"plane:z={z_low - 0.04:.3f}"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        with SimulaProcess("-p", "--power-on", "--env", plane, robot="puma260", lockstep=True) as sim, \
                rccl.open(sim.url, robot="puma260", record=True, on_error="raise", timeout=5.0) as arm:
            arm.setmod("joint")
            arm.setvel(0.1, 1.0)
            start = to(KIN.fk(START), "start")
            arm.move(start)
            arm.waitfor(start.end, timeout=60)
            guard = arm.collisions(env=[plane], margin=MARGIN)
            t6 = arm.t6
            t0 = arm.gen.t

            def sink(tr):                    # the target goes down at 30 mm/s
                m = t6.copy()
                m[2, 3] -= 0.03 * (arm.gen.t - t0)
                tr.set(m)

            target = Trsf("SINK", t6)
            target.bind(sink)
            p = makeposition("sinking", T6, EQ, target, TL, T6)
            arm.setmod("cartesian")
            arm.settime(0.2, 6.0)
            req = arm.move(p)
            assert any(c.__class__.__name__ == "CollisionWatch" for c in req.checks)
            with pytest.raises(TrajectoryFault) as err:
                arm.waitfor(p.end, timeout=60)
            cause = err.value.cause
            assert isinstance(cause, PathCollision), err.value
            assert cause.pair[1] == f"env:{plane}" and cause.fraction is None and cause.time > t0
            assert f"env:{plane}" in str(err.value)
            # it stopped inside the margin, before any contact, about 30 mm down
            assert 0.0 < cause.distance < MARGIN
            assert lowest_point(world, cause.q)[1] < z_low - 0.02
            # the arm holds: the commanded and measured joints stay put
            q_held = arm.q
            m0 = arm.measured_q()
            n0 = len(arm.trace)
            arm.rci.wait(30.0, until=lambda: len(arm.trace) >= n0 + 36)    # a second of cycles (the frozen t stands)
            assert np.array_equal(arm.q, q_held)
            assert np.max(np.abs(arm.measured_q() - m0)) < 2e-3
            k = guard.world.pairs.index(cause.pair)
            assert guard.world.distances(arm.measured_q())[k] > 0.0     # no contact where it holds
            arm.recover()


def test_watch_rides_on_the_motions_asked_for_and_stops_only_when_closer():
    from rccl.adaptive.check import Sample
    from rccl.collision import CollisionWatch

    gen, p = planner(every_cycle="all")
    p.setmod("joint")
    req = p.move(makeposition("here", T6, EQ, Trsf("HERE", KIN.fk(START)), TL, T6))
    assert any(isinstance(c, CollisionWatch) for c in req.checks)          # "all": a const target too
    gen, p = planner()
    req = p.move(makeposition("here", T6, EQ, Trsf("HERE", KIN.fk(START)), TL, T6))
    assert not any(isinstance(c, CollisionWatch) for c in req.checks)      # "functional": not a const one
    watch = CollisionWatch(p.collision_guard.world, MARGIN, "move(x)")

    def sample(q):
        return Sample(0.1, 3, q, np.zeros(6), np.array(q, dtype=float), None, None, None)

    ready = load_robot("puma260").poses["ready"]           # flange 0.9 mm from the forearm at the start
    assert watch.ends(sample(ready)) is None
    away = ready.copy()
    away[4] += 0.05
    assert watch.ends(sample(away)) is None                 # inside the margin but not closer than at the start
    closer = ready.copy()
    closer[4] -= 0.05
    with pytest.raises(PathCollision, match=r"forearm \(on link3\) and flange \(on link6\).*trajectory time 0.100 s"):
        watch.ends(sample(closer))
