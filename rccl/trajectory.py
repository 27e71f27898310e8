"""The RCCL trajectory generator (thesis 5.2, appendix E.1): one call per RCI sample, joint angles out.

Each motion request becomes a *segment* that is linear in its own space:

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
(stopping is moving to the same point twice).

Errors: a request that cannot be planned (unreachable, outside a joint range, through a
singularity, needing a configuration change in Cartesian mode) is refused before its
motion starts, the arm holds at the previous destination and the error is reported to the
planning level. A failure in the middle of a path (a moving target that becomes
unreachable, a step larger than the joint velocity limit allows) freezes the arm at the
last command: never a joint jump.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from .exceptions import ConfigurationChange, MotionError, SingularPath, TrajectoryFault, Unreachable
from .limits import Limits
from .motion import MotionParams, Request
from .position import joint_position
from .queue import MotionQueue
from .transform import axis_angle, inverse

ACC_PEAK = 0.75          # peak of the quartic's acceleration: ACC_PEAK * |v2 - v1| / tau
STEP_MARGIN = 1.25       # a commanded step may exceed v_max * dt by this factor before it is a fault
SINGULAR_SLOWDOWN = 10.0  # a Cartesian path needing > 10x its requested time for joint speed is singular
MIN_BLEND_SCALE = 0.5    # below this speed factor a corner is taken by stopping at it instead (see plan_segment)
MAX_CHECK_POINTS = 200   # samples of a Cartesian path checked by move() before its motion starts
CONTROL_CHECK_POINTS = 12  # the control level's re-check when the planning level's no longer applies


# --------------------------------------------------------------------------------------
# kinematics wrapper: the generated module's errors become RCCL errors naming the position
# --------------------------------------------------------------------------------------
class Kinematics:
    """The contract's kinematics module with RCCL error wrapping and configuration helpers."""

    def __init__(self, module) -> None:
        self.module = module
        self.fk = module.fk
        self._ik = module.ik
        self.config_of = module.config_of
        self.Config = getattr(module, "Config", None)
        self.name = getattr(module, "ROBOT", getattr(module, "__name__", "robot"))

    def ik(self, base_to_t6: np.ndarray, config, q_ref: np.ndarray, where: str) -> np.ndarray:
        try:
            q = self._ik(base_to_t6, config, q_ref=q_ref)
        except ValueError as exc:  # KinematicsError subclasses ValueError
            cls = SingularPath if "singular" in type(exc).__name__.lower() else Unreachable
            p = base_to_t6[:3, 3]
            raise cls(f"{where}: no joint solution in configuration {config} for T6 at "
                      f"({p[0]:.4f}, {p[1]:.4f}, {p[2]:.4f}) m: {exc}") from exc
        q = np.asarray(q, dtype=float)
        if not np.all(np.isfinite(q)):
            raise Unreachable(f"{where}: inverse kinematics returned {q}")
        return q


def drive(d: np.ndarray, k: np.ndarray, theta: float, lam: float) -> np.ndarray:
    """Drive transform Trans(lam d) Rot(k, lam theta) (E.3-E.5), 4x4."""
    kx, ky, kz = k
    a = lam * theta
    c, s = math.cos(a), math.sin(a)
    v = 1.0 - c
    return np.array([
        [kx * kx * v + c, kx * ky * v - kz * s, kx * kz * v + ky * s, lam * d[0]],
        [kx * ky * v + kz * s, ky * ky * v + c, ky * kz * v - kx * s, lam * d[1]],
        [kx * kz * v - ky * s, ky * kz * v + kx * s, kz * kz * v + c, lam * d[2]],
        [0.0, 0.0, 0.0, 1.0],
    ])


def resolve_config(kin: Kinematics, current, wanted):
    """The configuration to use: ``wanted`` (a Config, or a dict of fields to change) applied to ``current``."""
    if wanted is None:
        return current
    if isinstance(wanted, dict):
        if hasattr(current, "_replace"):
            return current._replace(**wanted)
        return replace(current, **wanted)
    return wanted


