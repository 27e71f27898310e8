"""The breakaway measurement program (Table 4.5): ramp a still joint's motor current until it moves.

Thesis 4.5.5's first method set the current of a joint free of gravity loading and
adjusted it by hand until the joint could just be moved; this program does the same
without a hand: at each of a few positions and in both directions, joint i is switched
from its position servo to current mode (CUR) and its motor torque is ramped slowly from
zero; the first encoder change marks the breakaway. The other joints stay servoed on the
pose. Between ramps the joint sweeps a few degrees back and forth, so that it stays warm
(a joint that stands cools, and a cold joint's friction is up to 20 % higher, 4.5.3).
Only the ramps (and a moment either side) are recorded; the fit (rcci.calib.breakaway) finds
them in the log by their CUR commands.
"""
from __future__ import annotations

import threading
from dataclasses import dataclass, field

import numpy as np

from rcci.calib.experiments import ACCEL, DEG, FRICTION_POSES, FRICTION_WARMUP_S, WARMUP_SPEED, sweep_warmup
from rcci.calib.paths import Path, PathSegment
from rcci.calib.program import command_joints, drive_recorded, open_measurement
from rci import codes
from rci.chg import CUR
from rci.conversions import DAC_MAX, DAC_MIN, Conversions

BREAKAWAY_RATE_HZ = 72
RAMP_S = 3.0              # s to reach RAMP_TOP x the data file's F_s (breakaway near 1.9 s)
RAMP_TOP = 1.6
MOVED_COUNTS = 3          # encoder counts from the ramp's start that mean "it moved"
AFTER_ONSET = 6           # cycles the ramp goes on after the onset (the fit reads up to it)
POSITIONS_DEG = (-20.0, 0.0, 20.0)   # offsets from the friction pose's angle
POSITIONS_M = (-0.05, 0.0, 0.05)     # on a prismatic joint (m)
WARM_DEG, SWEEP_DEG = 10.0, 8.0      # half widths of the warm-up and of the sweeps between ramps
WARM_M, SWEEP_M = 0.04, 0.03         # on a prismatic joint (m)
BETWEEN_S = 6.0           # s of sweeping between ramps (keeps the joint warm)


@dataclass
class BreakawayPlan:
    """Ramps of one joint: at ``positions`` (rad, joint angle) and both directions."""

    name: str
    joint: int                     # 1-based
    pose: np.ndarray               # rad, the other joints
    positions: list[float]
    ramp_rate: float               # N m/s of motor torque on motor ``joint``
    meta: dict = field(default_factory=dict)
    rate_hz: int = BREAKAWAY_RATE_HZ
    warm_half: float = WARM_DEG * DEG      # rad (m): the warm-up's half width
    sweep_half: float = SWEEP_DEG * DEG    # rad (m): the sweeps' between ramps


def breakaway_plans(static_pos: np.ndarray, G: np.ndarray, joints=range(1, 7), robot=None) -> list[BreakawayPlan]:
    """One plan per joint, at the friction pose (axis vertical or gravity-free at the
    centre) and POSITIONS_DEG around it (POSITIONS_M on a prismatic joint); the ramp reaches
    RAMP_TOP x ``static_pos`` (the data file's Table 4.5, joint N m) through G's diagonal in
    RAMP_S. ``robot`` (rcci.calib.robot.RobotInfo; None: the thesis's PUMA 260): the thesis's
    pose where the ramps, the warm-up and the sweeps fit the arm's ranges, else the friction
    pose found for that arm (rcci.calib.experiments.pose_for)."""
    plans = []
    for j in joints:
        q, offsets, warm, sweep = _pose(j, robot)
        pos = [float(q[j - 1] + d) for d in offsets]
        rate = RAMP_TOP * float(static_pos[j - 1]) / abs(float(G[j - 1, j - 1])) / RAMP_S
        meta = {"experiment": "breakaway", "joint": j, "pose": list(q), "positions": pos,
                "ramp_motor_torque_rate": rate, "moved_counts": MOVED_COUNTS}
        plans.append(BreakawayPlan(f"breakaway-j{j}", j, q, pos, rate, meta, warm_half=warm, sweep_half=sweep))
    return plans


