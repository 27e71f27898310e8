"""The composition matrix of issue 25: generator x feature x arm x link, each cell on a lockstep simula.

    .venv/bin/python -m tests.composition --report reports/composition.md      # the whole matrix
    .venv/bin/python -m tests.composition --arm puma260 --link socket          # a slice, printed

Every cell opens one ``rccl.open(url, robot, trajectory=generator)`` arm on a lockstep
``simula --robot ARM`` reached over the link (TCP socket, or Zenoh), moves to the arm's
start pose (joint mode) and exercises one feature in free air. Its verdict:

- ``pass``: the feature did what it promises (each runner below says what it checks);
- ``refused``: a primitive refused the combination before the motion started, or the force
  estimate was refused at the motion's start, with the message shown (the sentence a user
  reads);
- ``fail``: anything else (a wrong outcome, an error during the motion, a broken arm).

Imported by tests/test_composition.py (a subset by default, the whole matrix under the
``matrix`` marker).
"""
from __future__ import annotations

import argparse
import contextlib
import math
import sys
import time
import traceback
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterator

import numpy as np

import rccl
from rccl import EQ, T6, TL, BadRequest, TrajectoryFault, Trsf, makeposition

GENERATORS = ("quartic", "ruckig")
FEATURES = ("plain", "functional", "force_limit", "deviation_limit", "monitor", "compliance", "conditional",
            "event_flags", "rate_change", "feedforward", "collision", "redundancy")
ARMS = ("puma260", "microbo", "puma560", "stanford", "panda")
LINKS = ("socket", "zenoh")

# joint values (rad, m) away from every singularity and joint stop, as in the per-arm tests
START = {
    "puma260": np.radians([10.0, 80.0, -170.0, 10.0, -60.0, 5.0]),
    "microbo": np.array([0.2, 0.20, 0.32, math.radians(-80.0), math.radians(100.0), 0.1]),
    "puma560": np.array([0.2, 1.2, -2.8, 0.3, -0.8, 0.1]),
    "stanford": np.array([0.2, 1.2, 0.7, 0.3, 0.8, 0.1]),
    # the Panda's ready pose turned a little at the base and the wrist (7 joints)
    "panda": np.array([0.2, -0.785, 0.0, -2.356, 0.0, 1.571, 0.6]),
}
DIRECTION = np.array([0.6, -0.48, 0.36]) / np.linalg.norm([0.6, -0.48, 0.36])   # of every line (base frame)
LINE = 0.02            # m, the length of a cell's Cartesian line
SPEED = 0.02           # m/s, its setvel (the issue's rate-change speed)
WAIT = 60.0            # s of wall time a cell may wait for one motion (the machine is shared)


@dataclass
class Verdict:
    """One cell's outcome: ``status`` pass / refused / fail, ``detail`` a sentence with the figures."""

    status: str
    detail: str


class Refused(Exception):
    """A combination refused before its motion started; the message is the user's sentence."""


class Failed(AssertionError):
    """A cell's check did not hold."""


def expect(ok: bool, what: str) -> None:
    if not ok:
        raise Failed(what)


# --- the robot side ---------------------------------------------------------------------------
@contextlib.contextmanager
def simula(robot: str, link: str) -> Iterator:
    """A powered lockstep ``simula --robot ROBOT`` on ``link`` ("socket" or "zenoh")."""
    from rci.simula.process import SimulaProcess
    # a control thread descheduled for seconds on a shared machine (load 12-16) is not what a cell
    # tests: simula waits 10 s for a CHG before ending the control (its default is 3 s)
    args = ["-p", "--power-on", "--lockstep-watchdog", "10"]
    if link == "zenoh":
        from rci.bus.link import free_endpoint
        args += ["--zenoh", f"matrix/{robot}", "--zenoh-listen", free_endpoint()]
    elif link != "socket":
        raise ValueError(f"link {link!r} is not one of {LINKS}")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        with SimulaProcess(*args, robot=robot, lockstep=True) as sim:
            yield sim


