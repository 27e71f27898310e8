"""The trajectory generator contract (thesis 5.2, 5.3.4): what the control cycle and the adaptive features use.

Two generators implement it: the thesis's quartic one (``rccl.trajectory.TrajectoryGenerator``)
and the jerk-limited one (``rccl.jerk.JerkLimitedGenerator``, Ruckig). The control cycle
(``rccl.session.Arm``), the planning level (``rccl.planner``), the adaptive features
(``rccl.adaptive``: functional targets, limits, monitors, compliance, stiction, conditional
motions) and the event flags (``rccl.events``) use only the members named here, never a
generator's internals, so that every feature works with either generator.

Units: time in s, joint angles in rad (m for a prismatic joint), frames 4x4 in m.
"""
from __future__ import annotations

from typing import Callable, Protocol, runtime_checkable

import numpy as np

from .conditional import choose
from .ending import MotionEnd
from .exceptions import BadRequest, MotionError, TrajectoryFault
from .limits import Limits
from .motion import Request
from .queue import MotionQueue

#: the generators ``rccl.open(trajectory=...)`` knows
KINDS = ("quartic", "ruckig")


@runtime_checkable
class MotionGenerator(Protocol):
    """One sample per call to ``step``; everything else is read or called between two steps.

    Control level (the RCI control function, once per sample, in this order):
    ``set_period`` when the robot's rate changes, ``follow_unpowered`` while the power is
    off, then ``step``. Planning level (any thread): ``queue``, ``errors``, ``faulted``,
    ``busy``, ``restart``, ``abort``. Adaptive features: ``request`` and ``tool`` (what
    runs), ``jac6``/``jac6_inv``/``jac6_cond`` (the Jacobian they measured this sample,
    which the functional-transform limiter reuses), ``abort`` and ``freeze``.
    """

    queue: MotionQueue[Request]
    q: np.ndarray                      # last commanded joint angles (rad)
    t: float                           # trajectory time of the last sample (s)
    dt: float                          # the sample period the next step advances by (s)
    limits: Limits
    samples: int
    errors: list[MotionError]          # refused requests and faults, for the planning level
    faulted: TrajectoryFault | None    # the arm is frozen at the last command while set
    ended: list[tuple[Request, MotionEnd]]   # requests ended early, with why
    before_transition: list[Callable[[], None]]
    on_transition: list[Callable[..., None]]
    jac6: np.ndarray | None
    jac6_inv: np.ndarray | None
    jac6_cond: float | None

    def step(self) -> np.ndarray:
        """Advance one sample period (``dt``) and return the joint angles to command (rad, (6,))."""
        ...

    def set_period(self, dt: float, limits: Limits) -> None:
        """From the next ``step`` on, samples are ``dt`` s apart and ``limits`` hold (the joint
        speeds less what encoder rounding adds at the new rate); the running motion keeps its
        speeds in real time (its timing is in seconds, not samples)."""
        ...

    def abort(self, end: MotionEnd) -> None:
        """End the running motion at the next ``step`` with ``end`` (any thread)."""
        ...

    def freeze(self, exc: BaseException) -> None:
        """Stop on ``exc``: hold the last command; running and queued requests fail with a TrajectoryFault."""
        ...

    def restart(self) -> None:
        """Clear a fault: hold where frozen, accept new requests."""
        ...

    def follow_unpowered(self, q: np.ndarray) -> None:
        """The power is off: end any motion (PowerOff) and make the command follow the measured ``q``."""
        ...

    @property
    def busy(self) -> bool:
        """True while a request runs or waits in the queue."""
        ...

    @property
    def request(self) -> Request | None:
        """The request whose motion is in progress now (a hold's repetition included), or None."""
        ...

    @property
    def tool(self) -> np.ndarray:
        """The tool frame seen from link 6 (4x4, m) of the motion in progress (or the last one)."""
        ...


def check_kind(kind: str) -> str:
    """``kind`` if it names a generator, else a BadRequest listing them."""
    if kind not in KINDS:
        raise BadRequest(f"rccl.open: trajectory={kind!r} is not 'quartic' (the thesis's, default) "
                         "or 'ruckig' (jerk-limited, rccl.jerk)")
    return kind


def follow_early_end(queue: MotionQueue, req: Request, end: MotionEnd) -> None:
    """After ``req`` ended early with ``end`` (trajectory level): run its matching conditional branch (5.6.1).

    The pruned tree: every request still queued is dropped (finished as not run) and the
    branch is queued alone. Nothing happens when no branch matches.
    """
    branch = choose(req.conditionals(), end)    # Request.attach_conditional: none lost at the end
    if branch is None:
        return
    for dropped in queue.clear():
        dropped.dropped_by = req
        dropped.finish(MotionError(f"{dropped.position.name}: not run, the conditional motion to "
                                   f"{branch.request.position.name} was chosen ({end})"))
    req.chosen = branch.request
    queue.put(branch.request, take_pending=False)
