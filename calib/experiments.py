"""The thesis's four measurements as joint paths plus the metadata their fits need.

Each ``*_plan`` returns Plans: a path for the controller to follow, the log metadata
(docs/calib.md) and a file name.  Poses are in the thesis's joint angles (DH of
Table 3.1) and chosen with the gravity model: friction paths are centred where gravity
does no net work (4.5.4), the sensitivity arcs are swept with and without the pulley
(4.5.2), the gravity sweeps start from Table 4.7 (4.5.6) and the halts are random
(4.5.5).
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np

from rcci.calib.friction_poses import check_friction_pose, friction_pose, loaded_friction_pose
from rcci.calib.paths import Path, PathSegment, sweep_path
from rcci.calib.plan import MeasurementPlan
from rcci.calib.poses import (TABLE_4_7, TABLE_4_8_SWEEPS, identifying_sweeps, main_sweep, repeat_sweep,
                         table_4_7_identifies)

DEG = np.pi / 180
ACCEL = 1.5  # rad/s^2 at the turns: gentle, so the servo keeps the setpoint

# Friction poses: joint i sweeps a window centred on the pose's angle; the other joints
# put the axis vertical (joints 1, 4, 5) or centre the window on the angle where the
# arm points straight up, so that gravity's work over the window cancels (2, 3).
# Degrees (pose, half-width of the window); tests/test_calib_programs.py checks each
# against the gravity regressor.  The windows are as long as the joint's range leaves
# room for the turns at speed: a longer pass averages more readings, and the turns
# (which yield nothing) cost the same whatever the window.
FRICTION_POSES: dict[int, tuple[tuple[float, ...], float]] = {
    1: ((90, 90, -90, 0, 0, 0), 90),      # joint 1 axis is always vertical
    2: ((90, 90, -90, 90, 90, 0), 60),    # arm straight up at theta2 = 90
    3: ((90, 90, -90, 90, 90, 0), 60),    # forearm straight up at theta2 + theta3 = 0
    4: ((90, 90, -90, 0, 45, 0), 150),    # forearm vertical: joint 4 axis vertical
    5: ((90, 90, 0, 90, 0, 0), 55),       # forearm horizontal, theta4 = 90: axis 5 vertical
    6: ((90, 90, -90, 0, 0, 0), 150),     # theta5 = 0 under a vertical forearm: axis 6 vertical
}
# Candidate speeds (deg/s); each joint uses those up to its top speed (friction_top_speed):
# the viscous coefficient is the slope of friction against speed, so its error falls
# with the spread of the speeds, and the top of the range is worth the most.
FRICTION_SPEEDS_DEG = (5, 10, 20, 40, 70, 110, 160, 200, 240)
# Round trips per speed: a pass's mean friction is as good as the readings it averages,
# and the fast passes (short, but the ones that carry the viscous term) get more trips.
FRICTION_TRIPS = (1, 1, 1, 2, 3, 4, 6, 8, 10)
MAX_PASS_S = 40.0  # s: the slowest speeds are skipped on the long windows of joints 4, 6
SWEEP_ACCEL = 12.0  # rad/s^2 at the turns of friction sweeps: short ramps beyond the window
TURN_MARGIN = 4 * DEG  # beyond the ramp: the last setpoints before a joint limit
FRICTION_RATE_HZ = 72  # readings per second in friction logs: twice the thesis's 36 Hz,
# so each pass averages twice as many ADC readings (each carries its own sensor noise and
# the part of the 1 kHz ripple the 15 ms filter lets through); still under 5 filter
# time constants apart, so the readings are not redundant
# Joints whose fast passes are read at every servo tick, in a log of their own. At 72 Hz
# each reading catches the ripple of one tick (alpha e_k of the filtered noise-shaped
# ripple, about 3 % of joint 5's friction), so a 0.5 s pass at 4 rad/s scatters by
# 0.5 %; read at every tick, the ripple of successive readings telescopes (its mean
# over a pass is the filter's change over the pass) and only the ADC noise remains,
# 0.05 % per pass (docs/calib.md, "Joint 5"). Joint 5 needs it most: its Table 4.3 bounds
# are +-6 % of the coefficient, the viscous term is 1.5 % of its friction at the top speed.
SERVO_RATE_HZ = 1000
# joint: (from deg/s, round trips per speed from there up). The other joints too: at
# 72 Hz their fits were as wide as their Table 4.3 bounds (docs/calib.md). Joints 4 and
# 6, whose 300-degree windows cost 2.5 times the records per pass, only from 200 deg/s.
SERVO_RATE_JOINTS = {2: (40.0, (1, 2, 2, 3)), 3: (40.0, (1, 1, 2, 2, 3, 3)),
                     4: (200.0, (2, 3)), 5: (40.0, (2, 3, 4, 5, 6, 8)),
                     6: (200.0, (2, 2, 3))}
FRICTION_WARMUP_S = 200.0  # s: 10 e-foldings of simula's warm-up (a cold joint +20 %, 4.5.3);
# after 100 s a joint is still 0.13 % over its warm friction, which fades during the first
# (slow) passes and biases the slope by -0.05e-3 N m s/rad on joint 5


WARMUP_S = 100.0  # s of motion before recording: 5 e-foldings of a cold joint's warm-up (4.5.3)


WARMUP_SPEED = 30 * DEG  # rad/s of the warm-up sweeps


def sweep_warmup(q: np.ndarray, joint: int, lo: float, hi: float, speed: float = WARMUP_SPEED,
                 seconds: float = WARMUP_S, dwell: float = 0.1) -> Path:
    """Back-and-forth over the window for about ``seconds`` s, so that the joint is warm
    ("once a joint had warmed up, successive measurements ... very high repeatability")."""
    trip = 2 * (hi - lo + 2 * (speed * speed / (2 * ACCEL) + 2 * DEG)) / speed
    return sweep_path(q, joint, lo, hi, [speed], max(1, int(np.ceil(seconds / trip))), ACCEL,
                      dwell=dwell)


def _start_move(here: np.ndarray | None, to: np.ndarray) -> list[PathSegment]:
    return [] if here is None else [PathSegment(here, to, 0.6, ACCEL, 0.5)]


def _prepend(here: np.ndarray | None, path: Path) -> Path:
    first = path.segments[0].start
    return Path(tuple(_start_move(here, first)) + path.segments)


def friction_top_speed(joint: int, lo: float, hi: float, lower: np.ndarray,
                       upper: np.ndarray, vmax: np.ndarray) -> float:
    """Fastest sweep (rad/s) of ``joint`` (1-based) through [lo, hi]: 90 % of the joint's
    velocity limit, or less where the ramp at SWEEP_ACCEL must fit between the window
    and the joint's range (with TURN_MARGIN and sweep_path's 2 degrees to spare)."""
    room = min(lo - lower[joint - 1], upper[joint - 1] - hi) - TURN_MARGIN - 2 * DEG
    if room <= 0:
        raise ValueError(f"joint {joint}: window [{lo:.3f}, {hi:.3f}] rad leaves no room "
                         "to turn inside the joint's range")
    return float(min(0.9 * vmax[joint - 1], np.sqrt(2 * SWEEP_ACCEL * room)))


THESIS_ARM = "puma260"   # the arm FRICTION_POSES were chosen for (and the default of the plans)


def _robot_limits(robot: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    from rcci.models import load_robot

    m = load_robot(robot)
    return np.array(m.lower, float), np.array(m.upper, float), np.array(m.max_velocity, float)


def pose_for(robot, j: int, lower: np.ndarray, upper: np.ndarray, loaded: bool = False) -> tuple[np.ndarray, float]:
    """(pose rad, half window rad) of joint ``j``'s friction sweeps on the arm of ``robot``
    (rcci.calib.robot.RobotInfo; None: the thesis's): FRICTION_POSES where they serve it (gravity
    does no work over the window, and the window with its turns fits the range), else
    rcci.calib.friction_poses.friction_pose's; with ``loaded`` (the friction sweeps, whose fit takes
    gravity's mean over the window off) then rcci.calib.friction_poses.loaded_friction_pose's;
    CalibError when none does."""
    from rcci.calib.exceptions import CalibError

    from rcci.calib.unmeasured import why_unmeasured

    qdeg, half = FRICTION_POSES[j]
    q = np.array(qdeg, float) * DEG
    if robot is None:
        return q, half * DEG
    why = why_unmeasured(robot.name, j)
    if why is not None:
        raise CalibError(f"robot {robot.name}: joint {j}: its torque is not measured: {why}")
    try:
        if len(q) != len(lower) or np.any(q < lower) or np.any(q > upper):
            raise ValueError("the thesis's pose is outside this arm's ranges")
        check_friction_pose(robot, j, q[j - 1] - half * DEG, q[j - 1] + half * DEG, q)
        friction_top_speed(j, q[j - 1] - half * DEG, q[j - 1] + half * DEG, lower, upper, np.full(len(q), 1.0))
        return q, half * DEG
    except (CalibError, ValueError):
        found = friction_pose(robot, j)
    if found is None and loaded:
        heavy = loaded_friction_pose(robot, j)
        found = None if heavy is None else heavy[:2]
    if found is None:
        raise CalibError(f"robot {robot.name}: no pose found for joint {j}'s friction window over which "
                         "gravity does no work" + (" or only little the fit can take off" if loaded else "")
                         + " (rcci.calib.friction_poses)")
    return found


def friction_plans(joints=range(1, 7), speeds_deg=None,
                   trips: tuple[int, ...] | int | None = None, robot=None) -> list[MeasurementPlan]:
    """4.5.4: passes in both directions at several constant speeds, no potential-energy change.

    By default each joint runs the FRICTION_SPEEDS_DEG up to its top speed
    (friction_top_speed), the last replaced by the top speed itself, with FRICTION_TRIPS
    round trips; ``speeds_deg`` and ``trips`` override both (then used as given, in one
    plan at 72 Hz). By default, for the joints of SERVO_RATE_JOINTS the speeds from its
    threshold up go into a second
    plan, ``friction-jN-servo``, read at every servo tick (SERVO_RATE_HZ) with its trips;
    both plans sweep the same window.
    The sweeps turn without standing still, so a joint stays as warm at the top speed
    as at the slowest (idle time cools it, 4.5.3), after FRICTION_WARMUP_S of warm-up.
    ``robot`` (rcci.calib.robot.RobotInfo; None: the thesis's arm) gives the joint ranges and
    speeds, and each window is checked on its gravity model (check_friction_pose).
    """
    from rcci.calib.exceptions import CalibError

    lower, upper, vmax = _robot_limits(THESIS_ARM if robot is None else robot.name)
    plans = []
    for j in joints:
        q, half_rad = pose_for(robot, j, lower, upper, loaded=True)
        half = half_rad / DEG
        lo, hi = q[j - 1] - half_rad, q[j - 1] + half_rad
        loaded = robot is not None and _gravity_works(robot, j, lo, hi, q)
        if speeds_deg is None:
            try:
                top = friction_top_speed(j, lo, hi, lower, upper, vmax) / DEG
            except ValueError as exc:
                arm = THESIS_ARM if robot is None else robot.name
                raise CalibError(f"robot {arm}: {exc} (rcci.calib.experiments.FRICTION_POSES)") from None
            slowest = 2 * half / MAX_PASS_S          # deg/s: no pass longer than MAX_PASS_S
            cand = [(v, n) for v, n in zip(FRICTION_SPEEDS_DEG, FRICTION_TRIPS)
                    if slowest <= v < top]
            if top - cand[-1][0] < 15:
                cand[-1] = (top, cand[-1][1])  # too close to its neighbour: move it to the top
            else:
                cand.append((top, FRICTION_TRIPS[-1]))
            speeds = [float(v) for v, _ in cand]
            n_trips = [n for _, n in cand] if trips is None else trips
        else:
            speeds = list(speeds_deg)
            n_trips = trips if trips is not None else 1
            if max(speeds) * DEG > 0.9 * vmax[j - 1]:
                raise CalibError(f"joint {j}: a sweep at {max(speeds):g} deg/s ({max(speeds) * DEG:.3f} "
                                 f"rad/s or m/s) is over 90 % of its velocity limit {vmax[j - 1]:g}")
        n_trips = [n_trips] * len(speeds) if isinstance(n_trips, int) else list(n_trips)
        groups = [(f"friction-j{j}", FRICTION_RATE_HZ, speeds, n_trips)]
        if speeds_deg is None and trips is None and j in SERVO_RATE_JOINTS:
            start, fast_trips = SERVO_RATE_JOINTS[j]
            slow = [(v, n) for v, n in zip(speeds, n_trips) if v < start]
            fast = [v for v in speeds if v >= start]
            groups = [(f"friction-j{j}", FRICTION_RATE_HZ, [v for v, _ in slow], [n for _, n in slow]),
                      (f"friction-j{j}-servo", SERVO_RATE_HZ, fast, list(fast_trips[-len(fast):]))]
            # an arm whose joint never reaches the threshold (the PUMA 560's joint 4 tops at 52 deg/s
            # of 200) has no servo-rate log: a plan without a pass would be a path of no segments
            groups = [g for g in groups if g[2]]
        for name, rate, vs, ns in groups:
            plan = _friction_plan(name, rate, j, q, lo, hi, vs, ns, float(vmax[j - 1]))
            plan.meta["log_set"] = [g[0] for g in groups]   # the fit warns when one is missing
            if loaded:         # the fit must take gravity's mean over the window off (window_gravity)
                plan.meta["gravity_loaded"] = True
            plans.append(plan)
    return plans


def _gravity_works(robot, j: int, lo: float, hi: float, q: np.ndarray) -> bool:
    """Whether gravity does work on joint ``j`` over [lo, hi] at ``q`` for some coefficients."""
    from rcci.calib.exceptions import CalibError

    try:
        check_friction_pose(robot, j, lo, hi, q)
    except CalibError:
        return True
    return False


def _friction_plan(name: str, rate: int, j: int, q: np.ndarray, lo: float, hi: float,
                   speeds: list[float], trips: list[int], vmax_j: float = np.inf) -> MeasurementPlan:
    segs: list[PathSegment] = []
    for v, n in zip(speeds, trips):
        segs += sweep_path(q, j - 1, lo, hi, [v * DEG], n, SWEEP_ACCEL,
                           start=segs[-1].end if segs else None, dwell=0.0).segments
    meta = {"experiment": "friction", "joint": j, "window": [lo, hi], "pose": list(q),
            "speeds": [v * DEG for v in speeds], "trips": list(trips)}
    warm = sweep_warmup(q, j - 1, lo, hi, speed=min(WARMUP_SPEED, 0.8 * vmax_j), seconds=FRICTION_WARMUP_S,
                        dwell=0.0)
    return MeasurementPlan(name, Path(tuple(segs)), meta, warmup=warm, rate_hz=rate)


# Pulley masses (kg) per joint: the load torque m g r should be of the order of the
# joint's friction (so the mass's work stands out of the friction's scatter) and leave
# room under the motor's current limit (the wrist motors give under 2 N m).
SENSITIVITY_MASS = {1: 4.0, 2: 4.0, 3: 4.0, 4: 1.0, 5: 1.0, 6: 1.0}


def sensitivity_plans(mass_kg: float | None, radius_m: float, joints=range(1, 7),
                      speeds_deg=(15, 30), trips: int = 3, arc_deg: float = 60.0,
                      robot=None, notes: list[str] | None = None) -> list[MeasurementPlan]:
    """4.5.2: the same arc with the pulley's mass and without it (two simula runs).

    The pulley is a simula load option (``--load pulley:...``); its string winds on a
    drum on the joint axis, and the mass rises as the joint angle increases (sign +1).
    ``mass_kg`` None takes SENSITIVITY_MASS, made smaller where the arm could not carry it
    (rcci.calib.headroom: the motors' current limits, with margins for a truth whose sensitivity,
    friction and gravity are not the data file's, from the ``ready`` pose a fresh arm
    stands in); each such change is appended to ``notes`` and kept in the log's metadata
    (``load_note``). A ``mass_kg`` given that the arm could not carry is refused. The arcs
    start from the friction poses (the thesis arm's); ``robot`` (rcci.calib.robot.RobotInfo,
    None: the thesis's arm) has them checked against its joint ranges.
    """
    from rcci.calib.exceptions import CalibError
    from rcci.calib.robot import robot_info

    info = robot if robot is not None else robot_info(THESIS_ARM)
    lower, upper, vmax = _robot_limits(info.name)
    plans = []
    for j in joints:
        # a gravity-loaded pose serves too: gravity's work cancels between the + and - passes and
        # again between the loaded and unloaded runs (4.43), only the motor must carry it (checked below)
        q, _ = pose_for(robot, j, lower, upper, loaded=True)
        prismatic = info.kinds[j - 1] == "prismatic"
        # a prismatic joint: a 0.2 m stroke, the string over a pulley fixed to the base pulls
        # the slide with the mass's weight (radius 1: the load's "torque" m g r is m g newtons)
        half = 0.1 if prismatic else arc_deg / 2 * DEG
        radius_j = 1.0 if prismatic else radius_m
        lo, hi = q[j - 1] - half, q[j - 1] + half
        ends = np.tile(q, (2, 1))
        ends[:, j - 1] = lo - 4 * DEG, hi + 4 * DEG
        if np.any(ends < lower) or np.any(ends > upper):
            raise CalibError(f"robot {info.name}: the sensitivity arc of joint {j} from its friction pose "
                             f"{np.round(np.degrees(q), 1).tolist()} deg leaves the joint ranges")

        def make(mass: float) -> MeasurementPlan:
            path = sweep_path(q, j - 1, lo, hi, [v * DEG for v in speeds_deg], trips, ACCEL)
            meta = {"experiment": "sensitivity", "joint": j, "window": [lo, hi], "pose": list(q),
                    "load": {"mass_kg": mass, "radius_m": radius_j, "sign": 1},
                    "log_set": [f"sensitivity-j{j}-loaded", f"sensitivity-j{j}-unloaded"]}
            tag = "loaded" if mass > 0 else "unloaded"
            args = [f"--load=pulley:joint={j},mass={mass},radius={radius_j}"] if mass > 0 else []
            return MeasurementPlan(f"sensitivity-j{j}-{tag}", path, meta, args,
                                   warmup=sweep_warmup(q, j - 1, lo, hi, speed=min(WARMUP_SPEED, 0.8 * vmax[j - 1])))

        loaded = _carried_load(info, j, make, _default_mass(info, j, radius_j) if mass_kg is None else mass_kg,
                               radius_j, adapt=mass_kg is None, notes=notes)
        plans += [loaded, make(0.0)]
    return plans


def _default_mass(info, j: int, radius: float) -> float:
    """SENSITIVITY_MASS on the thesis's arm; on another, the mass whose load m g r is half the
    joint's data-file friction (kg, to 0.1 kg, at least 0.2 kg)."""
    from rcci.calib.sensitivity import GRAVITY

    if info.name == THESIS_ARM:
        return SENSITIVITY_MASS[j]
    fr = info.nominal["friction"]
    friction = 0.5 * (fr["coulomb_pos"]["values"][j - 1] + fr["coulomb_neg"]["values"][j - 1])
    return max(0.2, round(0.5 * friction / (GRAVITY * radius), 1))


SENSITIVITY_MASS_STEPS = (1.0, 0.8, 0.64, 0.5, 0.4, 0.32, 0.25)   # of the default mass, tried in turn
MIN_LOAD_OF_FRICTION = 0.2   # the load torque m g r must be at least this share of the joint's friction


def _carried_load(info, j: int, make, mass: float, radius_m: float, adapt: bool,
                  notes: list[str] | None) -> MeasurementPlan:
    """The loaded plan of joint ``j`` with the largest mass (``mass`` times a step of
    SENSITIVITY_MASS_STEPS; only ``mass`` itself unless ``adapt``) that rcci.calib.headroom says
    the arm carries from its ready pose; CalibError naming the motor and currents if none."""
    from rcci.calib.exceptions import CalibError
    from rcci.calib.headroom import approach_routes, plan_setpoints, start_pose, worst
    from rcci.calib.sensitivity import GRAVITY

    fr = info.nominal["friction"]
    friction = 0.5 * (fr["coulomb_pos"]["values"][j - 1] + fr["coulomb_neg"]["values"][j - 1])
    first = None
    for step in SENSITIVITY_MASS_STEPS if adapt else (1.0,):
        m = round(mass * step, 3)
        if adapt and m * GRAVITY * radius_m < MIN_LOAD_OF_FRICTION * friction:
            break
        plan = make(m)
        load = np.zeros(len(info.lower))
        load[j - 1] = -m * GRAVITY * radius_m          # simula: -sign m g r on the joint
        here = start_pose(info.name)
        start = plan.warmup.segments[0].start if plan.warmup is not None else plan.path.segments[0].start
        tried = []
        for via in approach_routes(here, start):
            plan.via = via
            tried.append((worst(info, plan_setpoints(plan, here, ACCEL), plan.rate_hz, load), via))
        # the straight approach when it is carried (as recorded in the shipped logs), else the best
        head, plan.via = tried[0] if tried[0][0].ok else min(tried, key=lambda hv: hv[0].current / hv[0].limit)
        first = first or tried[0][0]
        if head.ok:
            said = []
            if plan.via:
                said.append(f"the approach from the ready pose goes by {np.round(np.degrees(plan.via[0]), 1).tolist()} "
                            "deg")
            if step < 1.0:
                said.append(f"recording with {m:g} kg")
            if said:
                note = (f"sensitivity-j{j}-loaded: {mass:g} kg on the straight approach is not carried "
                        f"({first.describe()}); " + " and ".join(said) + " (rcci.calib.headroom)")
                plan.meta["load_note"] = note
                if notes is not None:
                    notes.append(note)
            return plan
    why = (first.describe() if first is not None else
           f"its load m g r = {mass * GRAVITY * radius_m:.2f} N m is under {100 * MIN_LOAD_OF_FRICTION:.0f} % of "
           f"the joint's friction ({friction:.2f} N m), too small to stand out of it: give a larger --mass or --radius")
    raise CalibError(f"robot {info.name}: sensitivity-j{j}-loaded with {mass:g} kg on a {radius_m:g} m drum: "
                     f"{why}" + ("; no smaller mass whose load stands out of the joint's friction is carried "
                                 "either" if adapt else "; give a smaller --mass"))


GRAVITY_TURN_ACCEL = 6.0  # rad/s^2 at the turns of the sweeps chosen by the regressor: short
# ramps beyond the 180-degree window, which must fit in ranges such as the PUMA 560's
# 200-degree joint 5 (the Table 4.7 sweeps keep ACCEL, as recorded in the shipped logs)
SWEEP_SPARE = 2 * DEG     # rad beyond sweep_path's own turn margin, for the servo's rounding


def gravity_plans(regressor: Callable[[np.ndarray], np.ndarray], lower: np.ndarray,
                  upper: np.ndarray, speed_deg: float = 20.0, trips: int = 1, *,
                  names: tuple[str, ...] | None = None, kinds: tuple[str, ...] | None = None,
                  noise: np.ndarray | None = None, extra: int = 2) -> list[MeasurementPlan]:
    """4.5.6: each Table 4.7 sweep and its friction-cancelling repeat (4.49-4.51), when they
    serve the arm (rcci.calib.poses.table_4_7_identifies: the thesis's PUMA 260); for any other
    arm, sweeps chosen by its regressor to identify every coefficient (``names``: its
    columns), ``extra`` beyond the fewest, each row weighted by the joint's expected
    ``noise`` (its friction; default equal), without repeats (rcci.calib.poses.identifying_sweeps)."""
    if not table_4_7_identifies(regressor, lower, upper, kinds):
        return _identifying_plans(regressor, lower, upper, speed_deg, trips, names, kinds, noise, extra)
    plans = []
    for name, joint in TABLE_4_8_SWEEPS:
        main = main_sweep(name, joint)
        repeat = repeat_sweep(main, regressor, lower, upper)
        for sw in (main, repeat) if repeat is not None else (main,):
            j = sw.joint - 1
            path = sweep_path(sw.q_start, j, sw.phi_low, sw.phi_low + np.pi, [speed_deg * DEG],
                              trips, ACCEL)
            tag = name if joint == TABLE_4_7[name][1] else f"{name}-j{joint}"
            meta = {"experiment": "gravity", "joint": sw.joint, "position": name, "role": sw.role,
                    "q_start": list(sw.q_start), "phi_low": sw.phi_low, "repeat_kind": sw.how,
                    "log_set": [f"gravity-{tag}-main"] + ([f"gravity-{tag}-repeat"] if repeat is not None else [])}
            plans.append(MeasurementPlan(f"gravity-{tag}-{sw.role}", path, meta,
                              warmup=sweep_warmup(sw.q_start, j, sw.phi_low, sw.phi_low + np.pi)))
    return plans


def _identifying_plans(regressor, lower, upper, speed_deg, trips, names, kinds, noise,
                       extra) -> list[MeasurementPlan]:
    """gravity_plans for an arm Table 4.7 does not serve: one main sweep per chosen pose, its
    turns at GRAVITY_TURN_ACCEL, with room inside the ranges for them and the warm-up."""
    n = len(lower)
    k = np.asarray(regressor((np.asarray(lower) + np.asarray(upper)) / 2)).shape[1]
    names = tuple(names) if names is not None else tuple(f"c{m + 1}" for m in range(k))
    kinds = tuple(kinds) if kinds is not None else ("revolute",) * n
    noise = np.ones(n) if noise is None else np.asarray(noise, dtype=float)
    v, warm = speed_deg * DEG, WARMUP_SPEED
    # sweep_path turns v^2 / 2a + 2 deg beyond the window, the warm-up (at ACCEL) likewise
    margin = max(v * v / (2 * GRAVITY_TURN_ACCEL), warm * warm / (2 * ACCEL)) + 2 * DEG + SWEEP_SPARE
    plans = []
    for sw in identifying_sweeps(regressor, names, np.asarray(lower), np.asarray(upper), kinds, noise,
                                 margin, extra=extra):
        j = sw.joint - 1
        path = sweep_path(sw.q_start, j, sw.phi_low, sw.phi_low + np.pi, [v], trips, GRAVITY_TURN_ACCEL)
        name = f"gravity-{sw.name}-j{sw.joint}-main"
        meta = {"experiment": "gravity", "joint": sw.joint, "position": sw.name, "role": "main",
                "q_start": list(sw.q_start), "phi_low": sw.phi_low, "repeat_kind": sw.how, "log_set": [name]}
        plans.append(MeasurementPlan(name, path, meta,
                                     warmup=sweep_warmup(sw.q_start, j, sw.phi_low, sw.phi_low + np.pi)))
    return plans


def static_plan(lower: np.ndarray, upper: np.ndarray, halts: int = 275, seed: int = 1985,
                speed_deg: float = 60.0, halt_s: float = 0.6, step_deg: float = 40.0,
                start: np.ndarray | None = None, vmax: np.ndarray | None = None) -> MeasurementPlan:
    """4.5.5, second method: the arm brought to a halt at random poses.

    Each pose is a random step of up to ``step_deg`` per joint from the last (kept 10 %
    inside the joint ranges), so the 275 halts take minutes rather than an hour; with the
    velocity limits ``vmax`` every joint moves within 0.8 of its own (a slide's, in m/s, may be
    below ``speed_deg``: the Microbo's 0.2 m/s).
    """
    rng = np.random.default_rng(seed)
    margin = 0.1 * (upper - lower)
    lo, hi = lower + margin, upper - margin
    here = np.clip(start if start is not None else (lo + hi) / 2, lo, hi)

    def walk(n: int, dwell: float, here: np.ndarray) -> list[PathSegment]:
        segs = []
        for _ in range(n):
            q = np.clip(here + rng.uniform(-step_deg, step_deg, len(here)) * DEG, lo, hi)
            segs.append(PathSegment(here, q, speed_deg * DEG, 3 * ACCEL, dwell))
            here = q
        return segs

    warm = walk(int(WARMUP_S / 1.0), 0.0, here)  # about 1 s per step, no halts
    here = warm[-1].end
    segs = [PathSegment(here, here, 1.0, ACCEL, halt_s)] + walk(halts - 1, halt_s, here)
    meta = {"experiment": "static", "halts": halts, "seed": seed, "halt_s": halt_s}
    path, warmup = Path(tuple(segs)), Path(tuple(warm))
    if vmax is not None:
        path, warmup = path.within(vmax), warmup.within(vmax)
    return MeasurementPlan("static", path, meta, warmup=warmup)