def open_arm(url: str, robot: str, generator: str):
    # timeout: a lockstep simula may be descheduled for seconds on a shared machine (load 16 seen)
    return rccl.open(url, robot, trajectory=generator, record=True, on_error="raise", timeout=5.0)


def start(arm) -> np.ndarray:
    """Joint-mode move to the arm's start pose; returns T6 there."""
    q = START[arm.robot]
    if not arm.powered:          # an earlier cell's severe end switched the power off: not this cell's matter
        arm.power_on()
    arm.setmod("joint")
    arm.setvel(0.1, 1.0)
    p = makeposition("start", T6, EQ, Trsf("START", arm.kinematics.fk(q)), TL, T6)
    arm.move(p)
    wait(arm, p)
    return arm.t6


def wait(arm, p) -> None:
    """Wait for position ``p``'s motion to end (bounded in wall time)."""
    try:
        p.end.wait(fault=arm.check, timeout=WAIT)
    except TimeoutError:
        raise Failed(f"the motion to {p.name} did not end within {WAIT:.0f} s") from None
    arm.check()


def line_to(t6: np.ndarray, length: float = LINE, name: str = "goal"):
    goal = t6.copy()
    goal[:3, 3] += length * DIRECTION
    return makeposition(name, T6, EQ, Trsf(name.upper(), goal), TL, T6), goal


def cartesian(arm, speed: float = SPEED) -> None:
    arm.setmod("cartesian")
    arm.setvel(speed, 0.5)


def settle(arm, seconds: float = 0.2) -> None:
    """Let ``seconds`` of trajectory time pass."""
    t_end = arm.gen.t + seconds
    arm.rci.wait(WAIT, until=lambda: arm.gen.t >= t_end)


def reached(arm, goal: np.ndarray, tol: float = 1e-3) -> float:
    """Distance (m) between the measured tool point and ``goal``'s; a Failed beyond ``tol``."""
    settle(arm)
    err = float(np.linalg.norm(arm.kinematics.fk(arm.measured_q())[:3, 3] - goal[:3, 3]))
    expect(err <= tol, f"the tool stopped {err * 1e3:.2f} mm from the goal")
    return err


# --- the features -----------------------------------------------------------------------------
def plain(arm) -> str:
    """A 20 mm Cartesian line: reached within 1 mm (measured)."""
    p, goal = line_to(start(arm))
    cartesian(arm)
    arm.move(p)
    wait(arm, p)
    return f"line reached, {reached(arm, goal) * 1e3:.2f} mm off"


def functional(arm) -> str:
    """A target on a belt moving 10 mm/s for 1 s: called once per sample, followed within 3 mm."""
    t6 = start(arm)
    cartesian(arm, 0.05)
    calls = [0]
    t0 = arm.gen.t

    def belt(tr):
        calls[0] += 1
        m = t6.copy()
        m[:3, 3] += 0.01 * min(arm.gen.t - t0, 1.0) * DIRECTION
        tr.set(m)

    b = Trsf("BELT", t6)
    b.bind(belt)
    p = makeposition("on_belt", T6, EQ, b, TL, T6)
    n0 = arm.gen.samples
    arm.move(p)
    arm.rci.wait(WAIT, until=lambda: arm.gen.t >= t0 + 1.5 or arm.gen.faulted is not None)
    arm.check()
    n = arm.gen.samples - n0
    expect(abs(calls[0] - n) <= 2, f"the function was called {calls[0]} times in {n} samples")
    b.bind(None)
    wait(arm, p)
    err = reached(arm, b.value_array, 3e-3)
    return f"called {calls[0]} times in {n} samples, {err * 1e3:.2f} mm off the belt's end"


