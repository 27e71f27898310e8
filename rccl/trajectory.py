"""The RCCL trajectory generator (thesis 5.2, appendix E.1): one call per RCI sample, joint angles out.

Each motion request becomes a *segment* (planned and timed in rccl.segments) that is
linear in its own space:

- joint mode: q(lam) = q_C + lam (q_B - q_C), a straight line in joint space (E.1);
- Cartesian mode: the tool frame X(lam) = X_C Drive(lam), with X_C the destination's tool
  frame and Drive(lam) = Trans(lam d) Rot(k, lam theta) the drive transform (E.3-E.5)
  taken relative to the destination, so Drive(1) = X_C^-1 X_B (the start) and Drive(0) = I.
  The tool point moves on a straight line and the tool turns about a fixed axis; T6 =
  X Tool^-1 is solved by inverse kinematics every sample in the configuration the arm is in.

``lam`` runs from 1 to 0 over the segment's travel time T. The destination is re-solved
every sample (its position equation may contain variable or functional transforms), so
the arm follows a moving target.

Transitions (Figure 5.2) follow Paul's quartic: with h in [0, 1] across the transition of
half-width tau centred on the corner B,

    alpha(h) = (2 - h) h^3 - 2h + 1        (1 -> 0: what is left of the old segment)
    beta(h)  = 1 - (tau / T2) (2 - h) h^3  (1 -> 1 - tau/T2: the new segment's lam)

and the commanded pose is the new segment at beta with the old segment's remaining
displacement (its lam = alpha tau / T1) added: in joint space when the old segment was
joint mode, as a base-frame rigid motion B Drive1 B^-1 when it was Cartesian. Position,
velocity and acceleration are continuous (alpha'' = beta'' = 0 at both ends); the peak
acceleration is 3 |v2 - v1| / (4 tau), which is how tau and the speeds are chosen to keep
every joint within its acceleration limit. An empty queue makes the generator repeat the
last request with zero displacement: the arm decelerates along the same quartic and holds
(stopping is moving to the same point twice). While the arm holds at rest the generator
looks at the queue every sample, so a request queued then (or let through by the queue's
policy, e.g. an event flag's start code) starts within one sample.

Early exit: ``abort(end)`` (a limit or monitor in ``rccl.adaptive``, ``stop_abort`` in
``rccl.events``) or a request's ``watch`` (called once per sample while the
request runs, e.g. an event flag's stop flag) ends the running motion at once: the
request finishes with ``ended = end`` and the arm leaves its path along the
straight joint-space continuation of its present position and velocity, which the
ordinary quartic transition brings to the next queued request, or to rest.

Planning and control: ``plan_path`` (called by ``move()`` at the planning level) computes a
request's ``Plan`` once: its geometry, the destination's joints and, in Cartesian mode, the
path sampled and checked for reach, joint ranges and singularities. The generator only
times a segment when it starts (``time_segment``), reusing the plan when the request
starts from the corner it was checked from; otherwise (a target that moved, an earlier
request refused) it re-checks the path from the actual corner first. A sample then costs
one T6 from a precomputed basis, one inverse kinematics call and the step check.

Errors: a request that cannot be planned (unreachable, outside a joint range, through a
singularity, needing a configuration change in Cartesian mode) is refused before its
motion starts, the arm holds at the previous destination and the error is reported to the
planning level. A failure in the middle of a path (a moving target that becomes
unreachable, a step larger than the joint velocity limit allows) freezes the arm at the
last command: never a joint jump.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from . import redundancy
from .adaptive.functional import FunctionalUpdater
from .drive import drive
from .ending import MotionEnd
from .exceptions import MotionError, PowerOff, SingularPath, TrajectoryFault, UnreachableTarget
from .limits import Limits
from .motion import MotionParams, Request
from .position import joint_position
from .generator import follow_early_end
from .queue import MotionQueue
from .segments import (ACC_PEAK, CONTROL_CHECK_POINTS, MIN_BLEND_SCALE, STEP_MARGIN, Kinematics, Plan,
                       Segment, Transition, TransitionEvent, check_range, hold_plan, holds_still,
                       is_static, plan_path, plan_segment, resolve_config, time_segment)

__all__ = ["TrajectoryGenerator", "TransitionEvent", "Kinematics", "Plan", "Segment", "Transition", "drive",
           "plan_path", "plan_segment", "resolve_config", "time_segment"]   # the planning names, for older imports


class TrajectoryGenerator:
    """Runs at the control level: ``step()`` once per sample returns the joint angles to command (rad).

    ``queue`` is shared with the planning level. ``errors`` collects refused requests and
    faults for the planning level; ``faulted`` freezes the arm at the last command.

    Work per sample: one inverse kinematics call in Cartesian mode (two in the transition
    from a Cartesian into a joint-mode segment), a few products of small preallocated
    arrays, and the step and range check. A segment start adds the timing of the next
    request (no kinematics when ``move()``'s checked path still applies, see ``plan_segment``).
    """

    def __init__(self, kin: Kinematics, limits: Limits, dt: float, q0: np.ndarray,
                 queue: MotionQueue[Request] | None = None) -> None:
        """Commanded steps are kept within ``limits.joint_velocity * dt``: with the limits of
        :func:`rccl.limits.for_link` (the speeds less what rounding to encoder counts can add),
        the counts sent never trip RCI's R_REQVEL check."""
        self.kin = kin
        if getattr(kin, "redundant", False):
            kin.clock = lambda: self.t     # the free parameter's rules of time (rccl.redundancy)
        self.limits = limits
        self.dt = float(dt)
        self.queue: MotionQueue[Request] = queue if queue is not None else MotionQueue()
        self.t = 0.0
        self.q = np.array(q0, dtype=float)
        self.q_prev = self.q.copy()
        self.errors: list[MotionError] = []
        #: called with no argument just before a transition is planned, and with a
        #: TransitionEvent just after (plots of the transition windows, profiles of the
        #: planning work); a listener must not raise
        self.before_transition: list[Callable[[], None]] = []
        self.on_transition: list[Callable[[TransitionEvent], None]] = []
        self.faulted: TrajectoryFault | None = None
        self.trans: Transition | None = None
        self.samples = 0
        self.ended: list[tuple[Request, MotionEnd]] = []   # requests ended early, with why
        self._abort: MotionEnd | None = None
        # the largest step commanded, and the largest planned step slowed down to it (a Cartesian
        # path's sampled speed estimate, a moving target); a planned step beyond it is a fault
        self._step_ok = limits.joint_velocity * self.dt * (1 + 1e-9)   # (a plan at full speed, rounded)
        self._step_bound = self._step_ok * STEP_MARGIN + 1e-9
        self.q_planned = self.q.copy()   # the last sample as planned, before any slowing
        self.slowed = 0          # samples whose step was slowed to the limit (counted, see _check_step)
        self._lo = limits.lower - 1e-9
        self._hi = limits.upper + 1e-9
        self._step_list, self._lo_list, self._hi_list = self._step_ok.tolist(), self._lo.tolist(), self._hi.tolist()
        # functional transforms (5.4.4): called once per sample, their change limited through the Jacobian (E.8)
        self.functional = FunctionalUpdater(limits.joint_velocity, dt, qdd_max=limits.joint_acceleration)
        self.jac6: np.ndarray | None = None      # frame-6 Jacobian where the arm is, if the caller measured it
        self.jac6_inv: np.ndarray | None = None  # its inverse, if the caller has it
        self.jac6_cond: float | None = None      # cond_1 of jac6, if the caller has it (with jac6_inv)
        self._hold_here(0.0)

    def set_period(self, dt: float, limits: Limits) -> None:
        """Samples ``dt`` s apart from the next step on, within ``limits`` (rccl.generator.MotionGenerator).

        Segments and transitions are timed in seconds, so the running motion keeps its speeds
        and accelerations in real time; only the per-sample step bounds change with the period.
        """
        dt = float(dt)
        if not dt > 0.0:
            raise ValueError(f"set_period: the sample period must be positive, got {dt!r} s")
        self.dt = dt
        self.limits = limits
        self._step_ok = limits.joint_velocity * dt * (1 + 1e-9)
        self._step_bound = self._step_ok * STEP_MARGIN + 1e-9
        self._step_list = self._step_ok.tolist()
        self.functional.set_period(limits.joint_velocity, dt, limits.joint_acceleration)

    @property
    def request(self) -> Request:
        """The request whose segment runs now (a hold's repetition included)."""
        return self.seg.req

    @property
    def tool(self) -> np.ndarray:
        """The tool frame (from link 6, 4x4, m) of the running segment."""
        return self.seg.tool

    def _hold_here(self, t: float) -> None:
        """Make the arm hold at the last commanded joint angles from time ``t`` on."""
        here = joint_position("here", self.kin, self.q)
        start = Request(here, here.snapshot(), MotionParams(mode="joint"), repeat=True, status="running")
        self.seg = plan_segment(self.kin, self.limits, self.dt, start, self.kin.fk(self.q), self.q, t, 0.0)
        self.trans = None

    def restart(self) -> None:
        """Clear a fault (planning level): the arm holds where it was frozen and accepts new requests."""
        self.queue.clear()
        self.q_prev = self.q.copy()
        self._hold_here(self.t)
        self.faulted = None          # last: the control level sees the fault until the hold is set up

    def follow_unpowered(self, q: np.ndarray) -> None:
        """The arm's power is off (control level, each sample): a motion in progress ends with a
        fault (PowerOff), and the commands follow ``q``, the joints the brakes hold (measured),
        so that power coming back starts from where the arm is, not from where it was sent."""
        if self.faulted is None and self.busy:
            self.freeze(PowerOff("the arm's power went off during the motion"))
        if np.array_equal(q, self.q):
            return
        self.q = np.array(q, dtype=float)
        self.q_prev = self.q.copy()
        self.q_planned = self.q.copy()
        if self.faulted is None:
            self._hold_here(self.t)

    # -- the per-sample entry point ---------------------------------------------------
    def step(self) -> np.ndarray:
        """Advance one sample period and return the joint angles to command (rad, (6,))."""
        if self.faulted is not None:
            return self.q
        end = self._abort
        if end is None:
            watch = self.seg.req.watch
            if watch is not None:
                end = watch(self)
        if end is not None:
            self._abort = None
            self._end_now(end)
        t = self.t + self.dt
        try:
            tr = self.trans
            if tr is not None and t >= tr.t_start + 2.0 * tr.tau:
                tr.prev.req.finish()
                if tr.prev.req.finished_t is None:          # when its outgoing transition ended (s)
                    tr.prev.req.finished_t = t
                self.trans = None
            seg = self.seg
            tr = self.trans
            if tr is None:
                if t >= seg.t0 + seg.T - seg.tau_out:
                    self._transition()
                elif holds_still(seg) and len(self.queue):
                    self._start_from_hold()
            elif holds_still(seg) and holds_still(tr.prev) and len(self.queue):
                self._start_from_hold()     # from one hold segment into the next: the same point
            self._update_functional()
            q = self._check_step(self._evaluate(t))
        except (MotionError, ValueError, ArithmeticError) as exc:
            self.freeze(exc)
            return self.q
        self.q_prev, self.q = self.q, q
        self.t = t
        self.samples += 1
        return q

    # -- internals ----------------------------------------------------------------------
    def _update_functional(self) -> None:
        """Call the functional transforms of the segments in play once, their change limited (E.8)."""
        positions = [self.seg.req.position]
        if self.trans is not None:
            positions.append(self.trans.prev.req.position)
        have = self.jac6 is not None
        jac6 = self.jac6 if have else self._jacobian_here
        self.functional.update(positions, jac6, self.seg.req.snap, self.jac6_inv if have else None,
                               self.jac6_cond if have else None)

    def _evaluate(self, t: float) -> np.ndarray:
        seg = self.seg
        tr = self.trans
        if tr is None:
            lam = 1.0 - (t - seg.t0) / seg.T
            return seg.q_at(lam if lam > 0.0 else 0.0, self.q)
        h = (t - tr.t_start) / (2.0 * tr.tau)
        h = 0.0 if h < 0.0 else (1.0 if h > 1.0 else h)
        poly = (2.0 - h) * h * h * h
        alpha = poly - 2.0 * h + 1.0
        lam2 = 1.0 - (tr.tau / seg.T) * poly
        prev = tr.prev
        mu = alpha * tr.tau / prev.T
        if prev.mode == "joint":
            return seg.q_at(lam2, self.q) + mu * prev.dq
        if seg.mode == "joint":
            # Cartesian into joint mode: the old segment's remainder as a joint-space offset, so the
            # new segment may change the configuration (continuous: d mu/dt matches d lam/dt at h = 0)
            q_rest = self.kin.ik(prev.t6_at(mu), prev.config, tr.q_ref, prev.where)
            tr.q_ref = q_rest
            return seg.q_at(lam2, self.q) + (q_rest - tr.q_b)
        t6 = prev.residual(mu) @ seg.t6_at(lam2)
        return self.kin.ik(t6, seg.config, self.q, f"transition {prev.where} -> {seg.where}")

    def _start_from_hold(self) -> None:
        """The arm holds still: start the queue's head request (if the queue admits it) from the last sample on."""
        req = self.queue.get()
        if req is None:
            return
        tr = self.trans
        if tr is not None:            # a transition between two holds of the same point: cut it short
            tr.prev.req.finish()
            self.trans = None
        self._transition(req, now=self.t)

    def _transition(self, req: Request | None = None, now: float | None = None) -> None:
        """Start a transition (``_begin_transition``), with the listeners around it."""
        for listener in self.before_transition:
            listener()
        self._begin_transition(req, now)
        if self.on_transition:
            tr, seg = self.trans, self.seg
            event = TransitionEvent(tr.t_start, tr.t_end, tr.prev.req.position.name, seg.req.position.name,
                                    not (tr.prev.req.repeat and seg.req.repeat))
            for listener in self.on_transition:
                listener(event)

    def _begin_transition(self, req: Request | None = None, now: float | None = None) -> None:
        """Leave the running segment: into the next queued request, or into a hold.

        Called when the segment reaches its outgoing transition; or, with ``req`` already
        taken from the queue and ``now`` the last sample's time (s), in the middle of a hold
        at rest, which the request then leaves from ``now`` on.
        """
        if not self.seg.static:
            # Figure 5.4: leave a segment whose destination moved from where the arm really is, at its velocity
            self.seg = self._continuation(self.seg.req, self._velocity(), self.seg.tau_out, self.seg)
        prev = self.seg
        tau = prev.tau_out
        t_b = prev.t0 + prev.T
        t6_b = prev.dest_t6()
        if prev.mode == "joint" or (prev.static and prev.q_dest is not None and not self.kin.redundant):
            q_b = prev.dest_q()   # a static Cartesian segment's end joints are known from its checked path
        else:
            q_b = self.kin.ik(t6_b, prev.config, self.q, prev.where)
            if self.kin.redundant:    # its rule ends here: q7 holds the value it has (rccl.redundancy)
                redundancy.freeze(prev.config, q_b)
        if now is None:
            req = self.queue.get()
        seg = None
        at_rest = prev.req.repeat and prev.stationary
        if req is not None:
            req.status = "running"
            try:
                if at_rest:  # the arm stands still: start the transition now, as long as the new speed needs
                    seg = plan_segment(self.kin, self.limits, self.dt, req, t6_b, q_b,
                                       t_b - tau if now is None else now, None,
                                       check_points=CONTROL_CHECK_POINTS)
                    tau, t_b = seg.tau_in, seg.t0
                else:
                    seg = plan_segment(self.kin, self.limits, self.dt, req, t6_b, q_b, t_b, tau,
                                       prev.v_end, prev.v_cart if prev.mode == "cartesian" else None,
                                       check_points=CONTROL_CHECK_POINTS)
                    if seg.scale < MIN_BLEND_SCALE:
                        # the turn is too sharp to blend at speed within this transition time and the
                        # acceleration limits: stop at the corner and start the request from rest
                        req.status = "queued"
                        self.queue.push_front(req)
                        seg = None
            except MotionError as exc:
                req.finish(exc)
                self.errors.append(exc)
                for dropped in self.queue.clear():  # later requests assumed this one: refuse them too
                    dropped.finish(MotionError(f"{dropped.position.name}: not run, an earlier request failed"))
        if seg is None:
            hold = prev.req if prev.req.repeat else prev.req.repeated()
            if prev.static and is_static(hold) and not isinstance(hold.profile, Plan):
                hold.profile = hold_plan(prev, hold, t6_b, q_b, self.limits)   # holding still at a fixed corner
            seg = plan_segment(self.kin, self.limits, self.dt, hold, t6_b, q_b, t_b, tau, prev.v_end,
                               prev.v_cart if prev.mode == "cartesian" else None)
        self.trans = Transition(prev, t_b - tau, tau, q_b, self.q.copy())
        self.seg = seg

    def _check_step(self, q: np.ndarray) -> np.ndarray:
        """The joints to command for the planned sample ``q``.

        Normally ``q`` itself. A step over ``limits.joint_velocity * dt`` (the limits already
        leave room for encoder rounding, see rccl.limits.for_link) is slowed to it when the
        planned step (from the last planned sample) is at most STEP_MARGIN over it: a
        Cartesian path's sampled speed estimate, a moving target; the next samples catch up
        (counted in ``slowed``). Refuses a larger planned step, a point outside a joint range,
        or values that are not finite.
        """
        # plain floats: on six numbers this is several times cheaper than numpy's temporaries
        for a, b, lim, lo, hi in zip(q.tolist(), self.q.tolist(), self._step_list, self._lo_list, self._hi_list):
            if not (abs(a - b) <= lim and lo <= a <= hi):
                break    # (NaN fails every comparison, so it is diagnosed below)
        else:
            self.q_planned = q
            return q
        units = self.kin.units
        if not np.all(np.isfinite(q)):
            raise UnreachableTarget(f"{self.seg.where}: the kinematics returned joint values that are not finite ({q}); "
                              "arm stopped")
        step = np.abs(q - self.q_planned)
        bound = self._step_bound
        bad = np.nonzero(~(step <= bound))[0]
        if bad.size:
            i = int(bad[0])
            raise SingularPath(f"{self.seg.where}: joint {i + 1} would move {step[i]:.4f} {units[i]} in one sample "
                               f"(limit {bound[i]:.4f} {units[i]} at {1 / self.dt:.0f} Hz): a singularity or a target "
                               "moving too fast; arm stopped")
        check_range(self.limits, q, self.seg.where, "the commanded point", units)
        self.q_planned = q
        if np.any(np.abs(q - self.q) > self._step_ok):
            q = self.q + np.clip(q - self.q, -self._step_ok, self._step_ok)
            self.slowed += 1
        return q

    # -- early exit (thesis 5.4.1, 5.4.2, 5.6.3) -------------------------------------------
    def abort(self, end: MotionEnd) -> None:
        """End the running motion at the next ``step`` (any thread), recording ``end`` as its ``ended``."""
        self._abort = end

    def _velocity(self) -> np.ndarray:
        """The commanded joint velocity of the last sample (rad/s)."""
        return (self.q - self.q_prev) / self.dt

    def _end_now(self, end: MotionEnd) -> None:
        """Finish the running request with ``end`` and leave its path along the arm's present velocity."""
        seg, tr = self.seg, self.trans
        req = seg.req
        if tr is not None and tr.prev.req.status == "running":
            tr.prev.req.finish()
        self.trans = None
        v = self._velocity()
        tau = max(self.dt, float(np.max(ACC_PEAK * np.abs(v) / self.limits.joint_acceleration)))
        stop = joint_position("stop", self.kin, self.q + v * tau)
        stop_req = Request(stop, stop.snapshot(), MotionParams(mode="joint"), repeat=True, status="running")
        self.seg = self._continuation(stop_req, v, tau, seg)
        if not req.repeat and req.status == "running":
            req.ended = end
            req.finished_t = self.t
            self.ended.append((req, end))
            req.finish(then=lambda: self._ended_early(req, end))

    def _ended_early(self, req: Request, end: MotionEnd) -> None:
        """Called after ``req`` was ended by ``end``: its matching conditional branch runs next (5.6.1)."""
        follow_early_end(self.queue, req, end)

    def _continuation(self, req: Request, v: np.ndarray, tau: float, like: Segment) -> Segment:
        """A joint-mode segment through the present command q at velocity v (rad/s), its corner tau s ahead."""
        s = Segment(req, self.kin)
        T = max(2.0 * tau, self.dt)
        b = self.q + v * tau
        s.mode, s.static, s.stationary = "joint", True, not np.any(v)
        s.T, s.t0, s.tau_in, s.tau_out = T, self.t + tau - T, 0.0, tau
        s.q_dest, s.x_dest, s.dq = b, self.kin.fk(b), -v * T
        s.tool, s.tool_inv, s.config = like.tool, like.tool_inv, self.kin.config_of(self.q)
        s.d, s.k, s.theta = np.zeros(3), np.array([0.0, 0.0, 1.0]), 0.0
        s.v_end, s.v_cart = v, None
        return s

    def freeze(self, exc: BaseException) -> None:
        """Stop on ``exc``: the arm holds where it is, every running and queued request fails
        with a TrajectoryFault naming it (a generator fault, or an adaptive feature's error)."""
        fault = TrajectoryFault(f"trajectory generator stopped the arm at t = {self.t:.3f} s: {exc}", exc)
        self.faulted = fault
        self.errors.append(fault)
        for r in ([self.trans.prev.req] if self.trans else []) + [self.seg.req] + self.queue.clear():
            if r.status in ("queued", "running"):
                r.finish(fault)

    def _jacobian_here(self) -> np.ndarray | None:
        """The frame-6 Jacobian at the last command, or None (no limiting) for kinematics without one."""
        jacobian6 = getattr(self.kin.module, "jacobian6", None)
        return None if jacobian6 is None else jacobian6(self.q)

    # -- read-out -------------------------------------------------------------------------
    @property
    def busy(self) -> bool:
        """True while a non-repeated request is running or queued."""
        return (bool(len(self.queue)) or not self.seg.req.repeat
                or (self.trans is not None and not self.trans.prev.req.repeat))
