"""Jerk-limited online trajectories: a trajectory generator that drives each move with Ruckig.

A drop-in alternative to the thesis's quartic generator (``rccl.trajectory``), chosen per
session: ``rccl.open(url, trajectory="ruckig")``. It serves the same ``MotionQueue`` of the
same ``Request`` records, so ``move``/``stop``/``waitfor``/``setmod`` work unchanged; the
quartic generator stays the default.

Each sample it hands Ruckig's *online* interface a plain input record (current position,
velocity and acceleration; the target; the limits) and takes one sample of the output
record; the result code says whether the move is still running (``Working``), done
(``Finished``) or refused (negative: a ``MotionError`` naming the move). The target is
re-solved every sample, so a moving target re-plans from the arm's present state.

- joint mode: the state is the arm's joint angles (rad, rad/s, rad/s^2); the target is the
  destination's joints (inverse kinematics in the requested configuration); all joints
  start and stop together (Ruckig's time synchronisation);
- Cartesian mode: the state is the tool frame in the base frame as six numbers: the tool
  point (m) and the rotation vector (rad) of the tool orientation relative to its
  orientation when the move started; Ruckig's phase synchronisation keeps that 6-vector on
  a straight line (the tool point moves straight, the tool turns about a fixed axis), and
  T6 = X Tool^-1 is solved by inverse kinematics in the arm's configuration every sample.

Blending (as the quartic's transitions do): when the running move has less than half its
transition time (``settime``) left and the next queued request is of the same mode (and, in
Cartesian mode, the same tool), that request becomes Ruckig's target at once, from the
arm's present velocity and acceleration, within the same limits; the first request is
done at that sample. Other corners (a change of mode or tool, an empty queue) are reached
at rest. Ruckig's phase synchronisation needs a start at rest: a blended Cartesian move
falls back to time synchronisation, so its tool point curves through the blend and then
heads straight for the target only approximately. ``abort(end)`` (or a
request's ``watch``) ends the running move at once: Ruckig's velocity interface
brings the arm to rest with the same jerk and acceleration limits, and the next queued
request then starts from there.

Limits (``JerkLimits.from_limits``): joint velocity and acceleration from the arm's model
(``rccl.limits``); in joint mode each joint's speed is also capped by the request's
rotational velocity (``setvel``), in Cartesian mode the tool's speeds by ``setvel`` and the
Cartesian limits. ``settime``'s travel time is a minimum duration.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from ruckig import ControlInterface, InputParameter, OutputParameter, Result, Ruckig, RuckigError, Synchronization

from . import redundancy
from .adaptive.functional import FunctionalUpdater
from .ending import MotionEnd
from .exceptions import BadRequest, MotionError, PowerOff, SingularPath, TrajectoryFault, UnreachableTarget
from .limits import Limits
from .motion import MotionParams, Request
from .generator import follow_early_end
from .queue import MotionQueue
from .segments import TransitionEvent
from .transform import T6, axis_angle, inverse

# estimate: each joint reaches its acceleration limit in 0.1 s (j = a_max / 0.1 s). The
# model's a_max is v_max / 0.25 s, so a joint reaches top speed in 0.25 s + 0.1 s; 0.1 s is
# about 3.6 samples at 36 Hz (the ramp is still resolved by the samples) and well below
# the 0.2 s quartic transition of rccl.motion, so jerk-limiting costs little time.
JERK_RAMP_S = 0.1
# a commanded step may exceed v_max * dt by this factor before it is a fault (as rccl.trajectory)
STEP_MARGIN = 1.25


@dataclass(frozen=True)
class JerkLimits:
    """Limits Ruckig respects. Joint: rad/s, rad/s^2, rad/s^3 per joint. Tool: m/s.. and rad/s.. (scalars)."""

    joint_velocity: np.ndarray
    joint_acceleration: np.ndarray
    joint_jerk: np.ndarray
    translational: tuple[float, float, float]     # m/s, m/s^2, m/s^3
    rotational: tuple[float, float, float]        # rad/s, rad/s^2, rad/s^3

    def __post_init__(self) -> None:
        for name in ("joint_velocity", "joint_acceleration", "joint_jerk"):
            for i, v in enumerate(getattr(self, name)):
                _check_limit(v, f"joint {i + 1} {name.split('_')[1]} limit")
        for name in ("translational", "rotational"):
            for what, v in zip(("velocity", "acceleration", "jerk"), getattr(self, name)):
                _check_limit(v, f"{name} {what} limit")

    @staticmethod
    def from_limits(limits: Limits, ramp_s: float = JERK_RAMP_S) -> "JerkLimits":
        """Velocity and acceleration from the arm's model, jerk = acceleration / ``ramp_s`` (s)."""
        ramp = _check_limit(ramp_s, "jerk ramp time (s)")
        vel = np.array([_check_limit(v, f"joint {i + 1} velocity limit") for i, v in enumerate(limits.joint_velocity)])
        acc = np.array([_check_limit(a, f"joint {i + 1} acceleration limit")
                        for i, a in enumerate(limits.joint_acceleration)])
        ta = _check_limit(limits.translational_acceleration, "translational acceleration limit")
        ra = _check_limit(limits.rotational_acceleration, "rotational acceleration limit")
        return JerkLimits(vel, acc, acc / ramp,
                          (_check_limit(limits.translational_velocity, "translational velocity limit"), ta, ta / ramp),
                          (_check_limit(limits.rotational_velocity, "rotational velocity limit"), ra, ra / ramp))


