"""Exceptions of RCCL's adaptive path control (limits, monitors, compliance, functional transforms)."""
from __future__ import annotations

from ..exceptions import BadRequest, MotionError, RCCLError


class AdaptiveError(RCCLError):
    """Base class of the errors raised by ``rccl.adaptive``."""


class SpecError(AdaptiveError, BadRequest):
    """A limit/comply/lock specification string or its values are malformed; the message says which token."""


class MonitorError(AdaptiveError, MotionError):
    """A user monitor function (evalfn) raised or returned something that is not a termination code."""


class ForceEstimateError(AdaptiveError, MotionError):
    """Cartesian forces cannot be estimated here: the Jacobian is singular or too badly conditioned (4.57)."""


class FunctionalError(AdaptiveError, MotionError):
    """A functionally defined transform produced a non-rigid or non-finite value, or drove the arm to a singularity."""