def force_limit(arm) -> str:
    """A 50 N limit lets a line complete in free air (a monitor records the peak estimate); a 1 mN one
    ends the line back at once (the estimate's noise passes it) and the arm holds."""
    t6 = start(arm)
    p, goal = line_to(t6)
    cartesian(arm)
    peak = [0.0]

    def record(s):
        peak[0] = max(peak[0], float(np.abs(s.force[:3]).max()))
        return 0

    arm.limit("fx fy fz", 50.0, 50.0, 50.0)
    arm.evalfn(record, needs=("force",))
    r1 = arm.move(p)
    wait(arm, p)
    expect(r1.ended is None, f"the 50 N limit ended a line in free air ({r1.ended})")
    q, _ = line_to(goal, -LINE, "back")
    arm.limit("fx fy fz", 1e-3, 1e-3, 1e-3)
    req = arm.move(q)
    try:
        wait(arm, q)
    except TrajectoryFault as exc:
        why = _refusal(exc)
        if why is None:
            raise
        raise Refused(f"50 N in free air: completed (peak estimate {peak[0]:.1f} N); a 1 mN limit: {why}") from None
    end = req.ended
    expect(end is not None and end.reason == "limit", f"the line was not ended by its 1 mN limit (ended: {end})")
    q_stop = arm.measured_q()
    settle(arm, 0.3)
    drift = float(np.abs(arm.measured_q() - q_stop).max())
    return (f"free air: peak force estimate {peak[0]:.1f} N under a 50 N limit, completed; 1 mN: ended on "
            f"{end.what} = {end.value:.3g} N at t = {end.t:.3f} s, joints drift {drift:.1e} after")


def deviation_limit(arm) -> str:
    """A 5 mm deviation limit lets a line complete; a 1 um one ends the next line (the servo lags more)."""
    t6 = start(arm)
    p, goal = line_to(t6)
    cartesian(arm)
    arm.limit("dx dy dz", 0.005, 0.005, 0.005)
    r1 = arm.move(p)
    wait(arm, p)
    expect(r1.ended is None, f"the 5 mm deviation limit ended the line ({r1.ended})")
    q, _ = line_to(goal, -LINE, "back")
    arm.limit("dx dy dz", 1e-6, 1e-6, 1e-6)
    r2 = arm.move(q)
    wait(arm, q)
    expect(r2.ended is not None and r2.ended.reason == "limit", f"the 1 um limit did not end the line ({r2.ended})")
    return f"5 mm: completed; 1 um: ended on {r2.ended.what} = {r2.ended.value * 1e6:.1f} um"


def monitor(arm) -> str:
    """evalfn ends a line after 10 samples with its code; it saw the torques every sample."""
    p, _ = line_to(start(arm))
    cartesian(arm)
    seen = []

    def after_ten(s):
        seen.append(s.torque is not None)
        return 7 if len(seen) >= 10 else 0

    arm.evalfn(after_ten)
    req = arm.move(p)
    wait(arm, p)
    expect(req.ended is not None and req.ended.reason == "monitor", f"the monitor did not end the line ({req.ended})")
    expect(len(seen) == 10 and all(seen), f"the monitor ran {len(seen)} times, torques {seen}")
    return f"ended after {len(seen)} samples with code {req.ended.code}"


def compliance(arm) -> str:
    """comply("fz", -2) during a line: a joint force-servoed every sample of it; lock restores position servoing."""
    p, _ = line_to(start(arm), 0.01)
    cartesian(arm)
    n0 = len(arm.adaptive_trace)
    arm.comply("fz", -2.0)
    arm.move(p)
    wait(arm, p)
    arm.lock("fz")
    settle(arm, 0.2)
    trace = arm.adaptive_trace[n0:]
    forced = sum(1 for x in trace if x[4])
    expect(forced > 0.5 * len(trace) - 15, f"only {forced} of {len(trace)} cycles force-servoed a joint")
    expect(not arm.last_command.current, "a joint is still current-servoed after lock")
    joints = sorted({j for x in trace for j in x[4]})
    return f"{forced} of {len(trace)} cycles force-servoed joint(s) {[j + 1 for j in joints]}; locked"


