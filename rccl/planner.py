"""The RCCL planning level: move, setvel, settime, setmod, setconf, stop, waitfor (thesis 5.3.2-5.3.4).

``Planner`` is what a user program talks to. It keeps the current motion parameters,
turns each ``move`` into a request packet, checks it *before* queueing (from where the
previous request will leave the arm: unreachable targets, joint ranges, singular
Cartesian paths, configuration changes in Cartesian mode all raise here, at the planning
level, before any motion starts; with ``collisions(...)`` on, so do paths that bring two
links, or a link and an environment object, inside the clearance margin: rccl.collision),
and queues it for the trajectory generator. The
generator re-plans each request from the arm's actual state when it reaches it.

Errors the trajectory level meets later (a variable target that moved out of reach, a
fault) are raised by the next primitive or by the ``waitfor`` that is blocked.
"""
from __future__ import annotations

import itertools
from dataclasses import replace
from typing import Callable

import numpy as np

from .exceptions import BadRequest, ConfigurationChange, TrajectoryFault
from .limits import Limits
from .motion import MotionParams, Request
from . import redundancy
from .position import EQ, TL, Position, makeposition
from .transform import T6, Trsf
from .queue import MotionQueue
from .sync import Event
from .segments import Kinematics, plan_path, resolve_config
from .trajectory import TrajectoryGenerator

_CONF_LETTERS = {"l": ("arm", -1), "r": ("arm", 1), "u": ("elbow", 1), "d": ("elbow", -1),
                 "f": ("wrist", -1), "n": ("wrist", 1)}
_CONF_WORDS = {"left": ("arm", -1), "right": ("arm", 1), "up": ("elbow", 1), "down": ("elbow", -1),
               "flip": ("wrist", -1), "noflip": ("wrist", 1)}


def parse_config(spec) -> dict | object | None:
    """A configuration request: None, a Config, or RCCL-style letters/words.

    Letters: l/r (arm left/right), u/d (elbow up/down), n/f (wrist noflip/flip), e.g.
    ``"ru"`` or ``"right up flip"``. Fields not named keep the arm's current value.
    """
    if spec is None or not isinstance(spec, str):
        return spec
    out: dict[str, int] = {}
    words = spec.replace(",", " ").split()
    tokens = words if any(w.lower() in _CONF_WORDS for w in words) else list(spec.replace(" ", ""))
    for tok in tokens:
        key = _CONF_WORDS.get(tok.lower()) or _CONF_LETTERS.get(tok.lower())
        if key is None:
            raise BadRequest(f"setconf: {tok!r} in {spec!r} is not one of l/r, u/d, n/f "
                             "(left/right, up/down, noflip/flip)")
        if key[0] in out and out[key[0]] != key[1]:
            raise BadRequest(f"setconf: {spec!r} asks for both values of {key[0]}")
        out[key[0]] = key[1]
    return out


