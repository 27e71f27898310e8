"""What an adaptive feature that may end a motion implements (thesis 5.4): the ``MotionCheck`` protocol.

A motion check belongs to one motion request (``Request.checks``). The adaptive control
level (``rccl.adaptive.control``) calls its ``ends(sample)`` once per sample while that
motion runs, with a ``Sample`` holding the estimates the check named in ``estimates``, and
ends the motion (the generator's ``abort``) with the ``MotionEnd`` it returns. The thesis
defines two: 5.4.1's force/deviation ``Limit`` and 5.4.2's ``Monitor`` function. A new one
is a class in a module of its own with these two members, attached to the next motion with
``AdaptiveArm.add_check(obj)``; nothing else changes.
"""
from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

from ..ending import MotionEnd
from .exceptions import SpecError


class Estimate(enum.Flag):
    """The estimates a check may ask for (combine with ``|``): net joint torques (4.37), the
    tool-frame force/torque (4.56, needs the torques and J^-1), the tool-frame path deviation (E.2)."""

    NONE = 0
    TORQUE = enum.auto()
    FORCE = enum.auto()
    DEVIATION = enum.auto()


#: the names of the estimates (the words of Monitor's ``needs``)
ESTIMATES = frozenset({"torque", "force", "deviation"})


def estimate_named(name: str, where: str) -> Estimate:
    """The Estimate of one of ``ESTIMATES``' names, else a SpecError naming ``where``."""
    if name not in ESTIMATES:
        raise SpecError(f"{where}: {name!r} is not an estimate ({', '.join(sorted(ESTIMATES))})")
    return Estimate[name.upper()]


@dataclass
class Sample:
    """What a check sees each sample (SI; tool-frame quantities in the motion's tool frame).

    ``torque``, ``force`` and ``deviation`` are None unless a check of this motion asked for
    them (or a compliance computes them anyway).
    """

    t: float                     # trajectory time (s)
    sample: int                  # generator sample count
    q: np.ndarray                # measured joint angles (rad)
    qd: np.ndarray               # measured joint velocities (rad/s)
    q_command: np.ndarray        # last commanded (nominal) joint angles (rad)
    torque: np.ndarray | None    # net joint torques t_a (4.37), N*m
    force: np.ndarray | None     # tool-frame force/torque (N, N*m)
    deviation: np.ndarray | None  # tool-frame deviation (m, rad)
    how: Any = None              # the raw RCI how record


@runtime_checkable
class MotionCheck(Protocol):
    """An adaptive feature watching one motion: what it needs measured, and whether the motion ends now."""

    @property
    def estimates(self) -> Estimate:
        """Which estimates the control level must compute for ``ends`` (an ``Estimate`` flag)."""
        ...

    def ends(self, s: Sample) -> MotionEnd | None:
        """This sample's verdict: a MotionEnd to end the motion now, None to let it go on.

        Runs at the control level: quick, no blocking. An error it raises stops the arm.
        """
        ...


def as_check(obj: Any, where: str) -> MotionCheck:
    """``obj`` if it is a usable motion check, else a SpecError naming ``where`` and what is wrong."""
    if not isinstance(obj, MotionCheck) or not callable(getattr(obj, "ends", None)):
        raise SpecError(f"{where}: {obj!r} is not a motion check (it needs an 'estimates' set and an 'ends(sample)' method)")
    if not isinstance(obj.estimates, Estimate):
        raise SpecError(f"{where}: {type(obj).__name__}.estimates is {obj.estimates!r}, not an "
                        "rccl.adaptive.check.Estimate (e.g. Estimate.FORCE | Estimate.DEVIATION, or Estimate.NONE)")
    return obj


def estimates_of(checks: list[MotionCheck]) -> Estimate:
    """Every estimate the checks of one motion need."""
    out = Estimate.NONE
    for c in checks:
        out |= c.estimates
    return out
