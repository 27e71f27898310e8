"""Redundancy in RCCL: the rules that choose a 7-joint arm's free parameter q7, and self-motion.

A 6-joint arm's Cartesian pose and configuration (``setconf``, thesis 5.3.2) fix its joints;
a 7-joint arm (the Panda) keeps one free parameter, its last joint q7 (rad): the generated
inverse kinematics solves the other six joints for a pose, a configuration and a given q7
(``ik(T, config, q_ref, q7=...)``). The thesis leaves "truly redundant manipulators" open
(6.4); its own idea for a choice the pose leaves open is an explicit setting, as setconf is
for the 6-joint configurations. ``setfree`` gives a rule for the next moves:

- :class:`Hold` -- q7 stays at a value (rad), or at the value the arm has when the motion
  starts (``Hold()``, the default of a redundant arm without a rule);
- :class:`FollowTime` -- q7 = f(t), t in seconds from the motion's start;
- :class:`FarFromLimits` -- each sample, q7 is chosen within ``step`` rad of the previous
  sample's value to minimise a cost of the distance to the joint limits and the nearness of
  a singularity (:func:`cost`), so it changes continuously.

:class:`SelfMotion` (``selfmove``) moves q7 along a minimum-jerk ramp while the tool's pose
stays fixed: the other joints follow through the inverse kinematics (the elbow swings).

The rule travels with the arm configuration of a request: :func:`bind` makes a
:class:`Binding` (arm configuration + rule), which compares equal to its arm configuration,
so the trajectory generators' calls ``kin.ik(T6, config, q_ref, where)`` reach
:func:`solve` unchanged, whichever generator runs (rccl.segments.Kinematics).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from .exceptions import BadRequest, SingularPath, UnreachableTarget

#: the free joint of a redundant arm (0-based): the Panda's q7
FREE_JOINT = 6
#: default largest change of q7 per inverse kinematics call for the optimising rule (rad);
#: estimate: 0.02 rad per sample is 0.72 rad/s at 36 Hz, under a third of the Panda's joint-7
#: speed limit (2.61 rad/s), so the rule never asks for a step the step check refuses
FAR_STEP = 0.02
#: candidates tried per call by the optimising rule (odd: the previous value is one of them)
FAR_CANDIDATES = 5
#: the smallest singular value of the 6x7 Jacobian (m or rad per rad) at which the singularity
#: term equals the joint-limit term's scale; estimate: a tenth of the Panda's reach-scale
#: singular values (0.1-0.5 in its ready pose)
SIGMA_REF = 0.05
#: a self-motion passing a pose whose 6x7 Jacobian has a smallest singular value under this is
#: refused as singular (estimate: 1/50 of SIGMA_REF; at that value one task direction needs
#: joint speeds 500x larger than the tool's)
SIGMA_SINGULAR = 1e-3
#: how far (rad) a rule's q7 at a Cartesian motion's start may be from the arm's: a jump this
#: small is one step of 0.036 rad/s at 36 Hz (the step check slows it), and it covers where a
#: ramp's last sample falls when the generator ends the motion one sample early
JUMP_TOL = 1e-3
#: samples a self-motion's motion lasts beyond its ramp (see Planner.selfmove)
SELF_PAD = 4
#: points at which a self-motion is checked before it starts
SELF_CHECK_POINTS = 200


# --------------------------------------------------------------------------------------
# the cost of the optimising rule
# --------------------------------------------------------------------------------------
def limit_cost(q: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> float:
    """Mean over the joints of ((2 q - lo - hi) / (hi - lo))^2: 0 with every joint mid-range,
    1 with every joint on a limit (dimensionless)."""
    x = (2.0 * q - lower - upper) / (upper - lower)
    return float(np.mean(x * x))


def sigma_min(jacobian: np.ndarray) -> float:
    """The smallest singular value of a 6xn Jacobian (mixed m/rad per rad): 0 at a singularity."""
    return float(np.linalg.svd(jacobian, compute_uv=False)[-1])


def cost(q: np.ndarray, jacobian: np.ndarray, lower: np.ndarray, upper: np.ndarray,
         sigma_ref: float = SIGMA_REF, weight: float = 1.0) -> float:
    """The optimising rule's cost of joints ``q`` (rad): ``limit_cost`` + weight (sigma_ref /
    sigma_min)^2, the second term growing without bound towards a singularity."""
    s = max(sigma_min(jacobian), 1e-12)
    return limit_cost(q, lower, upper) + weight * (sigma_ref / s) ** 2


def min_jerk(s: float) -> float:
    """The minimum-jerk ramp 10 s^3 - 15 s^4 + 6 s^5 on s in [0, 1] (clamped): 0 -> 1, its first
    and second derivatives 0 at both ends; the peak slope is 1.875."""
    s = 0.0 if s < 0.0 else (1.0 if s > 1.0 else s)
    return s * s * s * (10.0 + s * (-15.0 + 6.0 * s))


# --------------------------------------------------------------------------------------
# the rules
# --------------------------------------------------------------------------------------
class FreeRule:
    """A rule for the free parameter q7 (rad). ``solve`` returns the arm's joints (rad, (7,))
    for the link-7 pose ``t6`` (4x4, base frame, m) in ``config``, near ``q_ref``, at ``t``
    seconds from the motion's start, where q7 was ``q7_0``."""

    def q7_at(self, q7_0: float, t: float) -> float:
        raise NotImplementedError(f"{type(self).__name__} chooses q7 in solve()")

    def solve(self, module, t6: np.ndarray, config, q_ref: np.ndarray, t: float, q7_0: float) -> np.ndarray:
        return module.ik(t6, config, q_ref, q7=self.q7_at(q7_0, t))

    def start_value(self, q_start: np.ndarray) -> float | None:
        """q7 (rad) the rule asks for at the motion's start, or None when it starts from the arm's."""
        return None


