"""Running a measurement plan as an RCI program: approach, then the path, recorded.

The control function sends a POS command to every joint each cycle (the thesis's way:
position requests to the joint servos, 4.5.1).  The first part of the control takes the
arm from wherever it is to the path's start and is not recorded (an approach may cross
an observation window at a speed that is not constant); the recorder is switched on at
the first cycle of the path itself, so a log holds exactly the experiment.
"""
from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from rcci.calib.exceptions import CalibError
from rcci.calib.experiments import ACCEL, MeasurementPlan
from rcci.calib.paths import Path, PathSegment, approach_path
from rcci.models import load_robot
from rci import codes
from rci.conversions import Conversions
from rci.exceptions import RCIError
from rci.recorder import Recorder
from rci.session import Session


@dataclass
class RunInfo:
    """What a run did: records logged, cycles in all, the log's path."""

    path: str
    records: int
    cycles: int


def drive(session: Session, f1, done: threading.Event) -> None:
    """Run control function ``f1`` on an open-able ``session`` until ``done`` is set, then stop
    recording and release. The session is closed on the way out; RCI errors propagate."""
    with session:
        session.control(f1)
        session.wait(until=done.is_set)
        session.record(None)
        session.release()


def open_measurement(url: str, robot: str, rate_hz: int, log_path: str, meta: dict,
                     timeout: float | None, realtime: bool = False,
                     user_fields: dict | None = None) -> tuple[Recorder, Session]:
    """The recorder (writing in the background) and the RCI session every measurement
    program runs on: errors raised, overruns counted (a lockstep simula on a busy machine
    is slow, not late), ``timeout`` s without a HOW before R_TIMEOUT."""
    rec = Recorder(log_path, robot=robot, nj=load_robot(robot).n_joints, rate_hz=rate_hz, meta=meta,
                   block_records=1024, user_fields=user_fields)
    rec.start_writer(0.5)
    session = Session(url, robot, rate_hz=rate_hz, realtime=realtime, lock_memory=False,
                      on_error="raise", gc="leave", overrun="count", timeout=timeout)
    return rec, session


def drive_recorded(session: Session, f1, done: threading.Event, rec: Recorder, name: str, url: str,
                   where) -> None:
    """``drive`` the measurement program ``name``, then close its recorder; an RCI error
    becomes a CalibError naming the program, the robot, ``where()`` it stopped and the
    partial log (kept, closed cleanly)."""
    try:
        drive(session, f1, done)
    except RCIError as exc:
        raise CalibError(f"measurement program {name} on {url} stopped {where()}: {exc} "
                         f"(partial log: {rec.path})") from None
    finally:
        rec.close()


#: a plan's moves keep every joint under this share of its velocity limit (the friction sweeps'
#: 90 % pass unchanged; a prismatic joint's sweep planned in degrees per second does not)
SPEED_SHARE_MAX = 0.95


def approach_speed(robot: str) -> float:
    """Speed (rad/s or m/s, of the joint that moves most) of the moves to a plan's start: 0.6, or
    80 % of the slowest joint's limit where that is less (the Stanford arm's 0.5 m/s slide)."""
    from rcci.models import load_robot

    return float(min(0.6, 0.8 * min(load_robot(robot).max_velocity)))


def command_joints(session: Session, conv: Conversions, q: np.ndarray) -> None:
    """POS commands for every joint: the angles ``q`` (rad) in whole encoder counts."""
    conv.command_positions(session.chg, q)


def run_plan(url: str, plan: MeasurementPlan, log_path: str, robot: str = "puma260", rate_hz: int = 36,
             realtime: bool = False, extra_meta: dict | None = None,
             timeout: float | None = 5.0, on_cycle: Callable[[int, int], None] | None = None) -> RunInfo:
    """Run ``plan`` on the robot (or simula) at ``url`` and record it into ``log_path``.

    ``timeout`` (s without a HOW before R_TIMEOUT) is generous by default because a
    lockstep simula on a busy machine may take much longer than a period per cycle;
    pass None for the session's default of two periods when driving a real arm.
    ``on_cycle(k, n)``, if given, is called once per second of the program (every ``rate_hz``
    cycles, in the control loop: it must be quick) with the cycles done of all ``n`` (approach,
    warm-up and path): rcci.calib.progress.Steps.within shows it.
    """
    from rcci.models import load_robot

    conv = Conversions.for_robot(robot)
    speed = approach_speed(robot)
    vmax = load_robot(robot).max_velocity            # no joint past 95 % of its limit (a slide's, m/s)
    body = plan.path.within(vmax, SPEED_SHARE_MAX).sample(rate_hz)
    meta = dict(plan.meta)
    meta.update(extra_meta or {})
    meta.update({"program": f"calib record {plan.name}", "log_name": plan.name, "rate_hz": rate_hz})
    # everything but the approach (which starts where the arm is) is sampled before the control
    # starts: at 1 kHz a friction log is 10^5 setpoints, and building them in the first cycle took
    # over 2 s at a load of 20 (R_OVERRUN: rci ends a control function hung that long)
    parts = [] if plan.warmup is None else [plan.warmup.within(vmax, SPEED_SHARE_MAX).sample(rate_hz)]
    first = parts[0][0] if parts else body[0]
    last = parts[0][-1] if parts else first
    settle = Path((PathSegment(last, body[0], speed, ACCEL, 0.5),)).sample(rate_hz)
    tail = np.vstack([*parts, settle, body])
    state = {"k": -1, "approach": None, "recording_from": 0}
    done = threading.Event()
    rec, session = open_measurement(url, robot, rate_hz, log_path, meta, timeout, realtime)

    def f1() -> None:
        how, chg = session.how, session.chg
        if state["approach"] is None:
            here = conv.counts_to_angles(np.asarray(how.pos[:conv.n], dtype=float))
            state["approach"] = approach_path(here, plan.via, first, ACCEL, speed).sample(rate_hz)
            state["recording_from"] = len(state["approach"]) + len(tail) - len(body)
            if not how.state & codes.POWER_ON:
                chg.power_on.issue()
        k = state["k"] = state["k"] + 1
        approach = state["approach"]
        n = len(approach) + len(tail)
        if k == state["recording_from"]:
            session.record(rec)
        if on_cycle is not None and k % rate_hz == 0:
            on_cycle(min(k, n), n)
        if k >= n:
            done.set()
            k = n - 1
        command_joints(session, conv, approach[k] if k < len(approach) else tail[k - len(approach)])

    drive_recorded(session, f1, done, rec, plan.name, url, lambda: f"after {max(state['k'], 0)} cycles")
    return RunInfo(log_path, rec.written, state["k"] + 1)


def record_plans(request, plans: list[MeasurementPlan]) -> None:
    """``calib record``: run each of ``plans`` on the robot of ``request`` (a
    rcci.calib.registry.RecordRequest), one log per plan in its folder, and say so."""
    import os

    for plan in plans:
        path = os.path.join(request.out, plan.name + ".rcilog")
        run = run_plan(request.url, plan, path, request.robot, request.args.rate or plan.rate_hz,
                       extra_meta=request.extra_meta)
        print(f"{plan.name}: {run.records} records -> {path}")