# --------------------------------------------------------------------------------------
# segments
# --------------------------------------------------------------------------------------
class Segment:
    """One planned motion: linear in joint space or along a drive transform, lam from 1 to 0 over T seconds."""

    __slots__ = ("req", "mode", "t0", "T", "tau_in", "tau_out", "stationary", "scale", "tool", "tool_inv", "config", "d", "k", "theta",
                 "dq", "q_dest", "static", "x_dest", "v_end", "v_cart", "kin", "where")

    def __init__(self, req: Request, kin: Kinematics) -> None:
        self.req = req
        self.kin = kin
        self.mode = req.mode
        self.where = f"move({req.position.name})"
        self.static = all(t.kind in ("const", "hold") for t in req.position.transforms())
        self.x_dest = None

    # the destination, re-solved at every sample unless every component is const/hold
    def dest_t6(self) -> np.ndarray:
        if self.static and self.x_dest is not None:
            return self.x_dest
        t6 = self.req.position.solve(self.req.snap)
        if self.static:
            self.x_dest = t6
        return t6

    def dest_q(self) -> np.ndarray:
        if self.static:
            return self.q_dest
        self.q_dest = self.kin.ik(self.dest_t6(), self.config, self.q_dest, self.where)
        return self.q_dest

    def t6_at(self, lam: float) -> np.ndarray:
        """Cartesian mode: T6 at lam (tool frame on the drive path, back to link 6)."""
        x = self.dest_t6() @ self.tool @ drive(self.d, self.k, self.theta, lam)
        return x @ self.tool_inv

    def q_at(self, lam: float, q_ref: np.ndarray) -> np.ndarray:
        if self.mode == "joint":
            return self.dest_q() + lam * self.dq
        return self.kin.ik(self.t6_at(lam), self.config, q_ref, self.where)

    def residual(self, mu: float) -> np.ndarray:
        """Cartesian mode: the base-frame rigid motion X_C Drive(mu) X_C^-1 still to be covered at lam = mu."""
        x = self.dest_t6() @ self.tool
        return x @ drive(self.d, self.k, self.theta, mu) @ inverse(x)


@dataclass
class Transition:
    prev: Segment
    t_start: float
    tau: float
    q_b: np.ndarray | None = None     # joints at the corner (Cartesian -> joint transitions)
    q_ref: np.ndarray | None = None   # last joint solution of the old segment's remainder

    @property
    def t_end(self) -> float:
        return self.t_start + 2.0 * self.tau


def _scale_for(v1: np.ndarray, v2: np.ndarray, c: np.ndarray) -> float:
    """Largest s in (0, 1] with |s v2_i - v1_i| <= c_i for all i (s = 0 is assumed feasible)."""
    s = 1.0
    for a, b, lim in zip(v2, v1, c):
        if abs(a) < 1e-15:
            continue
        lo, hi = (b - lim) / a, (b + lim) / a
        if lo > hi:
            lo, hi = hi, lo
        s = min(s, hi)
    return max(s, 1e-3)


def _scale_norm(v1: np.ndarray, v2: np.ndarray, c: float) -> float:
    """Largest s in (0, 1] with |s v2 - v1| <= c (Euclidean), assuming |v1| <= c."""
    a = float(v2 @ v2)
    if a < 1e-30:
        return 1.0
    b = float(v1 @ v2)
    disc = b * b - a * (float(v1 @ v1) - c * c)
    if disc < 0:
        return 1e-3
    return max(1e-3, min(1.0, (b + math.sqrt(disc)) / a))


