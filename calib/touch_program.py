"""The kinematic calibration's measurement program: touch the fixture's faces with the probe.

An RCI control function (POS commands every cycle, like the other measurement
programs) that makes each touch of a ``TouchPlan`` as a coordinate-measuring machine
probes a surface: a straight move to a stand-off point in front of the face, a fast
approach along the face's normal until the probe's switch closes, a short back-off, and
the measuring approach at ``SLOW`` (recorded), stopped on the cycle the switch is seen
closed; then back to the stand-off. Moves are planned with the nominal kinematics (the
arm's true geometry is what is being measured); the joints are commanded in encoder
counts, so the arm is exactly at the commanded counts at every cycle and the contact
lies between the last open and the first closed reading.

The log holds only the measuring approaches, each record tagged with its touch's index
(user field ``touch``); the fit (rcci.calib.kinematics) reads the probe bit from ``inport1``.
"""
from __future__ import annotations

import threading
from collections.abc import Callable

import numpy as np

from rcci.calib.exceptions import CalibError
from rcci.calib.program import command_joints, drive_recorded, open_measurement
from rcci.calib.touch import (BACKOFF, FAST, OVERTRAVEL, SLOW, STANDOFF, TouchPlan, cartesian_line,
                         hub_pose, joint_route, joint_line, pose_t6, tool_transform)
from rci import codes
from rci.conversions import Conversions

# one step of the program: a builder of setpoints from the joint angles it starts at,
# whether it stops on the probe, and the touch index it records under (None: not recorded)
Step = tuple[Callable[[np.ndarray], np.ndarray], bool, int | None, str]


def _steps(plan: TouchPlan, kin) -> list[Step]:
    """The program's steps, each built when it starts (it depends on where the last stopped)."""
    rate, tip, fx = plan.rate_hz, plan.tip, plan.fixture
    tool = tool_transform(tip)
    steps: list[Step] = []

    def line_to(point: np.ndarray, rotation: np.ndarray, config, speed: float | None = None):
        def build(q: np.ndarray) -> np.ndarray:
            B = pose_t6(point, rotation, tip)
            kw = {} if speed is None else {"linear": speed}
            return cartesian_line(kin, kin.fk(q), B, config, q, rate, tip, **kw)
        return build

    def along(direction: np.ndarray, distance: float, config, speed: float):
        def build(q: np.ndarray) -> np.ndarray:
            A = kin.fk(q)
            P = A @ tool
            return cartesian_line(kin, A, pose_t6(P[:3, 3] + distance * direction, P[:3, :3], tip),
                                  config, q, rate, tip, linear=speed, steady=True)
        return build

    def to_hub(t, where):
        def build(q: np.ndarray) -> np.ndarray:
            route = joint_route(kin, q, hub_pose(kin, t, fx, tip), fx, tip, f"the way to {where}")
            return np.vstack([joint_line(a, b, rate, robot=kin.ROBOT) for a, b in zip(route, route[1:])])
        return build

    prev = None
    for k, t in enumerate(plan.touches):
        config = kin.Config(*t.config)
        d = t.approach(fx)
        standoff = t.point - STANDOFF * d
        where = f"touch {k + 1} ({fx.faces[t.face].name})"
        if t.via_hub:
            if prev is not None:
                steps.append((line_to(fx.faces[prev.face].hub, prev.rotation, kin.Config(*prev.config)),
                              False, None, where))
            steps.append((to_hub(t, where), False, None, where))
            steps.append((line_to(standoff, t.rotation, config), False, None, where))
        else:
            steps.append((line_to(standoff, t.rotation, config), False, None, where))
        reach = STANDOFF + OVERTRAVEL
        steps.append((along(d, reach, config, FAST), True, None, where))
        steps.append((along(-d, BACKOFF, config, FAST), False, None, where))
        steps.append((along(d, BACKOFF + OVERTRAVEL, config, SLOW), True, k, where))
        steps.append((line_to(standoff, t.rotation, config), False, None, where))
        prev = t
    if prev is not None:
        steps.append((line_to(fx.faces[prev.face].hub, prev.rotation, kin.Config(*prev.config)),
                      False, None, "the end"))
    return steps