def conditional(arm) -> str:
    """A monitor ends a line; cond("monitor", alt) runs alt instead of the queued rest (5.6.1)."""
    t6 = start(arm)
    p, _ = line_to(t6)
    alt, alt_goal = line_to(t6, -0.01, "alt")
    rest, _ = line_to(t6, 0.5 * LINE, "rest")
    cartesian(arm)
    n = [0]
    arm.evalfn(lambda s: n.__setitem__(0, n[0] + 1) or (1 if n[0] >= 8 else 0))
    req = arm.move(p)
    branch = arm.cond("monitor", alt)
    r_rest = arm.move(rest)
    wait(arm, alt)
    expect(req.chosen is branch and branch.status == "done", f"the branch did not run ({branch.status})")
    expect(r_rest.status == "failed", f"the queued request was not dropped ({r_rest.status})")
    return f"branch taken after {n[0]} samples, queued request dropped, {reached(arm, alt_goal) * 1e3:.2f} mm off"


def event_flags(arm) -> str:
    """move_ev: the first motion runs to DONE; a stop code (stop_ev) ends the second early."""
    from rccl import events as ev
    t6 = start(arm)
    p, goal = line_to(t6)
    cartesian(arm)
    try:
        try:
            e1 = ev.move_ev(arm, p)
        except ev.EventError as exc:
            if arm.rci.in_control and arm.gen is not None and "control is running" in str(exc):
                raise Failed(f"refused with a wrong reason (the control is running, its generator is "
                             f"{type(arm.gen).__name__}): {exc}") from None
            raise Refused(str(exc)) from None
        expect(ev.wait_ev(e1, timeout=WAIT) == ev.DONE, f"the first motion ended {ev.code_name(e1.stop)}")
        q, _ = line_to(goal, -LINE, "back")
        e2 = ev.move_ev(arm, q)
        expect(ev.wait_ev(e2, started=True, timeout=WAIT) is not None, "the second motion did not start")
        settle(arm, 0.2)
        ev.stop_ev(-5, e2)
        code = ev.wait_ev(e2, timeout=WAIT)
        expect(code == -5 and e2.request.ended is not None, f"the stop code did not end the motion ({code})")
    finally:
        ev.detach(arm)
    return "DONE, then ended by stop code -5"


def rate_change(arm) -> str:
    """36 -> 250 -> 1000 Hz during a 20 mm line at 20 mm/s: commanded speed <= setvel, duration as programmed."""
    p, goal = line_to(start(arm))
    cartesian(arm)
    n0 = len(arm.clock_trace)
    t0 = arm.gen.t
    arm.move(p)
    for at, rate in ((0.3, 250), (0.6, 1000)):
        arm.rci.wait(WAIT, until=lambda: arm.gen.t >= t0 + at or arm.gen.faulted is not None)
        with arm.rci.chg.lock:
            arm.rci.chg.rate.issue(1, rate)
    wait(arm, p)
    n1 = len(arm.clock_trace)
    clock = np.array(arm.clock_trace[n0:n1])
    pc = np.array([arm.kinematics.fk(x[1])[:3, 3] for x in arm.trace[n0:n1]])
    period = np.diff(clock)
    speed = np.linalg.norm(np.diff(pc, axis=0), axis=1)[:-1] / period[1:]
    moving = np.nonzero(speed > 1e-4)[0]
    duration = float(clock[moving[-1] + 1] - clock[moving[0]])
    rates = [r for _, r in arm.rate_changes]
    expect(rates == [250, 1000], f"the generator saw the rates {rates}")
    expect(speed.max() <= SPEED * 1.001, f"the tool was commanded at {speed.max() * 1e3:.1f} mm/s")
    expect(duration >= LINE / SPEED, f"the line took {duration:.3f} s, less than {LINE / SPEED:.1f} s at setvel")
    err = reached(arm, goal)
    return f"max {speed.max() * 1e3:.2f} mm/s, {duration:.2f} s, rates {rates}, {err * 1e3:.2f} mm off"