# --------------------------------------------------------------------------------------
# planning one segment (used by the control level, and by the planning level to check early)
# --------------------------------------------------------------------------------------
def plan_segment(kin: Kinematics, limits: Limits, dt: float, req: Request, t6_b: np.ndarray,
                 q_b: np.ndarray, t0: float, tau_in: float | None, v1: np.ndarray | None = None,
                 v1_cart: tuple[np.ndarray, np.ndarray] | None = None,
                 check_points: int = MAX_CHECK_POINTS) -> Segment:
    """Plan ``req`` from the corner (T6 ``t6_b``, joints ``q_b``); raise an RCCL MotionError if it cannot run.

    ``v1`` (rad/s) and ``v1_cart`` ((m/s, rad/s) in the base frame) are the velocities the
    previous segment ends with; the new segment is slowed if needed so the transition of
    half-width ``tau_in`` stays within the acceleration limits. ``tau_in=None`` means the
    arm starts from rest: the transition is then made long enough to reach the new speed
    within the acceleration limits (read it back from ``seg.tau_in``); ``t0`` is then the
    transition's start and ``seg.t0`` is set to ``t0 + seg.tau_in``.
    """
    seg = Segment(req, kin)
    params: MotionParams = req.params
    pos = req.position
    where = seg.where
    seg.t0 = t0
    seg.tool = pos.tool_from_t6(req.snap)
    seg.tool_inv = inverse(seg.tool)
    t6_c = pos.solve(req.snap)
    x_b, x_c = t6_b @ seg.tool, t6_c @ seg.tool
    rel = inverse(x_c) @ x_b
    seg.d = rel[:3, 3].copy()
    seg.k, seg.theta = axis_angle(rel)
    dist = float(np.linalg.norm(seg.d))
    cfg_b = kin.config_of(q_b)
    seg.config = resolve_config(kin, cfg_b, params.config)
    # Cartesian speed limits bind the tool only where its path is the straight line (Cartesian mode);
    # in joint mode the chord length with the requested speeds sets the pace, the joint limits bound it
    t_vel = 0.0
    if seg.mode == "cartesian":
        t_vel = max(dist / limits.translational_velocity, seg.theta / limits.rotational_velocity)
    if params.travel_time is None:  # settime's travel time replaces the requested speeds (not the limits)
        t_vel = max(t_vel, dist / params.translational_velocity, seg.theta / params.rotational_velocity)
    vmax = limits.joint_velocity
    if seg.mode == "joint":
        q_c = getattr(pos, "joints", None)
        if q_c is not None and seg.static and params.config is None:
            seg.config = kin.config_of(q_c)      # a joint-defined position (park): go to its joints
        else:
            q_c = _fit_range(limits, kin.ik(t6_c, seg.config, q_b, where))
        _check_range(limits, q_c, where, "destination")
        seg.dq = q_b - q_c
        seg.q_dest = q_c
        t_lim = max(t_vel, float(np.max(np.abs(seg.dq) / vmax)))
        v_start_dir = -seg.dq          # joint velocity * T at the start (and at the end)
        v_end_dir = -seg.dq
    else:
        if seg.config != cfg_b:
            raise ConfigurationChange(
                f"{where}: Cartesian mode cannot change the arm configuration from {cfg_b} to {seg.config}; "
                "use setmod('joint') for this move")
        seg.dq = np.zeros(6)
        if dist < 1e-12 and seg.theta < 1e-12:
            q_c = kin.ik(t6_c, seg.config, q_b, where) if not np.allclose(t6_b, t6_c, atol=1e-12) else q_b
            seg.q_dest = q_c
            t_lim = 0.0
            v_start_dir = v_end_dir = np.zeros(6)
        elif (req.profile is not None and np.array_equal(req.profile[0], t6_b)
              and np.array_equal(req.profile[3], t6_c)
              and np.allclose(req.profile[1], q_b, rtol=0.0, atol=1e-12)):
            # move() already checked this very path (same corner, same destination): reuse its results
            t_joint, v_start_dir, v_end_dir, seg.q_dest = req.profile[2]
            t_lim = max(t_vel, t_joint)
        else:
            n = int(min(check_points, max(8, math.ceil(t_vel / dt))))
            q_prev = q_b
            path = [q_b]
            for j in range(1, n + 1):
                lam = 1.0 - j / n
                t6 = x_c @ drive(seg.d, seg.k, seg.theta, lam) @ seg.tool_inv
                q = kin.ik(t6, seg.config, q_prev, f"{where} at {100 * (1 - lam):.0f}% of the path")
                _check_range(limits, q, where, f"path point at {100 * (1 - lam):.0f}%")
                path.append(q)
                q_prev = q
            steps = np.abs(np.diff(np.array(path), axis=0)) * n  # |dq/dlam| per joint
            t_joint = float(np.max(steps / vmax))
            if t_joint > SINGULAR_SLOWDOWN * max(t_vel, 0.05):
                j, i = np.unravel_index(int(np.argmax(steps / vmax)), steps.shape)
                raise SingularPath(
                    f"{where}: the straight-line path passes through or too near a singularity: joint {i + 1} "
                    f"would have to turn {steps[j, i] / n:.3f} rad between {100 * j / n:.0f}% and "
                    f"{100 * (j + 1) / n:.0f}% of the path (joint speed {t_joint / max(t_vel, 1e-9):.0f}x its limit "
                    "at the requested speed); choose another path or use joint mode")
            seg.q_dest = path[-1]
            t_lim = max(t_vel, t_joint)
            v_start_dir = (path[1] - path[0]) * n
            v_end_dir = (path[-1] - path[-2]) * n
            req.profile = (t6_b.copy(), q_b.copy(), (t_joint, v_start_dir, v_end_dir, seg.q_dest), t6_c.copy())
    travel = params.travel_time
    T = max(t_lim, travel) if travel is not None else t_lim
    tau_req = params.transition_time / 2.0
    if tau_in is None:  # from rest: a transition long enough to reach the segment's speed
        T = max(T, 2.0 * tau_req, 2.0 * dt)
        tau_in = max(tau_req, _tau_for(limits, v_start_dir / T, x_c, seg, T))
        t0 = t0 + tau_in
        v1 = v1_cart = None
        seg.t0 = t0
    seg.tau_in = tau_in
    seg.stationary = dist < 1e-12 and seg.theta < 1e-12 and float(np.max(np.abs(seg.dq))) < 1e-12
    T = max(T, tau_in + tau_req, 2.0 * dt)
    # keep the incoming transition within the acceleration limits (peak ACC_PEAK |dv| / tau);
    # seg.scale < 1 is how much the new segment had to be slowed for it (the generator stops at
    # the corner instead when that is below MIN_BLEND_SCALE, e.g. for a sharp reversal)
    seg.scale = 1.0
    if v1 is not None and tau_in > 0:
        s = _scale_for(v1, v_start_dir / T, limits.joint_acceleration * tau_in / ACC_PEAK)
        if v1_cart is not None and seg.mode == "cartesian":
            vt2, vr2 = _cart_velocity(x_c, seg, T)
            s = min(s, _scale_norm(v1_cart[0], vt2, limits.translational_acceleration * tau_in / ACC_PEAK),
                    _scale_norm(v1_cart[1], vr2, limits.rotational_acceleration * tau_in / ACC_PEAK))
        T /= s
        seg.scale = s
    tau_out = max(tau_req, _tau_for(limits, v_end_dir / T, x_c, seg, T))
    seg.T = max(T, tau_in + tau_out)
    seg.tau_out = tau_out
    seg.v_end = v_end_dir / seg.T
    seg.v_cart = _cart_velocity(x_c, seg, seg.T)
    if seg.static:
        seg.x_dest = t6_c
    return seg