def run_touches(url: str, plan: TouchPlan, log_path: str, robot: str = "puma260",
                extra_meta: dict | None = None, timeout: float | None = 5.0,
                start_q: np.ndarray | None = None) -> int:
    """Run ``plan`` on the robot (or simula) at ``url``; returns the records logged.

    The arm first moves in joint space from where it is to the hub with the first
    touch's orientation (``start_q`` is unused; the arm's reading is the start).
    """
    from rccl.kinematics import load

    kin = load(robot)
    conv = Conversions.for_robot(robot)
    rate = plan.rate_hz
    meta = dict(plan.meta)
    meta.update(extra_meta or {})
    meta.update({"program": f"calib record {plan.name}", "log_name": plan.name, "rate_hz": rate,
                 "touch_points": [list(map(float, t.point)) for t in plan.touches],
                 "touch_faces": [t.face for t in plan.touches]})
    steps = _steps(plan, kin)
    bit = 1 << plan.bit

    def to_first_hub(q: np.ndarray) -> np.ndarray:
        route = joint_route(kin, q, hub_pose(kin, plan.touches[0], plan.fixture, plan.tip),
                            plan.fixture, plan.tip, "the move from the arm's pose to the first touch")
        return np.vstack([joint_line(a, b, rate, robot=kin.ROBOT) for a, b in zip(route, route[1:])])
    state = {"step": -1, "k": 0, "sp": None, "q": None, "error": None, "power": False, "rec_off": False}
    done = threading.Event()
    rec, session = open_measurement(url, robot, rate, log_path, meta, timeout,
                                    user_fields={"touch": ("<i2", ())})

    def pos_all(q: np.ndarray) -> None:
        command_joints(session, conv, q)

    def begin(q: np.ndarray) -> None:
        state["step"] += 1
        state["k"] = 0
        if state["step"] >= len(steps):
            state["rec_off"] = True
            done.set()
            state["sp"] = q[None, :]
            return
        build, _, touch, where = steps[state["step"]]
        try:
            state["sp"] = build(q)
        except (ValueError, CalibError) as exc:   # no joint solution, or no clear route
            state["error"] = exc if isinstance(exc, CalibError) else CalibError(
                f"{plan.name}: {where}: no nominal joint solution on the way: {exc}")
            state["step"] = len(steps)
            done.set()
            state["sp"] = q[None, :]
            return
        if touch is not None:
            rec.user["touch"] = touch
            session.record(rec)
        elif session.recorder is not None:
            state["rec_off"] = True      # after this cycle: the closing reading is recorded too

    def f1() -> None:
        how = session.how
        if state["rec_off"]:
            session.record(None)
            state["rec_off"] = False
        if not state["power"]:
            if not how.state & codes.POWER_ON:
                session.chg.power_on.issue()
            state["power"] = True
            here = conv.counts_to_angles(np.asarray(how.pos[:conv.n], dtype=float))
            steps.insert(0, (to_first_hub, False, None, "the start"))
            state["q"] = here
            begin(here)
        if done.is_set():
            pos_all(state["sp"][-1])
            return
        sp, k = state["sp"], state["k"]
        _, guarded, touch, where = steps[state["step"]]
        if guarded and how.inport1 & bit:
            # the switch is closed: hold here (the arm stands on the counts it reached)
            q = conv.counts_to_angles(np.asarray(how.pos[:conv.n], dtype=float))
            begin(q)
            sp, k = state["sp"], 0
        elif k >= len(sp):
            if guarded:
                state["error"] = CalibError(
                    f"{plan.name}: {where}: the probe did not touch within {1e3 * OVERTRAVEL:.0f} mm "
                    f"past the nominal face (is the fixture where the plan says, and the probe on inport1 "
                    f"bit {plan.bit}?)")
                state["step"] = len(steps)
                done.set()
                state["sp"] = sp[-1:]
                pos_all(sp[-1])
                return
            begin(sp[-1])
            sp, k = state["sp"], 0
        pos_all(sp[min(k, len(sp) - 1)])
        state["k"] = k + 1

    drive_recorded(session, f1, done, rec, plan.name, url, lambda: f"at step {state['step']}")
    if state["error"] is not None:
        raise state["error"]
    return rec.written
