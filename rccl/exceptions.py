"""Exceptions raised by RCCL (transforms, position equations, motion requests, the trajectory generator)."""
from __future__ import annotations


class RCCLError(Exception):
    """Base class of every error RCCL raises."""


class TransformError(RCCLError, ValueError):
    """A transform is malformed (not 4x4, not rigid, NaN) or used wrongly; the message names it."""


class ConstTransformError(TransformError):
    """A const transform was written to."""


class PositionError(RCCLError, ValueError):
    """A position equation is malformed (no T6, T6 twice, no EQ, bad tool); the message names the position."""


class MotionError(RCCLError):
    """A motion request cannot be executed as asked."""


class BadRequest(MotionError, ValueError):
    """A motion parameter is out of range (negative speed, unknown mode, bad configuration string)."""


class UnreachableTarget(MotionError):
    """A target (or a point of a Cartesian path) is outside the workspace; says which position and where."""


class SingularPath(MotionError):
    """A Cartesian path passes through (or too near) a singularity: the joints would have to jump."""


class ConfigurationChange(MotionError):
    """A Cartesian-mode move would need a different arm configuration; use joint mode and setconf()."""


class PowerOff(MotionError):
    """The arm's power is off: a move would command joints that cannot turn. ``arm.power_on()``."""


class TrajectoryFault(MotionError):
    """The trajectory generator stopped the arm at the control level; the planning level sees this."""

    def __init__(self, message: str, cause: BaseException | None = None) -> None:
        super().__init__(message)
        self.cause = cause


class NotRunning(RCCLError):
    """A motion primitive was called while RCCL is not open/controlling (rccl.open not entered)."""


class PathCollision(MotionError):
    """A motion would bring two links, or a link and an environment object, closer than the clearance margin.

    ``pair`` names the two (link or capsule names, environment objects as ``env:<word>``),
    ``distance`` is their distance there (m, negative: overlapping), ``margin`` the clearance
    asked for (m), ``fraction`` where along the motion (0 start .. 1 end; None for a per-cycle
    stop), ``time`` when (s: after the motion starts for a planned path, trajectory time for a
    per-cycle stop) and ``q`` the joint values there (rad, m).
    """

    def __init__(self, message: str, pair: tuple[str, str], distance: float, margin: float,
                 fraction: float | None, time: float | None, q) -> None:
        super().__init__(message)
        self.pair = pair
        self.distance = distance
        self.margin = margin
        self.fraction = fraction
        self.time = time
        self.q = q


class CollisionFileError(RCCLError, ValueError):
    """A collision geometry file (models/collision/<robot>.toml) is malformed; the message names the file and key."""