class Planner:
    """The planning-level RCCL primitives bound to one trajectory generator.

    ``fault_check`` (optional) is called by every primitive and while ``waitfor`` blocks;
    the RCI session uses it to deliver control-level terminations.
    """

    def __init__(self, kin: Kinematics, limits: Limits, generator: TrajectoryGenerator,
                 fault_check: Callable[[], None] | None = None) -> None:
        self.kin = kin
        self.limits = limits
        self.gen = generator
        self.queue: MotionQueue[Request] = generator.queue
        self.params = MotionParams()
        self._serial = itertools.count(1)
        self._fault_check = fault_check
        self._reported = 0
        self._pred_t6: np.ndarray | None = None
        self._pred_q: np.ndarray | None = None
        self.last: Request | None = None
        # collision checking (rccl.collision.CollisionGuard), off until ``arm.collisions(...)``
        self.collision_guard = None

    # -- errors from the trajectory level ---------------------------------------------
    def check(self) -> None:
        """Raise the first trajectory-level error not yet reported (and any RCI termination)."""
        if self._fault_check is not None:
            self._fault_check()
        errors = self.gen.errors
        if self._reported < len(errors):
            err = errors[self._reported]
            self._reported += 1
            self._pred_t6 = self._pred_q = None   # the arm did not go where we predicted
            if isinstance(err, TrajectoryFault):
                raise err
            raise TrajectoryFault(f"a queued request was refused by the trajectory generator: {err}", err)
        if self.gen.faulted is not None:
            raise TrajectoryFault(f"the arm is stopped after a fault ({self.gen.faulted}); call recover() to "
                                  "hold it where it is and go on", self.gen.faulted)

    def recover(self) -> None:
        """After a TrajectoryFault: drop queued requests and hold the arm where it stopped; moves work again."""
        self._reported = len(self.gen.errors)
        self.gen.restart()
        self._pred_t6 = self._pred_q = None

    # -- parameters (5.3.2) ------------------------------------------------------------
    def setvel(self, translational: float, rotational: float) -> None:
        """Speeds for the next moves: translational m/s, rotational rad/s (cancels settime's travel time)."""
        self.params.setvel(translational, rotational)

    def settime(self, transition: float, travel: float) -> None:
        """Transition time (s, whole transition) and travel time (s) for the next moves."""
        self.params.settime(transition, travel)

    def setmod(self, mode: str) -> None:
        """Trajectory mode of the next moves: 'joint' ('j') or 'cartesian' ('c')."""
        self.params.setmod(mode)

    def setconf(self, spec=None) -> None:
        """Arm configuration for the next joint-mode moves (e.g. "ru", "flip", a Config); None keeps the current."""
        wanted = parse_config(spec)
        if wanted is not None and not isinstance(wanted, (dict, self.kin.Config)):
            raise BadRequest(f"setconf({spec!r}): not a configuration of the {self.kin.name}: give letters "
                             f"(e.g. 'ru', 'right up flip': l/r, u/d, n/f), a {self.kin.Config.__name__}, or None")
        fields = getattr(self.kin.Config, "_fields", None) or getattr(self.kin.Config, "__dataclass_fields__", None)
        if isinstance(wanted, dict) and fields is not None:
            unknown = sorted(set(wanted) - set(fields))
            if unknown:
                raise BadRequest(f"setconf({spec!r}): the {self.kin.name} has no {'/'.join(unknown)} configuration "
                                 f"choice (its configuration has {', '.join(fields)})")
        self.params.config = wanted

    def setfree(self, spec=None, *, q7=None, step: float = redundancy.FAR_STEP) -> None:
        """A redundant arm's rule for its free parameter q7 in the next moves (rccl.redundancy):
        ``q7=value`` (rad, held), ``q7=f`` (f(t) rad, t s from each motion's start), ``"far"``
        (each sample within ``step`` rad of the last, far from joint limits and singularities),
        ``"hold"`` or None (keep the q7 the arm has: the default). A 6-joint arm refuses it."""
        if not getattr(self.kin, "redundant", False):
            raise BadRequest(f"setfree: the {self.kin.name} has {getattr(self.kin, 'dof', 6)} joints and no free "
                             "parameter: its pose and configuration (setconf) fix its joints")
        self.params.free = redundancy.rule_of(spec, q7=q7, lower=self.limits.lower, upper=self.limits.upper,
                                              step=step)

    def selfmove(self, q7: float, duration: float) -> Request:
        """Self-motion of a redundant arm: q7 to ``q7`` (rad) in ``duration`` s along a minimum-jerk
        ramp, the other joints through the inverse kinematics, the tool's pose fixed (from where
        the previous request leaves the arm). Raises before anything moves when the arm would
        leave a joint range or pass a singularity on the way (naming q7 and how far along)."""
        self.check()
        if not getattr(self.kin, "redundant", False):
            raise BadRequest(f"selfmove: the {self.kin.name} has {getattr(self.kin, 'dof', 6)} joints and no "
                             "self-motion: its pose fixes its joints")
        target, duration = redundancy.check_target(q7, duration, self.limits)
        if self._pred_q is None or not self.gen.busy:     # (at rest: from where the arm is)
            q = self.gen.q.copy()
            self._pred_q, self._pred_t6 = q, self.kin.fk(q)
        t6, q_start = self._pred_t6.copy(), self._pred_q
        rule = redundancy.SelfMotion(target=target, duration=duration)
        where = f"selfmove(q7={target:.4f})"
        redundancy.check_selfmotion(self.kin, self.limits, t6, q_start, rule, where)
        here = makeposition("selfmove", T6, EQ, Trsf("SELFMOVE", t6), TL, T6)
        saved = replace(self.params)
        try:
            self.params.mode = "cartesian"
            # the motion outlasts the ramp by SELF_PAD samples: whichever generator runs, q7 has
            # reached the target at rest when it ends the motion (the quartic ends it at its
            # outgoing transition, Ruckig a few samples before a zero move's minimum duration)
            self.params.travel_time = duration + redundancy.SELF_PAD * self.gen.dt
            self.params.config = None
            self.params.free = rule
            return self.move(here)
        finally:
            self.params = saved

    # -- motion requests ---------------------------------------------------------------
    def move(self, position: Position) -> Request:
        """Queue a motion to ``position`` with the current parameters; return the request.

        Raises (before anything moves) if the move cannot be made from where the previous
        request leaves the arm.
        """
        self.check()
        if not isinstance(position, Position):
            raise BadRequest(f"move: {position!r} is not a position (use makeposition)")
        req = Request(position, position.snapshot(), replace(self.params), next(self._serial))
        self._precheck(req)
        if self.collision_guard is not None:          # the per-cycle watch, for the motions that get one
            watch = self.collision_guard.watch_for(req)
            if watch is not None:
                req.checks.append(watch)
        position.end.expect()
        self.queue.put(req)
        self.last = req
        return req

    def stop(self, time: float, transition: float | None = None) -> Request:
        """Stay at the last position for about ``time`` s: a second move to it with that travel time (5.3.4)."""
        self.check()
        if self.last is None:
            raise BadRequest("stop: no previous move to stop at")
        saved = replace(self.params)
        try:
            self.params.settime(transition if transition is not None else saved.transition_time, time)
            self.params.config = None
            self.params.free = None      # a redundant arm holds its q7 while it stops
            return self.move(self.last.position)
        finally:
            self.params = saved

    def waitfor(self, event: Event | Request, timeout: float | None = None) -> None:
        """Block until ``event`` (a position's ``end``) drops below one, or a request completes (5.3.3).

        ``timeout`` (s, default none) raises TimeoutError naming the event if it has not come by
        then (the motion goes on). Raises BadRequest at once for a position's ``end`` that no
        queued or running motion will signal (it would block forever).
        """
        self.check()
        if timeout is not None and not (isinstance(timeout, (int, float)) and timeout >= 0):
            raise BadRequest(f"waitfor: timeout={timeout!r} must be a number of seconds >= 0 (or None: no limit)")
        if isinstance(event, Request):
            while not event.wait(0.02):
                self.check()
                if timeout is not None:
                    timeout -= 0.02
                    if timeout <= 0:
                        raise TimeoutError(f"waitfor: request to {event.position.name} not done")
            self.check()
            return
        if not isinstance(event, Event):
            raise BadRequest(f"waitfor: {event!r} is not an event (e.g. position.end) or a request")
        if not event.will_signal():
            raise BadRequest(f"waitfor({event.name}): no motion to it is queued or running, so it would never "
                             "come; move() to the position first")
        event.wait(fault=self.check, timeout=timeout)
        self.check()

    # -- planning-level check -------------------------------------------------------------
    def _precheck(self, req: Request) -> None:
        if getattr(self.kin, "redundant", False) and not self.gen.busy:
            # a redundant arm's rules (far, time) end q7 where the samples took it, not where the
            # path check predicted: at rest, plan from where the arm is
            self._pred_q = None
        if self._pred_q is None:
            q = self.gen.q.copy()
            self._pred_q, self._pred_t6 = q, self.kin.fk(q)
        if req.params.mode == "cartesian" and req.params.config is not None:
            cfg_b = self.kin.config_of(self._pred_q)
            if resolve_config(self.kin, cfg_b, req.params.config) != cfg_b:
                raise ConfigurationChange(
                    f"move({req.position.name}): Cartesian mode cannot change the arm configuration; "
                    "use setmod('joint') with setconf()")
        # the path check (reach, joint ranges, singularities along a Cartesian line), done once here;
        # the generator reuses it when the request starts from this corner (see plan_segment)
        plan = plan_path(self.kin, self.limits, self.gen.dt, req, self._pred_t6, self._pred_q)
        if self.collision_guard is not None:          # self-collision and environment along the path
            self.collision_guard.check_plan(req, plan, self.kin, self.limits)
        req.profile = plan
        self._pred_t6 = plan.t6_c
        self._pred_q = plan.q_dest

    @property
    def running(self) -> bool:
        return self.gen.faulted is None