@dataclass(frozen=True)
class Hold(FreeRule):
    """q7 held at ``value`` (rad); ``None``: at the value the arm has when the motion starts
    (each sample keeps the previous sample's q7), the default of a redundant arm."""

    value: float | None = None

    def q7_at(self, q7_0: float, t: float) -> float:
        return q7_0 if self.value is None else self.value

    def start_value(self, q_start: np.ndarray) -> float | None:
        return self.value

    def __str__(self) -> str:
        return "q7 held" if self.value is None else f"q7 held at {self.value:.4f} rad"


@dataclass(frozen=True)
class FollowTime(FreeRule):
    """q7 = fn(t) (rad), t in seconds from the motion's start (its first commanded sample)."""

    fn: Callable[[float], float]

    def q7_at(self, q7_0: float, t: float) -> float:
        try:
            v = float(self.fn(t))
        except (TypeError, ValueError) as exc:
            raise BadRequest(f"setfree(q7=f): f({t:.4f} s) did not give a number of radians: {exc}") from None
        if not math.isfinite(v):
            raise BadRequest(f"setfree(q7=f): f({t:.4f} s) = {v!r} is not a finite number of radians")
        return v

    def start_value(self, q_start: np.ndarray) -> float | None:
        return self.q7_at(float(q_start[FREE_JOINT]), 0.0)

    def __str__(self) -> str:
        return f"q7 following {getattr(self.fn, '__name__', 'a function')}(t)"


@dataclass(frozen=True)
class SelfMotion(FreeRule):
    """Self-motion: q7 from where the arm has it at the motion's start to ``target`` (rad)
    along :func:`min_jerk` over ``duration`` seconds, the tool's pose fixed."""

    target: float
    duration: float

    def q7_at(self, q7_0: float, t: float) -> float:
        return q7_0 + (self.target - q7_0) * min_jerk(t / self.duration)

    def __str__(self) -> str:
        return f"self-motion of q7 to {self.target:.4f} rad in {self.duration:g} s"