def _tau_for(limits: Limits, v_joint: np.ndarray, x_c: np.ndarray, seg: Segment, T: float) -> float:
    """Half-width of a transition that brings the segment's velocities to rest within every acceleration limit."""
    tau = float(np.max(ACC_PEAK * np.abs(v_joint) / limits.joint_acceleration))
    if seg.mode != "cartesian":
        return tau
    vt, vr = _cart_velocity(x_c, seg, T)
    return max(tau, ACC_PEAK * float(np.linalg.norm(vt)) / limits.translational_acceleration,
               ACC_PEAK * float(np.linalg.norm(vr)) / limits.rotational_acceleration)


def _cart_velocity(x_c: np.ndarray, seg: Segment, T: float) -> tuple[np.ndarray, np.ndarray]:
    """Tool velocity (m/s) and angular velocity (rad/s) in the base frame along a Cartesian segment."""
    r = x_c[:3, :3]
    return -(r @ seg.d) / T, -(r @ seg.k) * seg.theta / T


def _fit_range(limits: Limits, q: np.ndarray) -> np.ndarray:
    """Joint-mode destinations: move a revolute joint outside its range by +-2 pi when that brings it inside.

    Inverse kinematics picks the 2 pi branch nearest the start; a joint whose range spans
    more than one side of +-pi (the PUMA waist) may need the other branch.
    """
    q = q.copy()
    for i in range(q.size):
        for shift in (2 * math.pi, -2 * math.pi):
            if not (limits.lower[i] <= q[i] <= limits.upper[i]) and limits.lower[i] <= q[i] + shift <= limits.upper[i]:
                q[i] += shift
    return q


def _check_range(limits: Limits, q: np.ndarray, where: str, what: str) -> None:
    i = limits.out_of_range(q)
    if i is not None:
        raise Unreachable(f"{where}: {what} needs joint {i + 1} at {q[i]:.4f} rad, outside its range "
                          f"[{limits.lower[i]:.4f}, {limits.upper[i]:.4f}] rad")


