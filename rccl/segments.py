"""RCCL's segments (thesis 5.2, appendix E.1): a motion request planned as a segment
linear in its own space, timed, and joined to the next by a transition.

- joint mode: q(lam) = q_C + lam (q_B - q_C), a straight line in joint space (E.1);
- Cartesian mode: the tool frame X(lam) = X_C Drive(lam), with X_C the destination's tool
  frame and Drive(lam) = Trans(lam d) Rot(k, lam theta) the drive transform (E.3-E.5)
  taken relative to the destination, so Drive(1) = X_C^-1 X_B (the start) and Drive(0) = I.

``plan_path`` (called by ``move()`` at the planning level) computes a request's ``Plan``
once: its geometry, the destination's joints and, in Cartesian mode, the path sampled and
checked for reach, joint ranges and singularities; ``time_segment`` / ``plan_segment``
time it when it starts. The generator that runs them sample by sample is
rccl.trajectory.TrajectoryGenerator.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import partial

import numpy as np

from . import redundancy
from .exceptions import ConfigurationChange, MotionError, SingularPath, UnreachableTarget
from .limits import Limits
from .motion import MotionParams, Request
from .drive import drive_basis, drive_coefficients
from .transform import T6, axis_angle, inverse

ACC_PEAK = 0.75          # peak of the quartic's acceleration: ACC_PEAK * |v2 - v1| / tau
STEP_MARGIN = 1.25       # a step up to this factor over v_max * dt is slowed to the limit; beyond, a fault
SINGULAR_SLOWDOWN = 10.0  # a Cartesian path needing > 10x its requested time for joint speed is singular
MIN_BLEND_SCALE = 0.5    # below this speed factor a corner is taken by stopping at it instead (see plan_segment)
MAX_CHECK_POINTS = 200   # samples of a Cartesian path checked by move() before its motion starts
# the control level's re-check of a Cartesian path, when the arm or the target is no longer where
# move() checked it from (a variable or functional target, a refused request before it): about
# 0.7 us per point with the compiled kinematics; with the fixed cost of planning, well under 100 us
CONTROL_CHECK_POINTS = 16
# the worst interval of a sampled Cartesian path is refined REFINE_LEVELS times at REFINE_POINTS
# points (64x finer, 16 more inverse kinematics calls): a branch jump at a singularity crossing
# then shows as the speed it would really need, whatever the coarse sampling
REFINE_POINTS = 8
REFINE_LEVELS = 2
# ... when a joint moves more in the worst coarse interval than this many seconds at its top
# speed: a branch jump of pi does on every joint (top speeds are far below 60 rad/s), while a
# path whose joints all move less than that between samples has no large step to hide
REFINE_TRIGGER_S = 0.05
SAME_CORNER_TOL = 1e-12
_EYE4 = np.eye(4)
_EYE4.flags.writeable = False   # shared by every plan whose tool is T6  # joints (rad or m) within this of the checked corner: move()'s path check still applies


# --------------------------------------------------------------------------------------
# kinematics wrapper: the generated module's errors become RCCL errors naming the position
# --------------------------------------------------------------------------------------
class Kinematics:
    """The contract's kinematics module with RCCL error wrapping, configuration and path helpers.

    ``ik`` calls the module's public ``ik`` directly (for the generated modules that is the
    compiled fast entry, which checks the pose, the guards and the prismatic ranges and
    never returns NaN); only a failure takes the slow path that builds the RCCL error.
    """

    def __init__(self, module) -> None:
        self.module = module
        self.fk = module.fk
        self._ik = module.ik
        self.config_of = module.config_of
        self.Config = getattr(module, "Config", None)
        self.name = getattr(module, "ROBOT", getattr(module, "__name__", "robot"))
        kinds = getattr(module, "JOINT_KINDS", ("revolute",) * 6)
        self.revolute = np.array([k == "revolute" for k in kinds])
        self.units = tuple("rad" if r else "m" for r in self.revolute)
        self.dof = len(kinds)
        #: a 7-joint arm: its free parameter q7 is chosen by a rule (rccl.redundancy, setfree)
        self.redundant = self.dof > 6
        #: the running generator's time (s), for the free parameter's rules of time
        self.clock = None
        if self.redundant:     # (T6, config, q_ref, t=None) -> joints, q7 by config's rule
            self._ik = partial(redundancy.solve, self)

    def ik(self, base_to_t6: np.ndarray, config, q_ref: np.ndarray, where: str, t: float | None = None) -> np.ndarray:
        """Joint angles (rad; m for prismatic joints) of T6 (base to link 6) in ``config``, branch nearest ``q_ref``;
        a redundant arm's q7 by ``config``'s rule at ``t`` s from the motion's start (None: the generator's clock)."""
        try:
            if t is None or not self.redundant:
                return self._ik(base_to_t6, config, q_ref)
            return self._ik(base_to_t6, config, q_ref, t)
        except ValueError as exc:  # KinematicsError subclasses ValueError
            raise self._error(exc, base_to_t6, config, where) from exc

    @staticmethod
    def _error(exc: ValueError, base_to_t6: np.ndarray, config, where: str) -> MotionError:
        cls = SingularPath if "singular" in type(exc).__name__.lower() else UnreachableTarget
        p = base_to_t6[:3, 3]
        return cls(f"{where}: no joint solution in configuration {config} for T6 at "
                   f"({p[0]:.4f}, {p[1]:.4f}, {p[2]:.4f}) m: {exc}")

    def ik_path(self, poses: np.ndarray, config, q_start: np.ndarray, where: str, lams: np.ndarray,
                limits: Limits | None = None, duration: float = 0.0) -> np.ndarray:
        """Joints along a path of T6 poses (N, 4, 4), each solved from the one before: (N + 1, 6), q_start first.

        One fast-entry inverse kinematics call per point (about half a microsecond each with
        the compiled kernels). When a point fails, the destination is tried first (the usual
        cause, named as such), then the points one by one from the start with their joint
        ranges (``limits``), so the error names the first point that fails (from ``lams``).
        """
        n = poses.shape[0]
        path = np.empty((n + 1, self.dof))
        path[0] = prev = q_start
        ik = self._ik
        # a redundant arm's rule sees the planned time of each point: (1 - lam) * duration (s)
        times = ((1.0 - lams) * duration).tolist() if self.redundant else None
        try:
            if times is None:
                for j in range(n):
                    prev = path[j + 1] = ik(poses[j], config, prev)
            else:
                for j in range(n):
                    prev = path[j + 1] = ik(poses[j], config, prev, times[j])
            if np.isfinite(path).all():   # (the contract's modules never return NaN; others might)
                return path
        except ValueError:
            pass
        if times is None:     # (a redundant arm's destination depends on the path before it: solved in order)
            self.ik(poses[-1], config, q_start, f"{where}, its destination")
        prev = q_start
        for j in range(n):
            at = f"{where} at {100 * (1 - lams[j]):.0f}% of the path"
            prev = path[j + 1] = self.ik(poses[j], config, prev, at, None if times is None else times[j])
            if limits is not None:
                check_range(limits, prev, at, "path point", self.units)
        return path


def resolve_config(kin: Kinematics, current, wanted):
    """The configuration to use: ``wanted`` (a Config, or a dict of fields to change) applied to ``current``."""
    if wanted is None:
        return current
    if isinstance(wanted, dict):
        fields = getattr(current, "_fields", None) or getattr(current, "__dataclass_fields__", {})
        unknown = sorted(set(wanted) - set(fields))
        if unknown:
            from .exceptions import BadRequest
            raise BadRequest(f"setconf: the {kin.name} has no {'/'.join(unknown)} configuration choice "
                             f"(its configuration is {type(current).__name__}({', '.join(fields)}))")
        if hasattr(current, "_replace"):
            return current._replace(**wanted)
        return replace(current, **wanted)
    return wanted


# --------------------------------------------------------------------------------------
# plans and segments
# --------------------------------------------------------------------------------------
class Plan:
    """The time-independent part of a motion from a corner: geometry, destination joints, checked path.

    Built once per request by ``plan_path`` (by ``move()`` at the planning level, where the
    Cartesian path is checked point by point for reach, joint ranges and singularities) and
    reused by the generator when the request starts from the corner it was checked from.
    ``basis`` (Cartesian, (4, 16)) gives T6(lam) = [1, cos(lam theta), sin(lam theta), lam] @ basis
    for a static destination (every transform const or hold).
    """

    __slots__ = ("mode", "t6_b", "q_b", "t6_c", "x_c", "tool", "tool_inv", "d", "k", "theta", "dist", "config",
                 "dq", "q_dest", "t_lim", "v_start_dir", "v_end_dir", "static", "drive", "basis", "vt_dir", "vr_dir",
                 "v_start_list", "acc_start", "acc_end", "vt_list", "vr_list", "vt_norm", "vr_norm", "stationary",
                 "t_est")

    def finish(self, limits: Limits) -> "Plan":
        """Precompute the floats ``time_segment`` needs, so timing a segment is plain float arithmetic."""
        jacc = limits.joint_acceleration.tolist()
        self.v_start_list = v0 = self.v_start_dir.tolist()
        v1 = self.v_end_dir.tolist()
        # max_i |v_i| / a_max_i of the path's joint velocities times T at each end (see _tau)
        self.acc_start = max(abs(v) / a for v, a in zip(v0, jacc))
        self.acc_end = max(abs(v) / a for v, a in zip(v1, jacc))
        self.vt_list, self.vr_list = self.vt_dir.tolist(), self.vr_dir.tolist()
        self.vt_norm, self.vr_norm = math.hypot(*self.vt_list), math.hypot(*self.vr_list)
        self.stationary = self.dist < 1e-12 and self.theta < 1e-12 and max(map(abs, self.dq.tolist())) < 1e-12
        return self

    def fits(self, req: Request, t6_b: np.ndarray, q_b: np.ndarray) -> bool:
        """Whether this plan still holds for ``req`` starting at (``t6_b``, ``q_b``)."""
        if self.mode != req.mode or not (t6_b is self.t6_b or np.array_equal(t6_b, self.t6_b)):
            return False
        if float(np.max(np.abs(q_b - self.q_b))) > SAME_CORNER_TOL:
            return False
        if self.static and is_static(req):
            return True
        return np.array_equal(req.position.solve(req.snap), self.t6_c)


def is_static(req: Request) -> bool:
    return all(t.kind in ("const", "hold") for t in req.position.transforms())


class Segment:
    """One planned motion: linear in joint space or along a drive transform, lam from 1 to 0 over T seconds."""

    __slots__ = ("req", "mode", "t0", "T", "tau_in", "tau_out", "stationary", "scale", "tool", "tool_inv", "config", "d", "k", "theta",
                 "dq", "q_dest", "static", "x_dest", "v_end", "v_cart", "kin", "where", "plan", "_drive", "_basis",
                 "_residual", "_coef", "_buf", "_buf44")

    def __init__(self, req: Request, kin: Kinematics) -> None:
        self.req = req
        self.kin = kin
        self.mode = req.mode
        self.where = f"move({req.position.name})"
        self.static = is_static(req)
        self.x_dest = None
        self.plan: Plan | None = None
        self._drive = self._basis = self._residual = None
        self._coef = np.ones(4)
        self._buf = np.empty(16)
        self._buf44 = self._buf.reshape(4, 4)   # the same memory as a 4x4 view: T6 of the current sample

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

    def _coefficients(self, lam: float) -> np.ndarray:
        c = self._coef
        a = lam * self.theta
        c[1] = math.cos(a)
        c[2] = math.sin(a)
        c[3] = lam
        return c

    def t6_at(self, lam: float) -> np.ndarray:
        """Cartesian mode: T6 at lam (tool frame on the drive path, back to link 6); valid until the next call."""
        if self._drive is None:
            self._drive = drive_basis(self.d, self.k)
        c = self._coefficients(lam)
        if self.static:
            if self._basis is None:
                x = self.dest_t6() @ self.tool
                self._basis = (x @ self._drive.reshape(4, 4, 4) @ self.tool_inv).reshape(4, 16)
            np.dot(c, self._basis, out=self._buf)
            return self._buf44
        drv = np.dot(c, self._drive, out=self._buf).reshape(4, 4)
        return self.dest_t6() @ self.tool @ drv @ self.tool_inv

    def q_at(self, lam: float, q_ref: np.ndarray) -> np.ndarray:
        if self.mode == "joint":
            return self.dest_q() + lam * self.dq
        return self.kin.ik(self.t6_at(lam), self.config, q_ref, self.where)

    def residual(self, mu: float) -> np.ndarray:
        """Cartesian mode: the base-frame rigid motion X_C Drive(mu) X_C^-1 still to be covered at lam = mu."""
        if self._drive is None:
            self._drive = drive_basis(self.d, self.k)
        c = self._coefficients(mu)
        if self.static:
            if self._residual is None:
                x = self.dest_t6() @ self.tool
                self._residual = (x @ self._drive.reshape(4, 4, 4) @ inverse(x)).reshape(4, 16)
            return (c @ self._residual).reshape(4, 4)
        x = self.dest_t6() @ self.tool
        return x @ (c @ self._drive).reshape(4, 4) @ inverse(x)


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


@dataclass(frozen=True)
class TransitionEvent:
    """What ``TrajectoryGenerator.on_transition`` listeners get when a transition starts
    (5.5.1): its window on the trajectory's clock (s), the positions it joins, and whether
    anything moves (False for one hold of a point into the next)."""

    t_start: float
    t_end: float
    from_position: str
    to_position: str
    moving: bool


def _scale_for(v1: list[float], v2_dir: list[float], T: float, c: list[float]) -> float:
    """Largest s in (0, 1] with |s v2_i - v1_i| <= c_i for all i, v2 = v2_dir / T (s = 0 is assumed feasible)."""
    s = 1.0
    for a, b, lim in zip(v2_dir, v1, c):
        a /= T
        if abs(a) < 1e-15:
            continue
        lo, hi = (b - lim) / a, (b + lim) / a
        if lo > hi:
            lo, hi = hi, lo
        s = min(s, hi)
    return max(s, 1e-3)


def _scale_norm(v1: list[float], v2_dir: list[float], T: float, c: float) -> float:
    """Largest s in (0, 1] with |s v2 - v1| <= c (Euclidean), v2 = v2_dir / T, assuming |v1| <= c."""
    v2 = [x / T for x in v2_dir]
    a = v2[0] * v2[0] + v2[1] * v2[1] + v2[2] * v2[2]
    if a < 1e-30:
        return 1.0
    b = v1[0] * v2[0] + v1[1] * v2[1] + v1[2] * v2[2]
    disc = b * b - a * (v1[0] * v1[0] + v1[1] * v1[1] + v1[2] * v1[2] - c * c)
    if disc < 0:
        return 1e-3
    return max(1e-3, min(1.0, (b + math.sqrt(disc)) / a))


# --------------------------------------------------------------------------------------
# planning one segment: the path (planning level, once per request) and its timing (per start)
# --------------------------------------------------------------------------------------
def plan_path(kin: Kinematics, limits: Limits, dt: float, req: Request, t6_b: np.ndarray, q_b: np.ndarray,
              check_points: int = MAX_CHECK_POINTS) -> Plan:
    """The geometry of ``req`` from the corner (T6 ``t6_b``, joints ``q_b``), its path checked; raises a MotionError.

    Cartesian mode samples the straight line at the sample rate (at most ``check_points``
    points) with the inverse kinematics in the arm's configuration: a point out of reach or
    outside a joint range raises ``UnreachableTarget``; a joint that would have to turn more than
    ``SINGULAR_SLOWDOWN`` times faster than its limit allows at the asked speed (the path
    passes through or near a singularity, e.g. the wrist's) raises ``SingularPath``.
    """
    params: MotionParams = req.params
    pos = req.position
    where = f"move({pos.name})"
    p = Plan()
    p.mode, p.t6_b, p.q_b, p.static = req.mode, t6_b, q_b.copy(), is_static(req)
    t6_c = p.t6_c = pos.solve(req.snap)
    if pos.tool is T6:   # the tool frame is link 6 (the usual case): no tool products
        p.tool = p.tool_inv = _EYE4
        x_b, x_c = t6_b, t6_c
    else:
        p.tool = pos.tool_from_t6(req.snap)
        p.tool_inv = inverse(p.tool)
        x_b, x_c = t6_b @ p.tool, t6_c @ p.tool
    p.x_c = x_c
    rel = inverse(x_c) @ x_b
    d = p.d = rel[:3, 3].copy()
    p.k, p.theta = axis_angle(rel)
    dist = p.dist = math.hypot(*d.tolist())
    cfg_b = kin.config_of(q_b)
    p.config = resolve_config(kin, cfg_b, params.config)
    p.drive = drive_basis(d, p.k)
    p.basis = _t6_basis(x_c, p.drive, p.tool_inv, pos.tool is T6)
    r = x_c[:3, :3]
    p.vt_dir, p.vr_dir = -(r @ d), -(r @ p.k) * p.theta   # tool velocity * T (base frame)
    # Cartesian speed limits bind the tool only where its path is the straight line (Cartesian mode);
    # in joint mode the chord length with the requested speeds sets the pace, the joint limits bound it
    t_vel = 0.0
    if p.mode == "cartesian":
        t_vel = max(dist / limits.translational_velocity, p.theta / limits.rotational_velocity)
    if params.travel_time is None:  # settime's travel time replaces the requested speeds (not the limits)
        t_vel = max(t_vel, dist / params.translational_velocity, p.theta / params.rotational_velocity)
    vmax = limits.joint_velocity
    units = kin.units
    # the planned duration (s) a redundant arm's rule of time is checked with
    p.t_est = t_est = max(t_vel, params.travel_time or 0.0)
    if p.mode == "joint":
        q_c = getattr(pos, "joints", None)
        if q_c is not None and p.static and params.config is None:
            p.config = kin.config_of(q_c)      # a joint-defined position (park): go to its joints
        else:
            p.config = redundancy.bind_for(kin, p.config, params, q_b, where, cartesian=False)
            q_c = _fit_range(limits, kin.ik(t6_c, p.config, q_b, where, t_est), kin.revolute)
        check_range(limits, q_c, where, "destination", units)
        p.dq = q_b - q_c
        p.q_dest = q_c
        p.t_lim = max(t_vel, float(np.max(np.abs(p.dq) / vmax)))
        p.v_start_dir = p.v_end_dir = -p.dq          # joint velocity * T at the start (and at the end)
        return p.finish(limits)
    if p.config != cfg_b:
        raise ConfigurationChange(
            f"{where}: Cartesian mode cannot change the arm configuration from {cfg_b} to {p.config}; "
            "use setmod('joint') for this move")
    p.config = redundancy.bind_for(kin, p.config, params, q_b, where, cartesian=True)
    p.dq = np.zeros(kin.dof)
    if dist < 1e-12 and p.theta < 1e-12:
        # (a redundant arm may move in place: its rule's q7 at the end, e.g. a self-motion)
        same = float(np.max(np.abs(t6_b - t6_c))) <= 1e-12 and not kin.redundant
        p.q_dest = q_b.copy() if same else kin.ik(t6_c, p.config, q_b, where, t_est)
        p.t_lim = 0.0
        p.v_start_dir = p.v_end_dir = np.zeros(kin.dof)
        return p.finish(limits)
    n = int(min(check_points, max(8, math.ceil(t_vel / dt))))
    lams = 1.0 - np.arange(1, n + 1) / n
    poses = (drive_coefficients(p.theta, lams) @ p.basis).reshape(n, 4, 4)
    path = kin.ik_path(poses, p.config, q_b, where, lams, limits, t_est)
    bad = (path[1:] < limits.lower - 1e-9) | (path[1:] > limits.upper + 1e-9)
    if bad.any():
        j, i = np.argwhere(bad)[0]
        check_range(limits, path[j + 1], where, f"path point at {100 * (1 - lams[j]):.0f}%", units)
    steps = np.abs(path[1:] - path[:-1]) * n  # |dq/dlam| per joint
    ratio = steps / vmax
    j, i = np.unravel_index(int(np.argmax(ratio)), ratio.shape)
    # the coarse samples hide how fast a joint really turns near a singularity (and a jump of pi
    # between two samples looks like a fast turn): refine the worst interval when some joint moves
    # more in it than REFINE_TRIGGER_S seconds at its top speed (any branch jump does)
    t_joint = float(ratio[j, i])
    if t_joint / n > REFINE_TRIGGER_S:
        t_joint = _refine(kin, limits, p, path[j], 1.0 - j / n, 1.0 / n, t_joint, where)
    if t_joint > SINGULAR_SLOWDOWN * max(t_vel, 0.05):
        raise SingularPath(
            f"{where}: the straight-line path passes through or too near a singularity: joint {i + 1} "
            f"would have to move {steps[j, i] / n:.3f} {units[i]} between {100 * j / n:.0f}% and "
            f"{100 * (j + 1) / n:.0f}% of the path (joint speed {t_joint / max(t_vel, 1e-9):.0f}x its limit "
            "at the requested speed); choose another path or use joint mode")
    p.q_dest = path[-1].copy()
    p.t_lim = max(t_vel, t_joint)
    p.v_start_dir = (path[1] - path[0]) * n
    p.v_end_dir = (path[-1] - path[-2]) * n
    return p.finish(limits)


def _refine(kin: Kinematics, limits: Limits, p: Plan, q_lo: np.ndarray, lam_lo: float, width: float,
            coarse: float, where: str) -> float:
    """max |dq/dlam| / v_max over the lam interval [lam_lo - width, lam_lo], sampled up to REFINE_POINTS^REFINE_LEVELS finer.

    ``coarse`` is the interval's value from its two ends. Each level samples the interval at
    REFINE_POINTS points (from ``q_lo``, the joints at ``lam_lo``) and descends into its worst
    sub-interval. A smooth path gives about the same value as the coarser samples, and the
    descent stops there; a branch jump stays one step, so its value grows REFINE_POINTS times
    per level.
    """
    vmax = limits.joint_velocity
    worst = coarse
    m = REFINE_POINTS
    for _ in range(REFINE_LEVELS):
        lams = lam_lo - width * np.arange(1, m + 1) / m
        poses = (drive_coefficients(p.theta, lams) @ p.basis).reshape(m, 4, 4)
        sub = kin.ik_path(poses, p.config, q_lo, where, lams, limits, p.t_est)
        ratio = (np.abs(sub[1:] - sub[:-1]) / vmax).max(axis=1)
        k = int(np.argmax(ratio))
        value = float(ratio[k]) * m / width
        converged = value < 1.5 * worst
        worst = max(worst, value)
        if converged:
            break
        lam_lo, q_lo, width = lam_lo - width * k / m, sub[k], width / m
    return worst


def _t6_basis(x_c: np.ndarray, drive4: np.ndarray, tool_inv: np.ndarray, no_tool: bool) -> np.ndarray:
    """T6(lam) = X_C Drive(lam) Tool^-1 as [1, cos, sin, lam] @ basis: the drive basis taken to link 6 in the base frame."""
    b = x_c @ drive4.reshape(4, 4, 4)
    return (b if no_tool else b @ tool_inv).reshape(4, 16)


def hold_plan(prev: Segment, req: Request, t6_b: np.ndarray, q_b: np.ndarray, limits: Limits) -> Plan:
    """The plan of holding at the corner of a static segment (the repeated request of an empty queue)."""
    p = Plan()
    p.mode, p.t6_b, p.q_b, p.static = req.mode, t6_b, q_b.copy(), True
    # (holding still, a redundant arm keeps its q7: the bare configuration, without the motion's rule)
    p.t6_c, p.tool, p.tool_inv, p.config = t6_b, prev.tool, prev.tool_inv, redundancy.arm_of(prev.config)
    p.x_c = t6_b @ p.tool
    p.d, p.k, p.theta, p.dist = np.zeros(3), np.array([0.0, 0.0, 1.0]), 0.0, 0.0
    p.drive = drive_basis(p.d, p.k)
    p.basis = _t6_basis(p.x_c, p.drive, p.tool_inv, False)
    p.vt_dir = p.vr_dir = np.zeros(3)
    p.dq = np.zeros_like(q_b)
    p.q_dest = q_b.copy()
    p.t_lim = 0.0
    p.t_est = 0.0
    p.v_start_dir = p.v_end_dir = np.zeros_like(q_b)
    return p.finish(limits)


def plan_segment(kin: Kinematics, limits: Limits, dt: float, req: Request, t6_b: np.ndarray,
                 q_b: np.ndarray, t0: float, tau_in: float | None, v1: np.ndarray | None = None,
                 v1_cart: tuple[np.ndarray, np.ndarray] | None = None,
                 check_points: int = MAX_CHECK_POINTS) -> Segment:
    """Plan ``req`` from the corner (T6 ``t6_b``, joints ``q_b``); raise an RCCL MotionError if it cannot run.

    The path comes from ``req.profile`` (the ``Plan`` that ``move()`` checked) when it still
    fits this corner and destination, else from ``plan_path`` (``check_points`` points).
    ``v1`` (rad/s) and ``v1_cart`` ((m/s, rad/s) in the base frame) are the velocities the
    previous segment ends with; the new segment is slowed if needed so the transition of
    half-width ``tau_in`` stays within the acceleration limits. ``tau_in=None`` means the
    arm starts from rest: the transition is then made long enough to reach the new speed
    within the acceleration limits (read it back from ``seg.tau_in``); ``t0`` is then the
    transition's start and ``seg.t0`` is set to ``t0 + seg.tau_in``.
    """
    plan = req.profile
    if not (isinstance(plan, Plan) and plan.fits(req, t6_b, q_b)):
        plan = req.profile = plan_path(kin, limits, dt, req, t6_b, q_b, check_points)
    return time_segment(kin, limits, dt, req, plan, t0, tau_in, v1, v1_cart)


def time_segment(kin: Kinematics, limits: Limits, dt: float, req: Request, plan: Plan, t0: float,
                 tau_in: float | None, v1: np.ndarray | None = None,
                 v1_cart: tuple[np.ndarray, np.ndarray] | None = None) -> Segment:
    """The segment of ``plan`` in time: travel time, transitions and speed scale within the limits.

    No kinematics and (almost) no arrays: this runs in the control cycle that starts the segment.
    """
    seg = Segment(req, kin)
    params = req.params
    seg.plan = plan
    seg.t0 = t0
    seg.tool, seg.tool_inv, seg.config = plan.tool, plan.tool_inv, plan.config
    seg.d, seg.k, seg.theta = plan.d, plan.k, plan.theta
    seg.dq, seg.q_dest = plan.dq, plan.q_dest
    seg._drive = plan.drive
    if seg.static:
        seg.x_dest = plan.t6_c
        seg._basis = plan.basis
    travel = params.travel_time
    T = plan.t_lim if travel is None or travel < plan.t_lim else travel
    tau_req = params.transition_time / 2.0
    cart = seg.mode == "cartesian"
    if tau_in is None:  # from rest: a transition long enough to reach the segment's speed
        T = max(T, 2.0 * tau_req, 2.0 * dt)
        tau_in = max(tau_req, _tau(limits, plan, plan.acc_start, cart, T))
        t0 = t0 + tau_in
        v1 = v1_cart = None
        seg.t0 = t0
    seg.tau_in = tau_in
    seg.stationary = plan.stationary
    T = max(T, tau_in + tau_req, 2.0 * dt)
    # keep the incoming transition within the acceleration limits (peak ACC_PEAK |dv| / tau);
    # seg.scale < 1 is how much the new segment had to be slowed for it (the generator stops at
    # the corner instead when that is below MIN_BLEND_SCALE, e.g. for a sharp reversal)
    seg.scale = 1.0
    if v1 is not None and tau_in > 0:
        f = tau_in / ACC_PEAK
        s = _scale_for(v1.tolist(), plan.v_start_list, T, [a * f for a in limits.joint_acceleration.tolist()])
        if v1_cart is not None and cart:
            s = min(s, _scale_norm(v1_cart[0].tolist(), plan.vt_list, T, limits.translational_acceleration * f),
                    _scale_norm(v1_cart[1].tolist(), plan.vr_list, T, limits.rotational_acceleration * f))
        T /= s
        seg.scale = s
    tau_out = max(tau_req, _tau(limits, plan, plan.acc_end, cart, T))
    seg.T = T = max(T, tau_in + tau_out)
    seg.tau_out = tau_out
    seg.v_end = plan.v_end_dir / T
    seg.v_cart = (plan.vt_dir / T, plan.vr_dir / T)
    return seg


def _tau(limits: Limits, plan: Plan, acc: float, cart: bool, T: float) -> float:
    """Half-width of a transition that brings the segment's velocities (its path's at speed 1/T) to rest within every limit.

    ``acc`` is max_i |v_dir_i| / a_max_i of the joint velocities times T at that end of the path.
    """
    if cart:
        acc = max(acc, plan.vt_norm / limits.translational_acceleration, plan.vr_norm / limits.rotational_acceleration)
    return ACC_PEAK * acc / T


def _fit_range(limits: Limits, q: np.ndarray, revolute: np.ndarray | None = None) -> np.ndarray:
    """Joint-mode destinations: move a revolute joint outside its range by +-2 pi when that brings it inside.

    Inverse kinematics picks the 2 pi branch nearest the start; a joint whose range spans
    more than one side of +-pi (the PUMA waist) may need the other branch. Prismatic joints
    (``revolute`` False) are left alone.
    """
    q = q.copy()
    for i in range(q.size):
        if revolute is not None and not revolute[i]:
            continue
        for shift in (2 * math.pi, -2 * math.pi):
            if not (limits.lower[i] <= q[i] <= limits.upper[i]) and limits.lower[i] <= q[i] + shift <= limits.upper[i]:
                q[i] += shift
    return q


def check_range(limits: Limits, q: np.ndarray, where: str, what: str, units=None) -> None:
    if not np.isfinite(q).all():
        raise UnreachableTarget(f"{where}: {what}: the kinematics returned joint values that are not finite ({q})")
    i = limits.out_of_range(q)
    if i is not None:
        u = units[i] if units is not None else "rad"
        raise UnreachableTarget(f"{where}: {what} needs joint {i + 1} at {q[i]:.4f} {u}, outside its range "
                          f"[{limits.lower[i]:.4f}, {limits.upper[i]:.4f}] {u}")


# --------------------------------------------------------------------------------------
# the generator
# --------------------------------------------------------------------------------------
def holds_still(seg: Segment) -> bool:
    """Whether ``seg`` is the arm holding at a fixed point (the repetition of a static request, no motion)."""
    return seg.req.repeat and seg.stationary and seg.static