@dataclass(frozen=True)
class FarFromLimits(FreeRule):
    """Each call, q7 is the candidate within ``step`` rad of ``q_ref``'s q7 (``candidates``
    evenly spaced values, the previous one among them) whose joints have the least
    :func:`cost`; joint ranges ``lower``/``upper`` (rad). A candidate with no solution, or
    with a joint outside its range, is skipped; with none left the previous q7 is solved
    (its error, or its joints for the range check to name)."""

    lower: np.ndarray
    upper: np.ndarray
    step: float = FAR_STEP
    candidates: int = FAR_CANDIDATES
    sigma_ref: float = SIGMA_REF
    weight: float = 1.0

    def solve(self, module, t6: np.ndarray, config, q_ref: np.ndarray, t: float, q7_0: float) -> np.ndarray:
        q7 = float(q_ref[FREE_JOINT])
        half = self.candidates // 2
        best, best_cost = None, math.inf
        for k in range(-half, half + 1):
            v = q7 + self.step * k / half
            if not self.lower[FREE_JOINT] <= v <= self.upper[FREE_JOINT]:
                continue
            try:
                q = module.ik(t6, config, q_ref, q7=v)
            except ValueError:
                continue
            if not np.all((q >= self.lower) & (q <= self.upper)):
                continue
            c = cost(q, module.jacobian6(q), self.lower, self.upper, self.sigma_ref, self.weight)
            if c < best_cost:
                best, best_cost = q, c
        if best is None:
            return module.ik(t6, config, q_ref, q7=q7)   # raises the kinematics' own error
        return best

    def __str__(self) -> str:
        return f"q7 far from limits and singularities (step {self.step:g} rad)"


#: the rule of a redundant arm when the program set none
DEFAULT = Hold()


def rule_of(spec: Any = None, *, q7: Any = None, lower: np.ndarray, upper: np.ndarray,
            step: float = FAR_STEP) -> FreeRule:
    """The rule ``setfree`` asks for: ``q7=value`` (rad, held), ``q7=f`` (f(t), t s from the
    motion's start), ``"far"`` (the optimising rule within ``lower``/``upper``, ``step`` rad
    per sample), ``"hold"`` or nothing (hold the q7 the arm has), or a FreeRule."""
    if isinstance(spec, FreeRule) and q7 is None:
        return spec
    if spec is not None and q7 is not None:
        raise BadRequest(f"setfree({spec!r}, q7={q7!r}): give either a rule name or q7=, not both")
    if q7 is not None:
        if callable(q7):
            return FollowTime(q7)
        try:
            v = float(q7)
        except (TypeError, ValueError):
            raise BadRequest(f"setfree(q7={q7!r}): q7 must be a number (rad) or a function of t (s)") from None
        if not lower[FREE_JOINT] <= v <= upper[FREE_JOINT]:
            raise BadRequest(f"setfree(q7={v:.4f}): outside joint 7's range [{lower[FREE_JOINT]:.4f}, "
                             f"{upper[FREE_JOINT]:.4f}] rad")
        return Hold(v)
    if spec is None or spec == "hold":
        return DEFAULT
    if spec == "far":
        if not (isinstance(step, (int, float)) and 0.0 < step < 0.5):
            raise BadRequest(f"setfree('far', step={step!r}): step must be a number of radians in (0, 0.5)")
        return FarFromLimits(np.asarray(lower, dtype=float), np.asarray(upper, dtype=float), float(step))
    raise BadRequest(f"setfree({spec!r}): not a rule: use q7=value (rad), q7=f (a function of t in s), "
                     "'far' (far from joint limits and singularities) or 'hold'")