# --------------------------------------------------------------------------------------
# the generator
# --------------------------------------------------------------------------------------
class TrajectoryGenerator:
    """Runs at the control level: ``step()`` once per sample returns the joint angles to command (rad).

    ``queue`` is shared with the planning level. ``errors`` collects refused requests and
    faults for the planning level; ``faulted`` freezes the arm at the last command.
    """

    def __init__(self, kin: Kinematics, limits: Limits, dt: float, q0: np.ndarray,
                 queue: MotionQueue[Request] | None = None) -> None:
        self.kin = kin
        self.limits = limits
        self.dt = float(dt)
        self.queue: MotionQueue[Request] = queue if queue is not None else MotionQueue()
        self.t = 0.0
        self.q = np.array(q0, dtype=float)
        self.q_prev = self.q.copy()
        self.errors: list[MotionError] = []
        self.faulted: TrajectoryFault | None = None
        self.trans: Transition | None = None
        self.samples = 0
        self._hold_here(0.0)

    def _hold_here(self, t: float) -> None:
        """Make the arm hold at the last commanded joint angles from time ``t`` on."""
        here = joint_position("here", self.kin, self.q)
        start = Request(here, here.snapshot(), MotionParams(mode="joint"), repeat=True, status="running")
        self.seg = plan_segment(self.kin, self.limits, self.dt, start, self.kin.fk(self.q), self.q, t, 0.0)
        self.trans = None

    def restart(self) -> None:
        """Clear a fault (planning level): the arm holds where it was frozen and accepts new requests."""
        self.queue.clear()
        self.faulted = None
        self.q_prev = self.q.copy()
        self._hold_here(self.t)

    # -- the per-sample entry point ---------------------------------------------------
    def step(self) -> np.ndarray:
        """Advance one sample period and return the joint angles to command (rad, (6,))."""
        if self.faulted is not None:
            return self.q
        t = self.t + self.dt
        try:
            if self.trans is not None and t >= self.trans.t_end:
                self.trans.prev.req.finish()
                self.trans = None
            seg = self.seg
            if self.trans is None and t >= seg.t0 + seg.T - seg.tau_out:
                self._begin_transition()
            self._update_functional()
            q = self._evaluate(t)
            self._check_step(q)
        except (MotionError, ValueError, ArithmeticError) as exc:
            self._freeze(exc)
            return self.q
        self.q_prev, self.q = self.q, q
        self.t = t
        self.samples += 1
        return q

    # -- internals ----------------------------------------------------------------------
    def _update_functional(self) -> None:
        positions = [self.seg.req.position]
        if self.trans is not None and self.trans.prev.req.position is not positions[0]:
            positions.append(self.trans.prev.req.position)
        for p in positions:
            p.update_functional()

    def _evaluate(self, t: float) -> np.ndarray:
        seg = self.seg
        tr = self.trans
        if tr is None:
            lam = max(0.0, 1.0 - (t - seg.t0) / seg.T)
            return seg.q_at(lam, self.q)
        h = min(1.0, max(0.0, (t - tr.t_start) / (2.0 * tr.tau)))
        poly = (2.0 - h) * h ** 3
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

    def _begin_transition(self) -> None:
        prev = self.seg
        tau = prev.tau_out
        t_b = prev.t0 + prev.T
        t6_b = prev.dest_t6()
        q_b = prev.dest_q() if prev.mode == "joint" else self.kin.ik(t6_b, prev.config, self.q, prev.where)
        req = self.queue.get()
        seg = None
        at_rest = prev.req.repeat and prev.stationary
        if req is not None:
            req.status = "running"
            try:
                if at_rest:  # the arm stands still: start the transition now, as long as the new speed needs
                    seg = plan_segment(self.kin, self.limits, self.dt, req, t6_b, q_b, t_b - tau, None,
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
            seg = plan_segment(self.kin, self.limits, self.dt, hold, t6_b, q_b, t_b, tau, prev.v_end,
                               prev.v_cart if prev.mode == "cartesian" else None)
        self.trans = Transition(prev, t_b - tau, tau, q_b, self.q.copy())
        self.seg = seg

    def _check_step(self, q: np.ndarray) -> None:
        step = np.abs(q - self.q)
        bound = self.limits.joint_velocity * self.dt * STEP_MARGIN + 1e-9
        bad = np.nonzero(step > bound)[0]
        if bad.size:
            i = int(bad[0])
            raise SingularPath(f"{self.seg.where}: joint {i + 1} would move {step[i]:.4f} rad in one sample "
                               f"(limit {bound[i]:.4f} rad at {1 / self.dt:.0f} Hz): a singularity or a target "
                               "moving too fast; arm stopped")
        _check_range(self.limits, q, self.seg.where, "the commanded point")

    def _freeze(self, exc: BaseException) -> None:
        fault = TrajectoryFault(f"trajectory generator stopped the arm at t = {self.t:.3f} s: {exc}", exc)
        self.faulted = fault
        self.errors.append(fault)
        for r in ([self.trans.prev.req] if self.trans else []) + [self.seg.req] + self.queue.clear():
            if r.status in ("queued", "running"):
                r.finish(fault)

    # -- read-out -------------------------------------------------------------------------
    @property
    def busy(self) -> bool:
        """True while a non-repeated request is running or queued."""
        return (bool(len(self.queue)) or not self.seg.req.repeat
                or (self.trans is not None and not self.trans.prev.req.repeat))
