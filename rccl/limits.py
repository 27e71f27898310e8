"""Velocity and acceleration limits the trajectory generator respects (joint and Cartesian).

Joint ranges and joint velocity limits come from the robot data file (``models/<robot>.toml``,
themselves tagged there as estimates). The thesis gives no acceleration limits and no
Cartesian limits; the defaults below are ``estimate``s, with their reasoning beside them.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

# estimate: a joint reaches its top speed in about a quarter of a second (small PM DC
# servos through 30-70:1 gearing, light links); so a_max = v_max / 0.25 s.
ACCEL_RAMP_S = 0.25
# estimate: the PUMA 260's tool speed is rated around 0.5-1 m/s; RCCL programs typically
# ran at 0.05-0.2 m/s. We allow 0.5 m/s and 3 rad/s (about 170 deg/s).
MAX_TRANSLATIONAL_VELOCITY = 0.5
MAX_ROTATIONAL_VELOCITY = 3.0
# estimate: 2 m/s^2 and 10 rad/s^2 keep every joint below its own acceleration limit over
# most of the workspace (the wrist joints are the fastest, the tool is 0.4 m from the shoulder).
MAX_TRANSLATIONAL_ACCELERATION = 2.0
MAX_ROTATIONAL_ACCELERATION = 10.0


@dataclass(frozen=True)
class Limits:
    """Limits in SI units: rad, rad/s, rad/s^2 per joint; m/s, rad/s, m/s^2, rad/s^2 for the tool."""

    lower: np.ndarray
    upper: np.ndarray
    joint_velocity: np.ndarray
    joint_acceleration: np.ndarray
    translational_velocity: float = MAX_TRANSLATIONAL_VELOCITY
    rotational_velocity: float = MAX_ROTATIONAL_VELOCITY
    translational_acceleration: float = MAX_TRANSLATIONAL_ACCELERATION
    rotational_acceleration: float = MAX_ROTATIONAL_ACCELERATION
    source: str = field(default="", compare=False)

    def out_of_range(self, q: np.ndarray) -> int | None:
        """Index of the first joint outside its range, or None."""
        bad = np.nonzero((q < self.lower - 1e-9) | (q > self.upper + 1e-9))[0]
        return int(bad[0]) if bad.size else None


def load_limits(robot: str) -> Limits:
    """Limits of ``robot`` from its data file (joint ranges and velocities, via models) plus the estimates above."""
    from rcci.models import load_robot

    model = load_robot(robot)
    vel = np.array(model.max_velocity, dtype=float)
    acc = vel / ACCEL_RAMP_S
    if model.max_acceleration is not None:   # a published acceleration limit (the Panda's) caps the estimate
        acc = np.minimum(acc, np.asarray(model.max_acceleration, dtype=float))
    return Limits(np.array(model.lower, dtype=float), np.array(model.upper, dtype=float), vel,
                  acc, source=str(model.path))


def for_link(limits: Limits, rounding: np.ndarray, period: float) -> Limits:
    """``limits`` with each joint's speed lowered by what encoder rounding can add to a step
    (``rounding`` rad / m per joint, rci.conversions.Conversions.rounding_step, over a
    ``period`` s): trajectories planned with them command counts that RCI's R_REQVEL check
    (the data file's ``max_velocity``) always accepts, at every sample rate."""
    slower = limits.joint_velocity - np.asarray(rounding, dtype=float) / float(period)
    if not np.all(slower > 0):
        raise ValueError(f"at {1 / period:.0f} Hz, encoder rounding ({rounding} per step) leaves no joint speed "
                         f"below the limits {limits.joint_velocity}")
    return replace(limits, joint_velocity=slower)