# --------------------------------------------------------------------------------------
# the rule bound to one request's configuration, and the solve the generators reach
# --------------------------------------------------------------------------------------
class Binding:
    """A redundant arm's configuration for one request: the arm configuration (``arm``) and the
    free parameter's ``rule``. Equal to its arm configuration (the configuration checks of
    the planning level are unchanged). ``t0`` is the generator's time (s) of the first
    sample solved with it and ``q7_0`` the q7 (rad) its motion starts from (the corner it was
    planned from, or where the arm is: :func:`anchor`); ``frozen`` a q7 (rad) held from the
    end of its segment on."""

    __slots__ = ("arm", "rule", "t0", "q7_0", "frozen")

    def __init__(self, arm, rule: FreeRule, q7_0: float) -> None:
        self.arm = arm
        self.rule = rule
        self.t0: float | None = None
        self.q7_0 = q7_0
        self.frozen: float | None = None

    def __eq__(self, other) -> bool:
        return self.arm == (other.arm if isinstance(other, Binding) else other)

    def __hash__(self) -> int:
        return hash(self.arm)

    def __str__(self) -> str:
        return f"{self.arm} ({self.rule})"

    __repr__ = __str__


def arm_of(config):
    """The arm configuration of ``config`` (a Binding's, or ``config`` itself)."""
    return config.arm if isinstance(config, Binding) else config


def bind(config, rule: FreeRule | None, q_start: np.ndarray, where: str, cartesian: bool = True) -> Binding:
    """``config`` with ``rule`` (None: :data:`DEFAULT`) for a request starting at joints
    ``q_start`` (rad); in Cartesian mode (``cartesian``) refuses a rule that asks for another
    q7 than the arm's at the start (a jump; a joint-mode move gets there along its line)."""
    arm = arm_of(config)
    rule = DEFAULT if rule is None else rule
    want = rule.start_value(q_start) if cartesian else None
    have = float(q_start[FREE_JOINT])
    if want is not None and abs(want - have) > JUMP_TOL:
        raise BadRequest(f"{where}: the rule ({rule}) starts q7 at {want:.4f} rad but the arm's q7 is {have:.4f} "
                         "rad there; in Cartesian mode q7 cannot jump: selfmove(q7=...) first, or a q7 "
                         "function that starts where the arm is")
    return Binding(arm, rule, have)


def bind_for(kin, config, params, q_start: np.ndarray, where: str, cartesian: bool):
    """``config`` for a request with motion parameters ``params`` (rccl.motion.MotionParams):
    bound to their free parameter's rule (setfree) on a redundant arm, unchanged on another."""
    if not getattr(kin, "redundant", False):
        return config
    return bind(config, params.free, q_start, where, cartesian)


def solve(kin, t6: np.ndarray, config, q_ref: np.ndarray, t: float | None = None) -> np.ndarray:
    """The joints (rad, (7,)) of a redundant arm for T6 ``t6`` in ``config`` (a Binding, or a
    bare arm configuration: the default rule) near ``q_ref``; ``t`` (s from the motion's
    start) given by the planning level, else read from the generator's clock ``kin.clock``."""
    if q_ref is None:
        raise BadRequest(f"{kin.name}: a redundant arm's inverse kinematics needs the previous joints (q_ref)")
    if not isinstance(config, Binding):
        return kin.module.ik(t6, config, q_ref, q7=float(q_ref[FREE_JOINT]))   # the default: hold q7
    if config.frozen is not None:
        return kin.module.ik(t6, config.arm, q_ref, q7=config.frozen)
    if t is None:
        if kin.clock is None:
            raise BadRequest(f"{kin.name}: no trajectory generator clock for the free parameter's rule")
        now = kin.clock()
        if config.t0 is None:         # the motion's first sample: its clock starts here
            config.t0 = now
        t = now - config.t0
    return config.rule.solve(kin.module, t6, config.arm, q_ref, t, config.q7_0)