def _pose(j: int, robot) -> tuple[np.ndarray, list[float], float, float]:
    """(pose rad, position offsets, warm-up half width, sweep half width) of joint ``j``'s ramps."""
    from rcci.calib.exceptions import CalibError
    from rcci.calib.experiments import pose_for

    q = np.array(FRICTION_POSES[j][0], float) * DEG
    prismatic = robot is not None and robot.kinds[j - 1] == "prismatic"
    offsets = list(POSITIONS_M) if prismatic else [d * DEG for d in POSITIONS_DEG]
    warm, sweep = (WARM_M, SWEEP_M) if prismatic else (WARM_DEG * DEG, SWEEP_DEG * DEG)
    if robot is None or (len(q) == len(robot.lower) and _fits(q, j, offsets, warm, robot)):
        return q, offsets, warm, sweep
    # the ramp starts from the gravity balance of the data file's model: a pose where gravity
    # works on the joint (the Stanford boom's joint 2) serves when none is free of it
    found, _ = pose_for(robot, j, np.asarray(robot.lower, float), np.asarray(robot.upper, float), loaded=True)
    if not _fits(found, j, offsets, warm, robot):
        raise CalibError(f"robot {robot.name}: joint {j}: the breakaway ramps at {offsets} from its friction "
                         f"pose with a +-{warm:g} warm-up leave the joint's range")
    return found, offsets, warm, sweep


def _fits(q: np.ndarray, j: int, offsets: list[float], warm: float, robot, turn: float = 0.15) -> bool:
    """Every joint of ``q`` inside its range, and joint ``j``'s ramp positions with the warm-up
    (``warm`` either side) and its turns (``turn`` rad or m, at most a tenth of the range) too."""
    lo, hi = np.asarray(robot.lower, float), np.asarray(robot.upper, float)
    if np.any(q < lo) or np.any(q > hi):
        return False
    k = j - 1
    room = warm + min(turn, 0.1 * (hi[k] - lo[k]))
    return all(lo[k] + room <= q[k] + d <= hi[k] - room for d in offsets)


def _sweep(q: np.ndarray, j: int, half: float, seconds: float, rate: int, vmax: np.ndarray) -> np.ndarray:
    """Setpoints sweeping joint j (0-based) +-half rad about q for about ``seconds``, within
    0.8 of the velocity limits ``vmax``."""
    lo, hi = q.copy(), q.copy()
    lo[j], hi[j] = q[j] - half, q[j] + half
    v = min(30 * DEG, 0.8 * float(vmax[j]))
    segs, n = [PathSegment(q, lo, v, ACCEL)], max(1, int(seconds * v / (4 * half)))
    for _ in range(n):
        segs += [PathSegment(lo, hi, v, ACCEL), PathSegment(hi, lo, v, ACCEL)]
    segs.append(PathSegment(lo, q, v, ACCEL, 0.5))
    return Path(tuple(segs)).sample(rate)