def _capped(jerk: JerkLimits, limits: Limits) -> JerkLimits:
    """``jerk`` with each joint's speed within ``limits`` (the speeds less encoder rounding, rccl.limits.for_link)."""
    vel = np.minimum(jerk.joint_velocity, limits.joint_velocity)
    return JerkLimits(vel, jerk.joint_acceleration, jerk.joint_jerk, jerk.translational, jerk.rotational)


def _check_limit(value, what: str) -> float:
    v = float(value)
    if not math.isfinite(v) or v <= 0.0:
        raise BadRequest(f"jerk-limited trajectory: the {what} must be a positive finite number, got {value!r}")
    return v


def _rotvec(r: np.ndarray) -> np.ndarray:
    """Rotation vector (rad, axis * angle) of the 3x3 rotation ``r``."""
    k, theta = axis_angle(r)
    return np.asarray(k, dtype=float) * float(theta)


def _rotation(v: np.ndarray) -> np.ndarray:
    """The 3x3 rotation of rotation vector ``v`` (rad), Rodrigues' formula."""
    theta = math.sqrt(float(v @ v))
    if theta < 1e-12:
        return np.eye(3)
    k = v / theta
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(theta) * kx + (1.0 - math.cos(theta)) * (kx @ kx)


class _Move:
    """The running request in Ruckig's terms: its mode, reference orientation, tool and configuration."""

    __slots__ = ("req", "mode", "tool", "tool_inv", "config", "r_ref", "q_dest", "where", "static", "finished")

    def __init__(self, req: Request, kin, q: np.ndarray) -> None:
        self.req = req
        self.mode = req.mode
        self.where = f"move({req.position.name})"
        self.finished = False     # reached (a moving target is still followed until the next request starts)
        plan = req.profile
        self.static = all(t.kind in ("const", "hold") for t in req.position.transforms())
        self.q_dest = getattr(plan, "q_dest", None) if self.static else None
        self.config = getattr(plan, "config", None) or kin.config_of(q)
        pos = req.position
        self.tool = np.eye(4) if pos.tool is T6 else pos.tool_from_t6(req.snap)   # tool frame seen from link 6
        self.tool_inv = inverse(self.tool)
        self.r_ref = (kin.fk(q) @ self.tool)[:3, :3].copy()