def feedforward(arm) -> str:
    """At 250 Hz, computed torque (rccl.feedforward) over the 20 mm line: every joint current-servoed every
    cycle of it, the line reached within 1 mm; compliance refused meanwhile; position mode restores POS."""
    t6 = start(arm)
    with arm.rci.chg.lock:
        arm.rci.chg.rate.issue(1, 250)
    arm.rci.wait(WAIT, until=lambda: arm.rate_hz == 250 or arm.gen.faulted is not None)
    p, goal = line_to(t6)
    cartesian(arm)
    arm.feedforward("computed")
    try:
        arm.comply("fz", -2.0)
    except BadRequest:
        pass
    else:
        raise Failed("comply was accepted with feed-forward on")
    n0 = len(arm.adaptive_trace)
    arm.move(p)
    wait(arm, p)
    err = reached(arm, goal)
    trace = arm.adaptive_trace[n0:]
    # from the motion's first cycle on, every cycle current-servoes all the joints; the cycles before it
    # (while the planning level queues the move: more of them on a loaded machine) are position mode
    nj = len(arm.q)
    first = next((i for i, x in enumerate(trace) if len(x[4]) == nj), None)
    expect(first is not None, f"none of {len(trace)} cycles current-servoed all {nj} joints")
    full = sum(1 for x in trace[first:] if len(x[4]) == nj)
    expect(full == len(trace) - first, f"only {full} of the {len(trace) - first} cycles from the motion's start "
                                       f"current-servoed all {nj} joints")
    arm.feedforward("position")
    q, _ = line_to(goal, -0.005, "back")
    arm.move(q)
    wait(arm, q)
    expect(not arm.last_command.current, "a joint is still current-servoed in position mode")
    return (f"{full} of {len(trace) - first} cycles from the start computed torque on {nj} joints, {err * 1e3:.2f} mm off, "
            f"{arm.ff_control.saturated} clipped; comply refused; position mode restored")


FLOOR = {"puma260": -0.40, "microbo": -0.08, "puma560": 0.0, "stanford": 0.0, "panda": 0.0}   # m: the table under each base
CLEARANCE = 0.005      # m, the collision cell's margin


def _box_at(p: np.ndarray, half: float = 0.005) -> str:
    """simula's word for a cube of side 2 ``half`` (m) centred on ``p`` (base frame)."""
    return ",".join(f"{a}0={v - half:.4f},{a}1={v + half:.4f}" for a, v in zip("xyz", p)).join(("box:", ""))