def run_breakaway(url: str, plan: BreakawayPlan, log_path: str, robot: str = "puma260",
                  extra_meta: dict | None = None, timeout: float | None = 5.0) -> int:
    """Run ``plan`` on the robot (or simula) at ``url``; returns the records logged.

    Each ramp starts from the motor torque that holds the arm against gravity (the data
    file's gravity model, through G^-T), so that both directions ramp from the balance.
    """
    from rcci.calib.robot import robot_info

    from rcci.models import load_robot

    info = robot_info(robot)
    vmax = np.asarray(load_robot(robot).max_velocity, dtype=float)
    gravity = info.gravity(np.array([info.nominal["gravity_coeffs"][n]["value"]
                                     for n in info.gravity_names]))
    conv = Conversions.for_robot(robot)
    rate = plan.rate_hz
    j = plan.joint - 1
    meta = dict(plan.meta)
    meta.update(extra_meta or {})
    meta.update({"program": f"calib record {plan.name}", "log_name": plan.name, "rate_hz": rate})
    # the steps: (kind, setpoints or (position, direction))
    steps: list[tuple[str, object]] = []
    first = plan.pose.copy()
    first[j] = plan.positions[0]
    warm = sweep_warmup(first, j, first[j] - plan.warm_half, first[j] + plan.warm_half,
                        speed=min(WARMUP_SPEED, 0.8 * float(vmax[j])), seconds=FRICTION_WARMUP_S,
                        dwell=0.0).within(vmax)
    steps.append(("warm", warm.sample(rate)))
    here = warm.segments[-1].end
    for x in plan.positions:
        q = plan.pose.copy()
        q[j] = x
        for d in (1, -1):
            steps.append(("move", Path((PathSegment(here, q, 0.6, ACCEL, 0.5),)).within(vmax).sample(rate)))
            steps.append(("ramp", (q, d)))
            steps.append(("warm", _sweep(q, j, plan.sweep_half, BETWEEN_S, rate, vmax)))
            here = q
    state = {"step": 0, "k": 0, "hold": None, "onset": None, "c0": None, "power": False}
    done = threading.Event()
    rec, session = open_measurement(url, robot, rate, log_path, meta, timeout)

    def back_from(held: np.ndarray, q: np.ndarray) -> np.ndarray:
        """Setpoints from where a ramp's breakaway left the joint back to the ramp's pose: the
        joint may have slid degrees past it (a heavy joint that breaks away at a high torque),
        more than one cycle's step at its velocity limit (R_REQVEL)."""
        return Path((PathSegment(np.asarray(held, dtype=float), q, 0.6, ACCEL, 0.2),)).within(vmax).sample(rate)

    def pos_all(qd: np.ndarray) -> None:
        command_joints(session, conv, qd)

    def f1() -> None:
        how = session.how
        if not state["power"]:
            if not how.state & codes.POWER_ON:
                session.chg.power_on.issue()
            state["power"] = True
            # from wherever the arm is to the start of the warm-up (not recorded)
            start = conv.counts_to_angles(np.asarray(how.pos[:conv.n], dtype=float))
            steps.insert(0, ("warm", Path((PathSegment(start, steps[0][1][0], 0.6, ACCEL, 0.5),))
                             .within(vmax).sample(rate)))
        if state["step"] >= len(steps):
            session.record(None)
            done.set()
            pos_all(steps[-1][1][-1])
            return
        kind, what = steps[state["step"]]
        k = state["k"]
        state["k"] += 1
        if kind in ("warm", "move"):
            sp = what
            pos_all(sp[min(k, len(sp) - 1)])
            if k >= len(sp) - 1:
                state["step"] += 1
                state["k"] = 0
                if kind == "move":
                    session.record(rec)          # the ramp's lead-in: a still joint
            return
        q, d = what
        e = int(how.pos[j])
        if k == 0:
            state["c0"], state["onset"], state["hold"] = e, None, None
        if state["hold"] is not None:            # after the breakaway: hold where it is
            pos_all(state["hold"])
            if k - state["onset"] > AFTER_ONSET + int(0.3 * rate):
                session.record(None)
                state["step"] += 1
                state["k"] = 0
                steps.insert(state["step"], ("warm", back_from(state["hold"], q)))
            return
        # the motor torques that hold the arm against gravity, t_s = G^-T t_g: on the
        # coupled wrist the motors of the later joints, holding theirs, also load this one
        ts = conv.joint_to_motor_torques(gravity(q))[j] + d * plan.ramp_rate * k / rate
        if state["onset"] is None and abs(e - state["c0"]) >= MOVED_COUNTS:
            state["onset"] = k
        if state["onset"] is not None and k - state["onset"] >= AFTER_ONSET or k / rate > 2 * RAMP_S:
            state["onset"] = k if state["onset"] is None else state["onset"]
            qh = conv.counts_to_angles(np.asarray(how.pos[:conv.n], dtype=float))
            qh[np.arange(conv.n) != j] = q[np.arange(conv.n) != j]
            state["hold"] = qh
            pos_all(qh)
            return
        pos_all(q)
        dac = int(np.clip(np.rint(ts * conv.k_dac[j]), DAC_MIN, DAC_MAX))
        session.chg.motion[j].issue(CUR, dac)

    drive_recorded(session, f1, done, rec, plan.name, url, lambda: f"at step {state['step']}")
    return rec.written