class JerkLimitedGenerator:
    """Runs at the control level: ``step()`` once per sample returns the joint angles to command (rad).

    Implements ``rccl.generator.MotionGenerator``, as the quartic generator does: the
    planning level, the adaptive features and the event flags use either through it.
    ``result`` is Ruckig's result code of the last sample (None while holding).
    """

    def __init__(self, kin, limits: Limits, dt: float, q0: np.ndarray,
                 queue: MotionQueue[Request] | None = None, jerk: JerkLimits | None = None) -> None:
        self.kin = kin
        if getattr(kin, "redundant", False):
            kin.clock = lambda: self.t     # the free parameter's rules of time (rccl.redundancy)
        self.limits = limits
        self._jerk_base = jerk if jerk is not None else JerkLimits.from_limits(limits)
        self.jerk = _capped(self._jerk_base, limits)
        self.dt = float(dt)
        self.queue: MotionQueue[Request] = queue if queue is not None else MotionQueue()
        self.t = 0.0
        self.q = np.array(q0, dtype=float)
        self.q_prev = self.q.copy()
        self.errors: list[MotionError] = []
        self.faulted: TrajectoryFault | None = None
        self.samples = 0
        self.ended: list[tuple[Request, MotionEnd]] = []
        self.result: Result | None = None
        self.move: _Move | None = None
        self._abort: MotionEnd | None = None
        self._braking = False
        # Ruckig's state space: the arm's joints in joint mode (and braking), the tool's 6-vector in
        # Cartesian mode; one record set per size (a single one for a 6-joint arm)
        self._dofs = sorted({6, len(self.q)})
        self._records = {n: (Ruckig(n, self.dt), InputParameter(n), OutputParameter(n)) for n in self._dofs}
        self._otg, self._inp, self._out = self._records[len(self.q)]
        self._step_bound = limits.joint_velocity * self.dt * STEP_MARGIN + 1e-9
        self._step_list = self._step_bound.tolist()
        self._lo_list, self._hi_list = (limits.lower - 1e-9).tolist(), (limits.upper + 1e-9).tolist()
        self.before_transition: list = []       # as TrajectoryGenerator's: around each blend or start
        self.on_transition: list = []
        self.functional = FunctionalUpdater(limits.joint_velocity, dt, qdd_max=limits.joint_acceleration)
        self.jac6: np.ndarray | None = None      # frame-6 Jacobian where the arm is, if the caller measured it
        self.jac6_inv: np.ndarray | None = None
        self.jac6_cond: float | None = None
        self._tool = np.eye(4)
        self.blends = 0                          # requests entered while the arm was still moving
        self.blend = True                        # False: every move starts and ends at rest (for comparison)

    def set_period(self, dt: float, limits: Limits) -> None:
        """Samples ``dt`` s apart from the next step on (rccl.generator.MotionGenerator).

        Ruckig is made anew for the new period; the next step re-plans from the present
        position, velocity and acceleration with the same limits, so the motion keeps its
        speeds in real time.
        """
        dt = float(dt)
        if not dt > 0.0:
            raise ValueError(f"set_period: the sample period must be positive, got {dt!r} s")
        self.dt = dt
        self.limits = limits
        self.jerk = _capped(self._jerk_base, limits)
        if self.move is not None and self.move.mode == "joint":
            self._inp.max_velocity = np.minimum(self._inp.max_velocity, self.jerk.joint_velocity).tolist()
        self._records = {n: (Ruckig(n, dt), inp, out) for n, (_, inp, out) in self._records.items()}
        self._otg = self._records[self._inp.degrees_of_freedom][0]
        self._step_bound = limits.joint_velocity * dt * STEP_MARGIN + 1e-9
        self._step_list = self._step_bound.tolist()
        self.functional.set_period(limits.joint_velocity, dt, limits.joint_acceleration)

    @property
    def request(self) -> Request | None:
        """The request being driven now (None while holding at rest)."""
        return self.move.req if self.move is not None else None

    @property
    def tool(self) -> np.ndarray:
        """The tool frame (from link 6, 4x4, m) of the running move, or of the last one."""
        return self._tool

    # -- planning-level calls -------------------------------------------------------------
    def restart(self) -> None:
        """Clear a fault: the arm holds where it was frozen and accepts new requests."""
        self.queue.clear()
        self.move = None
        self._braking = False
        self.q_prev = self.q.copy()
        self.faulted = None          # last: the control level sees the fault until the hold is set up

    def follow_unpowered(self, q: np.ndarray) -> None:
        """The arm's power is off (control level, each sample): a move in progress ends with a
        fault (PowerOff), and the commands follow ``q``, the joints the brakes hold (measured),
        so that power coming back starts from where the arm is (as TrajectoryGenerator does)."""
        if self.faulted is None and self.busy:
            self.freeze(PowerOff("the arm's power went off during the motion"))
        if not np.array_equal(q, self.q):
            self.q = np.array(q, dtype=float)
            self.q_prev = self.q.copy()

    def abort(self, end: MotionEnd) -> None:
        """End the running move at the next ``step`` (any thread): the arm brakes to rest."""
        self._abort = end

    @property
    def busy(self) -> bool:
        """True while a request is running or queued (or the arm is braking after an abort)."""
        return bool(len(self.queue)) or (self.move is not None and not self.move.finished) or self._braking

    # -- the per-sample entry point ---------------------------------------------------
    def step(self) -> np.ndarray:
        """Advance one sample period and return the joint angles to command (rad, (6,))."""
        if self.faulted is not None:
            return self.q
        t = self.t + self.dt
        try:
            mv = self.move
            end = self._abort
            if end is None and mv is not None:
                watch = mv.req.watch
                if watch is not None:
                    end = watch(self)
            if end is not None:
                self._abort = None
                if mv is not None and not mv.finished:
                    self._end_now(mv, end)
                    mv = None
            if (mv is None or mv.finished) and not self._braking and len(self.queue):
                mv = self._start_next() or mv
            elif mv is not None and not self._braking and len(self.queue) and self._may_blend(mv):
                mv = self._start_next(blend_from=mv) or mv
            if self._braking:
                q = self._brake_sample()
            elif mv is None:
                self.result = None
                q = self.q          # holding still: nothing to compute
            else:
                q = self._sample(mv)
            self._check_step(q)
        except (MotionError, ValueError, ArithmeticError) as exc:
            self.freeze(exc)
            return self.q
        self.q_prev, self.q = self.q, q
        self.t = t
        self.samples += 1
        return q

    # -- internals ----------------------------------------------------------------------
    def _may_blend(self, mv: _Move) -> bool:
        """Whether the head request may take over now: ``mv`` has under half its transition time left,
        and the next request has the same mode (and, in Cartesian mode, the same tool frame)."""
        if not self.blend or mv.finished or self.result != Result.Working:
            return False
        left = self._out.trajectory.duration - self._out.time
        if left > 0.5 * mv.req.params.transition_time:
            return False
        nxt = self.queue.peek()
        if nxt is None or nxt.mode != mv.mode:
            return False
        if mv.mode == "joint":
            return True
        tool = np.eye(4) if nxt.position.tool is T6 else nxt.position.tool_from_t6(nxt.snap)
        return bool(np.allclose(tool, mv.tool, atol=1e-12))

    def _start_next(self, blend_from: _Move | None = None) -> _Move | None:
        """Start the head request: from rest, or (``blend_from``) from the state of the move still running."""
        for listener in self.before_transition:
            listener()
        req = self.queue.get()
        if req is None:
            return None
        req.status = "running"
        try:
            mv = _Move(req, self.kin, self.q)
            redundancy.anchor(mv.config, self.q)     # a 7-joint arm's q7 rule starts where the arm is
            if blend_from is not None and mv.mode == "cartesian":
                mv.r_ref = blend_from.r_ref      # the state's rotation vector stays relative to the same frame
            self._prepare(mv, self.move, carry=blend_from is not None)
        except (MotionError, ValueError) as exc:
            err = exc if isinstance(exc, MotionError) else MotionError(f"move({req.position.name}): {exc}")
            req.finish(err)
            self.errors.append(err)
            for dropped in self.queue.clear():
                dropped.finish(MotionError(f"{dropped.position.name}: not run, an earlier request failed"))
            return None
        if blend_from is not None:
            blend_from.finished = True
            old = blend_from.req
            if old.finished_t is None:
                old.finished_t = self.t
            old.finish()
            self.blends += 1
        prev_name = self.move.req.position.name if self.move is not None else "here"
        self.move = mv
        self._tool = mv.tool
        if self.on_transition:
            event = TransitionEvent(self.t, self.t, prev_name, req.position.name, blend_from is not None)
            for listener in self.on_transition:
                listener(event)
        return mv

    def _prepare(self, mv: _Move, prev: _Move | None, carry: bool = False) -> None:
        """Fill Ruckig's input record for ``mv`` starting at ``self.q``: at rest; or, after a joint-mode
        move still following a moving target or when blending (``carry``), from Ruckig's present
        state (position, velocity, acceleration in the move's state space)."""
        target = self._target(mv)      # first: a refused destination leaves the input record untouched
        n = len(self.q) if mv.mode == "joint" else 6
        self._otg, self._inp, self._out = self._records[n]
        inp, lim, params = self._inp, self.jerk, mv.req.params
        inp.control_interface = ControlInterface.Position
        if not carry and not (prev is not None and prev.mode == "joint" and mv.mode == "joint"):
            inp.current_velocity = [0.0] * n
            inp.current_acceleration = [0.0] * n
        inp.target_velocity = [0.0] * n
        inp.target_acceleration = [0.0] * n
        inp.minimum_duration = params.travel_time
        if mv.mode == "joint":
            inp.synchronization = Synchronization.Time
            cap = _check_limit(params.rotational_velocity, "requested rotational velocity (setvel)")
            inp.max_velocity = np.minimum(lim.joint_velocity, cap).tolist()
            inp.max_acceleration = lim.joint_acceleration.tolist()
            inp.max_jerk = lim.joint_jerk.tolist()
            inp.current_position = self.q.tolist()
        else:
            inp.synchronization = Synchronization.Phase
            vt = min(lim.translational[0], _check_limit(params.translational_velocity, "requested velocity (setvel)"))
            vr = min(lim.rotational[0], _check_limit(params.rotational_velocity, "requested rotational velocity"))
            x = self.kin.fk(self.q) @ mv.tool
            start = x[:3, 3].tolist() + [0.0, 0.0, 0.0]
            # Ruckig's limits are per coordinate, the tool's are on the norm of its translation and of
            # its rotation: each coordinate gets limit / sqrt(3), so the norm stays within the limit in
            # any direction, a moving target's included (up to sqrt(3) slower than needed on an axis)
            c = 1.0 / math.sqrt(3.0)
            inp.max_velocity = [c * vt] * 3 + [c * vr] * 3
            inp.max_acceleration = [c * lim.translational[1]] * 3 + [c * lim.rotational[1]] * 3
            inp.max_jerk = [c * lim.translational[2]] * 3 + [c * lim.rotational[2]] * 3
            if carry:    # Ruckig's own state carries on: no phase-synchronised profile from a moving start
                inp.synchronization = Synchronization.Time
            else:
                inp.current_position = start
        inp.target_position = target

    def _target(self, mv: _Move) -> list[float]:
        """The destination in the move's state space: joints (rad), or tool point (m) + rotation vector (rad)."""
        if mv.mode == "joint":
            if mv.q_dest is None or not mv.static:
                q_ref = self.q if mv.q_dest is None else mv.q_dest
                mv.q_dest = self.kin.ik(mv.req.position.solve(mv.req.snap), mv.config, q_ref, mv.where)
                bad = self.limits.out_of_range(mv.q_dest)
                if bad is not None:
                    raise UnreachableTarget(f"{mv.where}: the destination needs joint {bad + 1} at {mv.q_dest[bad]:.4f}, "
                                      f"outside its range [{self.limits.lower[bad]:.4f}, {self.limits.upper[bad]:.4f}]")
            return mv.q_dest.tolist()
        x = mv.req.position.solve(mv.req.snap) @ mv.tool
        return x[:3, 3].tolist() + _rotvec(mv.r_ref.T @ x[:3, :3]).tolist()

    def _sample(self, mv: _Move) -> np.ndarray:
        inp, out = self._inp, self._out
        if not mv.static:
            # functional transforms (5.4.4): called once per sample, their change limited (E.8)
            have = self.jac6 is not None
            jac6 = self.jac6 if have else self._jacobian_here
            self.functional.update([mv.req.position], jac6, mv.req.snap, self.jac6_inv if have else None,
                                   self.jac6_cond if have else None)
            inp.target_position = self._target(mv)    # a moving target: Ruckig re-plans from the present state
        result = self._update(mv.where)
        out.pass_to_input(inp)
        s = out.new_position
        if mv.mode == "joint":
            q = np.array(s)
        else:
            x = np.eye(4)
            x[:3, :3] = mv.r_ref @ _rotation(np.array(s[3:]))
            x[:3, 3] = s[:3]
            q = self.kin.ik(x @ mv.tool_inv, mv.config, self.q, mv.where)
        if result == Result.Finished and not mv.finished:
            mv.finished = True
            if mv.req.finished_t is None:
                mv.req.finished_t = self.t + self.dt
            mv.req.finish()
        if mv.finished and mv.static:
            self.move = None       # holding still at a fixed point: nothing more to compute
        return q

    def _jacobian_here(self) -> np.ndarray | None:
        """The frame-6 Jacobian at the last command, or None (no limiting) for kinematics without one."""
        jacobian6 = getattr(self.kin.module, "jacobian6", None)
        return None if jacobian6 is None else jacobian6(self.q)

    def _update(self, where: str) -> Result:
        """One Ruckig online step; a refusal (result code or Ruckig's input check) is a MotionError."""
        inp = self._inp
        try:
            result = self._otg.update(inp, self._out)
        except RuckigError as exc:
            raise MotionError(f"{where}: Ruckig refused the input: {str(exc).strip()}") from exc
        self.result = result
        if result not in (Result.Working, Result.Finished):
            raise MotionError(f"{where}: Ruckig refused the motion (result {result.name}) from "
                              f"{list(inp.current_position)} to {list(inp.target_position)}")
        return result

    def _end_now(self, mv: _Move, end: MotionEnd) -> None:
        """Finish ``mv`` with ``end`` and brake the joints to rest (Ruckig's velocity interface)."""
        inp = self._inp
        n = len(self.q)
        if mv.mode == "joint":   # Ruckig's own state: the brake continues the profile's acceleration
            v, a = np.array(inp.current_velocity), list(inp.current_acceleration)
        else:   # Cartesian mode tracks no joint state: the last step's velocity, zero acceleration
            v, a = (self.q - self.q_prev) / self.dt, [0.0] * n
            self._otg, self._inp, self._out = self._records[n]     # (the joints' record set)
            inp = self._inp
        inp.control_interface = ControlInterface.Velocity
        inp.synchronization = Synchronization.No
        inp.minimum_duration = None
        inp.current_position = self.q.tolist()
        inp.current_velocity = np.clip(v, -self.jerk.joint_velocity, self.jerk.joint_velocity).tolist()
        inp.current_acceleration = a
        inp.target_velocity = [0.0] * n
        inp.target_acceleration = [0.0] * n
        inp.max_velocity = self.jerk.joint_velocity.tolist()
        inp.max_acceleration = self.jerk.joint_acceleration.tolist()
        inp.max_jerk = self.jerk.joint_jerk.tolist()
        self._braking = True
        self.move = None
        req = mv.req
        req.ended = end
        req.finished_t = self.t
        self.ended.append((req, end))
        # 5.6.1: a matching conditional branch runs next, chosen before the end wakes the program
        req.finish(then=lambda: follow_early_end(self.queue, req, end))

    def _brake_sample(self) -> np.ndarray:
        inp, out = self._inp, self._out
        result = self._update("braking after an early exit")
        out.pass_to_input(inp)
        if result == Result.Finished:
            self._braking = False
        return np.array(out.new_position)

    def _check_step(self, q: np.ndarray) -> None:
        """Refuse a commanded step above the joint velocity limit, outside a joint range, or not finite."""
        # fast path on plain floats (NaN fails every comparison and falls through to the diagnosis)
        for a, b, bound, lo, hi in zip(q.tolist(), self.q.tolist(), self._step_list, self._lo_list, self._hi_list):
            if not (abs(a - b) <= bound and lo <= a <= hi):
                break
        else:
            return
        if not np.all(np.isfinite(q)):
            raise UnreachableTarget(f"the commanded joint values are not finite ({q}); arm stopped")
        step = np.abs(q - self.q)
        bad = np.nonzero(step > self._step_bound)[0]
        if bad.size:
            i = int(bad[0])
            raise SingularPath(f"joint {i + 1} would move {step[i]:.4f} rad in one sample (limit "
                               f"{self._step_bound[i]:.4f} at {1 / self.dt:.0f} Hz): a singularity or a target "
                               "moving too fast; arm stopped")
        i = self.limits.out_of_range(q)
        if i is not None:
            raise UnreachableTarget(f"the commanded point needs joint {i + 1} at {q[i]:.4f}, outside its range "
                              f"[{self.limits.lower[i]:.4f}, {self.limits.upper[i]:.4f}]; arm stopped")

    def freeze(self, exc: BaseException) -> None:
        """Stop on ``exc``: the arm holds where it is, every running and queued request fails
        with a TrajectoryFault naming it (a generator fault, or an adaptive feature's error)."""
        fault = TrajectoryFault(f"jerk-limited generator stopped the arm at t = {self.t:.3f} s: {exc}", exc)
        self.faulted = fault
        self.errors.append(fault)
        self._braking = False
        running = [self.move.req] if self.move is not None else []
        self.move = None
        for r in running + self.queue.clear():
            if r.status in ("queued", "running"):
                r.finish(fault)