def collision(arm) -> str:
    """arm.collisions(...) on: a line above the table is checked and reached; a line ending in a 10 mm box is
    refused before it moves (PathCollision naming the box); a target drawn towards that box by a function
    is stopped by the per-cycle check before the wrist reaches it, and the arm holds."""
    from rccl import PathCollision
    t6 = start(arm)
    guard = arm.collisions(env=[f"plane:z={FLOOR[arm.robot]}"], margin=CLEARANCE)
    p, goal = line_to(t6)
    cartesian(arm)
    arm.move(p)
    checked = guard.samples_checked
    wait(arm, p)
    err = reached(arm, goal)
    # the box: the nearest point along the line (10 mm steps) that leaves the arm 3 margins clear at the goal
    from rccl.collision import CollisionWorld
    q_goal = arm.q
    for ahead in np.arange(0.03, 0.31, 0.01):
        box = _box_at(goal[:3, 3] + ahead * DIRECTION)
        world = CollisionWorld(arm.robot, (box,))
        if min(d for d, pair in zip(world.distances(q_goal), world.pairs) if pair[1] == f"env:{box}") > 3 * CLEARANCE:
            break
    arm.collisions(env=[box], margin=CLEARANCE)
    into, _ = line_to(goal, ahead, "into_box")
    q0 = arm.q
    try:
        arm.move(into)
        raise Failed("the line into the box was accepted")
    except PathCollision as exc:
        expect(exc.pair[1] == f"env:{box}", f"the refusal named {exc.pair}, not the box")
        refusal = exc
    expect(np.array_equal(arm.q, q0) and not arm.gen.busy, "the arm moved after the refusal")
    t0 = arm.gen.t

    def towards(tr):                 # 10 mm/s along the line, into the box
        m = goal.copy()
        m[:3, 3] += 0.01 * (arm.gen.t - t0) * DIRECTION
        tr.set(m)

    f = Trsf("TOWARDS", goal)
    f.bind(towards)
    drawn = makeposition("drawn", T6, EQ, f, TL, T6)
    arm.settime(0.2, 4.0)
    arm.move(drawn)
    try:
        wait(arm, drawn)
        raise Failed("the per-cycle check did not stop the target drawn into the box")
    except TrajectoryFault as exc:
        expect(isinstance(exc.cause, PathCollision) and exc.cause.pair[1] == f"env:{box}",
               f"the motion ended with {exc!r}, not the per-cycle collision stop")
        stop = exc.cause
    held, n0 = arm.q, len(arm.trace)
    arm.rci.wait(WAIT, until=lambda: len(arm.trace) >= n0 + 10)       # ten cycles (the frozen generator's t stands)
    expect(np.array_equal(arm.q, held), "the arm did not hold after the per-cycle stop")
    arm.recover()
    arm.collisions_off()
    return (f"line reached {err * 1e3:.2f} mm off ({checked} samples checked); a line {ahead * 1e3:.0f} mm into a "
            f"box refused at {refusal.fraction * 100:.0f}% ({refusal.pair[0]}, {refusal.distance * 1e3:.1f} mm); a "
            f"target drawn into it stopped {stop.distance * 1e3:.1f} mm from it, the arm holds")


SELF_TURN = 0.2      # rad, the redundancy cell's self-motion of q7


def redundancy(arm) -> str:
    """A 7-joint arm (rccl.redundancy): the 20 mm line with q7 far from limits and singularities
    (setfree("far")) reached within 1 mm, q7 changing at most FAR_STEP per sample; then a 1 s
    self-motion of q7 by 0.2 rad: the commanded T6 stands still (1e-9) and q7 ends on the target.
    A 6-joint arm refuses setfree with its sentence."""
    from rccl.redundancy import FAR_STEP
    t6 = start(arm)
    p, goal = line_to(t6)
    cartesian(arm)
    arm.setfree("far")
    n0 = len(arm.trace)
    arm.move(p)
    wait(arm, p)
    err = reached(arm, goal)
    q7 = np.array([x[1][6] for x in arm.trace[n0:]])
    step = float(np.abs(np.diff(q7)).max())
    expect(step <= FAR_STEP + 1e-12, f"q7 moved {step:.4f} rad in one sample (rule: {FAR_STEP} at most)")
    arm.setfree()
    here, target = arm.t6.copy(), float(arm.q[6]) - SELF_TURN
    n0 = len(arm.trace)
    req = arm.selfmove(q7=target, duration=1.0)
    wait(arm, req.position)
    trace = arm.trace[n0:]
    still = max(float(np.abs(arm.kinematics.fk(x[1]) - here).max()) for x in trace)
    expect(still < 1e-9, f"the commanded T6 moved {still:.2e} during the self-motion")
    expect(abs(arm.q[6] - target) < 1e-9, f"q7 ended at {arm.q[6]:.6f}, not {target:.6f} rad")
    return (f"far: line reached {err * 1e3:.2f} mm off, q7 steps <= {step:.4f} rad; self-motion of q7 by "
            f"{SELF_TURN} rad with T6 still to {still:.1e}")


RUNNERS: dict[str, Callable] = {f: globals()[f] for f in FEATURES}


