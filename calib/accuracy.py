"""How well RCCL positions a simulated arm with the nominal and with the calibrated kinematics.

``positioning_error`` runs RCCL (rccl.open, joint-mode moves, the arm's configuration
kept) on a lockstep simula built from a parameter file with DH errors (the truth), to
a set of target poses of link 6 spread over the workspace; after each move it reads the
encoders as the robot reports them and puts them through the truth's exact forward
kinematics (the A-matrix product with the truth's errors, which equals simula's
Pinocchio model to rounding: tests/test_calib_kinematic_loop.py). The error of a target
is how far the arm's true T6 (and the probe tip, rcci.calib.touch.TIP, on it) is from where
RCCL was told to put it. Three runs: RCCL with the nominal kinematics, with the
calibrated ones (``fitted``), and with the truth's own (the floor that the encoder counts
the joints are commanded in leave).

``cycle_cost`` is the trajectory generator's CPU time per control cycle (Cartesian mode,
thesis Table 5.1's measure) with each kinematics, measured in the same run.
"""
from __future__ import annotations

import gc
import time
from dataclasses import dataclass

import numpy as np

from rcci.calib.touch import TIP, tool_transform

RATE_HZ = 36
CENTRE = np.radians([90.0, 60.0, -150.0, 20.0, -50.0, 30.0])   # a pose in front, elbow up
SPREAD = np.radians([35.0, 20.0, 25.0, 40.0, 30.0, 60.0])
TOUR_START = np.radians([0.0, 80.0, -170.0, 10.0, -60.0, 0.0])   # bench/rccl_cycle.py's start


@dataclass(frozen=True)
class Accuracy:
    """Position errors (m) of T6's origin and of the probe tip, and orientation errors (rad),
    one per target, for one kinematics."""

    name: str
    t6: np.ndarray
    tip: np.ndarray
    angle: np.ndarray

    def row(self) -> tuple[float, float, float, float, float]:
        """(T6 RMS, T6 max, tip RMS, tip max, orientation RMS)."""
        rms = lambda a: float(np.sqrt(np.mean(a ** 2)))  # noqa: E731
        return rms(self.t6), float(self.t6.max()), rms(self.tip), float(self.tip.max()), rms(self.angle)


def targets(n: int, seed: int = 7, robot: str = "puma260") -> list[np.ndarray]:
    """``n`` T6 targets (nominal fk of joint angles around CENTRE, one configuration, away
    from the wrist singularity)."""
    from rccl.kinematics import load

    kin = load(robot)
    rng = np.random.default_rng(seed)
    want = kin.config_of(CENTRE)
    out = []
    while len(out) < n:
        q = CENTRE + rng.uniform(-1, 1, 6) * SPREAD
        if abs(np.sin(q[4])) < 0.3 or kin.config_of(q) != want or np.any(q < kin.LOWER) or np.any(q > kin.UPPER):
            continue
        out.append(kin.fk(q))
    return out


def _angle(A: np.ndarray, B: np.ndarray) -> float:
    c = (np.trace(A[:3, :3].T @ B[:3, :3]) - 1.0) / 2.0
    return float(np.arccos(np.clip(c, -1.0, 1.0)))


def _run(url: str, kinematics, goals: list[np.ndarray], truth_fk, name: str, robot: str) -> Accuracy:
    import rccl
    from rccl import EQ, T6, TL, Trsf, makeposition

    tool = tool_transform(TIP)
    e6, et, ea = [], [], []
    with rccl.open(url, robot=robot, kinematics=kinematics, rate_hz=RATE_HZ, timeout=2.0) as arm:
        arm.setmod("joint")
        arm.setvel(0.3, 2.0)
        start = makeposition("start", T6, EQ, Trsf("S", arm.kinematics.fk(CENTRE)), TL, T6)
        arm.move(start)
        arm.waitfor(start.end)
        for k, goal in enumerate(goals):
            p = makeposition(f"t{k}", T6, EQ, Trsf(f"T{k}", goal), TL, T6)
            arm.move(p)
            arm.waitfor(p.end)
            arm.rci.wait(4.0 / RATE_HZ)          # the servo has reached the last setpoint
            T = truth_fk(arm.measured_q())
            e6.append(np.linalg.norm(T[:3, 3] - goal[:3, 3]))
            et.append(np.linalg.norm((T @ tool)[:3, 3] - (goal @ tool)[:3, 3]))
            ea.append(_angle(T, goal))
    return Accuracy(name, np.array(e6), np.array(et), np.array(ea))