def anchor(config, q: np.ndarray) -> None:
    """The motion of ``config`` (a Binding) starts at the joints ``q`` (rad), not at the corner
    the planning level predicted: its rule's q7_0 is ``q``'s (Ruckig starts each move where
    the arm is; the quartic starts a segment at its planned corner, re-planned if it moved)."""
    if isinstance(config, Binding):
        config.q7_0 = float(q[FREE_JOINT])


def freeze(config, q: np.ndarray) -> None:
    """From now on ``config`` (a Binding) holds q7 at ``q``'s (rad): its segment has ended."""
    if isinstance(config, Binding):
        config.frozen = float(q[FREE_JOINT])


# --------------------------------------------------------------------------------------
# self-motion: the check before it starts
# --------------------------------------------------------------------------------------
def check_target(q7: Any, duration: Any, limits) -> tuple[float, float]:
    """``selfmove``'s arguments as floats: q7 (rad) within joint 7's range, duration (s) > 0."""
    try:
        v, d = float(q7), float(duration)
    except (TypeError, ValueError):
        raise BadRequest(f"selfmove(q7={q7!r}, duration={duration!r}): q7 (rad) and duration (s) must be numbers") from None
    if not (math.isfinite(d) and d > 0.0):
        raise BadRequest(f"selfmove: duration={duration!r} must be a positive number of seconds")
    lo, hi = float(limits.lower[FREE_JOINT]), float(limits.upper[FREE_JOINT])
    if not (math.isfinite(v) and lo <= v <= hi):
        raise BadRequest(f"selfmove(q7={q7!r}): outside joint 7's range [{lo:.4f}, {hi:.4f}] rad")
    return v, d


def check_selfmotion(kin, limits, t6: np.ndarray, q_start: np.ndarray, rule: SelfMotion,
                     where: str, points: int = SELF_CHECK_POINTS) -> np.ndarray:
    """The joints (rad, (points + 1, 7)) of ``rule``'s self-motion at the fixed T6 ``t6``, each
    solved from the one before in the arm's configuration at ``q_start``; raises
    UnreachableTarget (no solution, or a joint outside its range) or SingularPath (a
    Jacobian's smallest singular value under SIGMA_SINGULAR, or a joint needing more than
    its speed limit over the duration), naming q7 and how far along the self-motion."""
    config = kin.config_of(q_start)
    path = np.empty((points + 1, q_start.size))
    path[0] = prev = q_start
    jac = kin.module.jacobian6
    for j in range(1, points + 1):
        t = rule.duration * j / points
        q7 = rule.q7_at(float(q_start[FREE_JOINT]), t)
        at = f"{where} at q7 = {q7:.4f} rad ({100 * j / points:.0f}% of the self-motion)"
        try:
            prev = path[j] = kin.module.ik(t6, config, prev, q7=q7)
        except ValueError as exc:
            cls = SingularPath if "singular" in type(exc).__name__.lower() else UnreachableTarget
            raise cls(f"{at}: no joint solution in configuration {config}: {exc}") from exc
        bad = limits.out_of_range(prev)
        if bad is not None:
            raise UnreachableTarget(f"{at}: joint {bad + 1} would be at {prev[bad]:.4f} rad, outside its range "
                                    f"[{limits.lower[bad]:.4f}, {limits.upper[bad]:.4f}] rad")
        s = sigma_min(jac(prev))
        if s < SIGMA_SINGULAR:
            raise SingularPath(f"{at}: the arm passes a singularity (smallest singular value of the Jacobian "
                               f"{s:.2g} < {SIGMA_SINGULAR:g})")
    speed = np.abs(np.diff(path, axis=0)).max(axis=0) * points / rule.duration
    ratio = speed / limits.joint_velocity
    i = int(np.argmax(ratio))
    if ratio[i] > 1.0:
        raise BadRequest(f"{where}: joint {i + 1} would need {speed[i]:.3f} rad/s (limit "
                           f"{limits.joint_velocity[i]:.3f}) at this duration; take at least "
                           f"{rule.duration * ratio[i]:.2f} s, or a smaller change of q7")
    return path