# --- cells ------------------------------------------------------------------------------------
def _refusal(exc: BaseException) -> str | None:
    """The message of an exception that is a refusal before (or at the start of) the motion, else None."""
    from rccl.adaptive.exceptions import ForceEstimateError
    if isinstance(exc, Refused):
        return str(exc)
    if isinstance(exc, BadRequest):
        return str(exc)
    if isinstance(exc, TrajectoryFault) and isinstance(exc.cause, ForceEstimateError):
        return str(exc.cause)
    return None


def run_cell(url: str, robot: str, generator: str, feature: str) -> Verdict:
    """One cell on the simula at ``url``; never raises."""
    try:
        with open_arm(url, robot, generator) as arm:
            try:
                detail = RUNNERS[feature](arm)
            except BaseException:
                with contextlib.suppress(Exception):
                    arm.recover()
                raise
        return Verdict("pass", detail)
    except Failed as exc:
        return Verdict("fail", str(exc))
    except Exception as exc:          # noqa: BLE001 - every other outcome is recorded, not raised
        why = _refusal(exc)
        if why is not None:
            return Verdict("refused", why)
        tb = traceback.extract_tb(exc.__traceback__)[-1]
        return Verdict("fail", f"{type(exc).__name__}: {exc} ({Path(tb.filename).name}:{tb.lineno})")


def run_matrix(arms=ARMS, links=LINKS, generators=GENERATORS, features=FEATURES,
               log: Callable[[str], None] = print) -> list[tuple[str, str, str, str, Verdict, float]]:
    """Every cell of the slice; one simula per (arm, link)."""
    rows = []
    for robot in arms:
        for link in links:
            with simula(robot, link) as sim:
                for gen in generators:
                    for feat in features:
                        t0 = time.monotonic()
                        v = run_cell(sim.url, robot, gen, feat)
                        dt = time.monotonic() - t0
                        rows.append((gen, feat, robot, link, v, dt))
                        log(f"{robot:9s} {link:6s} {gen:8s} {feat:16s} {v.status:8s} {dt:5.1f} s  {v.detail}")
    return rows


def report(rows, command: str) -> str:
    """The markdown report: counts, then one table per arm and link."""
    counts = {s: sum(1 for r in rows if r[4].status == s) for s in ("pass", "refused", "fail")}
    out = ["# Composition matrix (issue 25)", "",
           f"Command: `{command}` (each cell on a lockstep simula; tests/composition.py says what each "
           "feature's cell checks).", "",
           f"Cells: {len(rows)}; pass {counts['pass']}, refused {counts['refused']}, fail {counts['fail']}.", ""]
    for robot in dict.fromkeys(r[2] for r in rows):
        for link in dict.fromkeys(r[3] for r in rows if r[2] == robot):
            out += [f"## {robot}, {link}", "", "| feature | generator | verdict | detail | s |", "|---|---|---|---|---|"]
            for gen, feat, rb, lk, v, dt in rows:
                if rb == robot and lk == link:
                    out.append(f"| {feat} | {gen} | {v.status} | {v.detail.replace('|', '/')} | {dt:.1f} |")
            out.append("")
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tests.composition", description=__doc__.splitlines()[0])
    ap.add_argument("--report", type=Path, help="write the markdown report here")
    ap.add_argument("--arm", action="append", choices=ARMS)
    ap.add_argument("--link", action="append", choices=LINKS)
    ap.add_argument("--generator", action="append", choices=GENERATORS)
    ap.add_argument("--feature", action="append", choices=FEATURES)
    a = ap.parse_args(argv)
    rows = run_matrix(a.arm or ARMS, a.link or LINKS, a.generator or GENERATORS, a.feature or FEATURES)
    if a.report:
        cmd = "python -m tests.composition " + " ".join(argv if argv is not None else sys.argv[1:])
        a.report.write_text(report(rows, cmd.strip()) + "\n")
    return 1 if any(r[4].status == "fail" for r in rows) else 0


if __name__ == "__main__":
    sys.exit(main())