def positioning_error(truth_params: str, fitted_params: str, n: int = 20, seed: int = 7,
                      robot: str = "puma260") -> list[Accuracy]:
    """RCCL's positioning error on a simula built from ``truth_params``: nominal, calibrated
    (``fitted_params``' [kinematics]) and the truth's own kinematics (the floor)."""
    from rccl.calibrated import calibrated_kinematics, load_calibrated
    from rccl.session import load_kinematics
    from rci.simula.process import SimulaProcess

    truth = load_calibrated(truth_params, robot)
    goals = targets(n, seed, robot)
    out = []
    with SimulaProcess("-p", "--power-on", "--warm", "--params", truth_params, robot=robot,
                       lockstep=True, seed=seed) as sim:
        for name, kin in (("nominal DH table", load_kinematics(robot)),
                          ("calibrated (calib fit kinematics)", calibrated_kinematics(fitted_params, robot)),
                          ("the truth's own (floor)", calibrated_kinematics(truth_params, robot))):
            out.append(_run(sim.url, kin, goals, truth.fk, name, robot))
    return out


def cycle_cost(kinematics, cycles: int = 3000, robot: str = "puma260", repeats: int = 3) -> dict:
    """CPU time (us) of the trajectory generator's step per cycle, Cartesian mode, on a
    tour of four positions 5 cm apart (as bench/rccl_cycle.py), with ``kinematics``: the
    run with the lowest mean of ``repeats``."""
    runs = [_cycle_cost(kinematics, cycles, robot) for _ in range(repeats)]
    return min(runs, key=lambda r: r["mean"])


def _cycle_cost(kinematics, cycles: int, robot: str) -> dict:
    from rccl.limits import load_limits
    from rccl.planner import Planner
    from rccl.position import EQ, TL, makeposition
    from rccl.trajectory import TrajectoryGenerator
    from rccl.transform import T6, Trsf, rot, trsl

    limits = load_limits(robot)
    gen = TrajectoryGenerator(kinematics, limits, 1.0 / RATE_HZ, TOUR_START)
    arm = Planner(kinematics, limits, gen)
    arm.setmod("cartesian")
    arm.setvel(0.1, 1.0)
    base = kinematics.fk(TOUR_START)
    offsets = [trsl(0.05, 0.0, 0.0), trsl(0.05, 0.05, 0.02) @ rot("z", 0.2), trsl(0.0, 0.05, 0.0) @ rot("x", 0.1),
               trsl(0.0, 0.0, 0.0)]
    positions = [makeposition(f"p{i}", T6, EQ, Trsf(f"P{i}", o @ base), TL, T6) for i, o in enumerate(offsets)]
    times = np.empty(cycles)
    clock = time.thread_time_ns
    gc.disable()
    try:
        for k in range(cycles):
            if len(arm.queue) < 2:
                for p in positions:
                    arm.move(p)
            t0 = clock()
            gen.step()
            times[k] = clock() - t0
    finally:
        gc.enable()
    if gen.errors:
        raise RuntimeError(f"generator reported errors: {gen.errors[:3]}")
    us = times / 1e3
    return {"mean": float(us.mean()), "median": float(np.median(us)), "p99": float(np.percentile(us, 99))}


def ik_cost(kin, calls: int = 3000, repeats: int = 5) -> float:
    """CPU time (us) of one ``ik`` call along a 5 cm straight line (successive poses
    1/``calls`` apart, as the generator asks them); the best of ``repeats`` runs (the
    others met more interference from the machine's other work)."""
    from rccl.transform import trsl

    base = kin.fk(TOUR_START)
    config = kin.config_of(TOUR_START)
    poses = [trsl(0.05 * k / calls, 0.0, 0.0) @ base for k in range(calls)]
    best = np.inf
    for _ in range(repeats):
        q = TOUR_START.copy()
        t0 = time.thread_time_ns()
        for T in poses:
            q = kin.ik(T, config, q)
        best = min(best, (time.thread_time_ns() - t0) / calls / 1e3)
    return float(best)
