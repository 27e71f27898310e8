"""Motion requests (thesis 5.2, 5.3.2): the parameters set by setvel/settime/setmod/setconf and the request packet.

``MotionParams`` holds what the planning level has set so far; ``move()`` copies it into a
``Request`` together with the destination position and a snapshot of its ``hold``
transforms, and queues it. What plugs into a request is a typed field of it: the
per-sample ``watch`` (event flags' stop), the ``eft`` it belongs to, the motion ``checks``
of 5.4 (limits, monitors), the ``conditional`` branches of 5.6.1; the trajectory level records
how it ``ended`` and when (``finished_t``).
"""
from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field, replace
from typing import Any, Callable

from .exceptions import BadRequest
from .position import Position, Snapshot

MODES = ("joint", "cartesian")
# estimate: RCCL's default transition was of the order of a few samples at 36 Hz; 0.2 s
# (7 samples at 36 Hz) keeps accelerations modest at the default speeds.
DEFAULT_TRANSITION = 0.2
# estimate: slow, safe defaults for a first program (5 cm/s, about 30 deg/s)
DEFAULT_VELOCITY = (0.05, math.radians(30.0))


def _positive(value: float, what: str) -> float:
    v = float(value)
    if not math.isfinite(v) or v <= 0:
        raise BadRequest(f"{what} must be a positive finite number, got {value!r}")
    return v


@dataclass
class MotionParams:
    """Parameters applied to the next ``move`` (thesis 5.3.2). SI: m/s, rad/s, s."""

    mode: str = "joint"
    translational_velocity: float = DEFAULT_VELOCITY[0]
    rotational_velocity: float = DEFAULT_VELOCITY[1]
    travel_time: float | None = None      # explicit travel time (settime) overrides the velocities
    transition_time: float = DEFAULT_TRANSITION
    config: Any = None                    # requested arm configuration (setconf), None = keep current
    free: Any = None                      # a redundant arm's q7 rule (setfree, rccl.redundancy), None = hold q7
    feedforward: Any = None               # rccl.feedforward.FeedForward in current mode, None = position servo

    def setvel(self, translational: float, rotational: float) -> None:
        self.translational_velocity = _positive(translational, "setvel: translational velocity (m/s)")
        self.rotational_velocity = _positive(rotational, "setvel: rotational velocity (rad/s)")
        self.travel_time = None

    def settime(self, transition: float, travel: float) -> None:
        self.transition_time = _positive(transition, "settime: transition time (s)")
        self.travel_time = _positive(travel, "settime: travel time (s)")

    def setmod(self, mode: str) -> None:
        m = {"j": "joint", "c": "cartesian"}.get(str(mode).lower(), str(mode).lower())
        if m not in MODES:
            raise BadRequest(f"setmod: mode {mode!r} is not 'joint' ('j') or 'cartesian' ('c')")
        self.mode = m


@dataclass(eq=False)
class Request:
    """One motion request packet (thesis 5.2): where, how, how fast; plus its completion status."""

    position: Position
    snap: Snapshot
    params: MotionParams
    serial: int = 0
    repeat: bool = False          # an internal repetition of the last request (the arm holds)
    # -- how it ends (set by the trajectory level) -----------------------------------------
    ended: Any = None             # rccl.ending.MotionEnd: why it ended early (None: it completed)
    finished_t: float | None = None   # trajectory time its outgoing transition ended (s)
    # -- what plugs into it (typed: the trajectory level, rccl.events and rccl.adaptive) ---
    watch: Callable[[], Any] | None = None   # called once per sample while it runs; a MotionEnd ends it
    eft: Any = None               # the event flag triple it belongs to (rccl.events)
    checks: list = field(default_factory=list)   # rccl.adaptive.check.MotionCheck: limits (5.4.1), monitors (5.4.2), ...
    conditional: list = field(default_factory=list)   # rccl.conditional.Conditional branches (5.6.1)
    is_conditional: bool = False  # it is itself a conditional branch (the tree stays pruned)
    chosen: "Request | None" = None        # the branch that followed it, when one did
    dropped_by: "Request | None" = None    # the request whose branch dropped it from the queue
    has_functional: bool | None = None     # cache: does its equation hold a functional transform
    status: str = "queued"        # queued -> running -> done | failed
    error: BaseException | None = None
    profile: Any = None           # the planning level's path check (corner, results), reused if still valid
    _done: threading.Event = field(default_factory=threading.Event, repr=False)
    _on_finish: list = field(default_factory=list, repr=False)
    _finish_lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    @property
    def mode(self) -> str:
        return self.params.mode

    def finish(self, error: BaseException | None = None, then: Callable[[], None] | None = None) -> None:
        """Mark complete (trajectory level); signals the position's ``end`` unless it is a repetition.

        ``then`` runs once the status is final (no branch attaches after it: attach_conditional)
        and before anyone waiting on this request or its end is woken: the trajectory level
        chooses and queues a conditional branch there, so a program woken by the end sees
        ``chosen`` already set."""
        self.status = "failed" if error is not None else "done"
        self.error = error
        if then is not None:
            then()
        if not self.repeat:
            self.position.end.signal()
        with self._finish_lock:
            self._done.set()
            callbacks, self._on_finish = self._on_finish, []
        for cb in callbacks:
            cb(self)

    def on_finish(self, callback: Callable[["Request"], None]) -> None:
        """Call ``callback(self)`` once when this request finishes (done or failed), from the
        thread that finishes it; at once, here, if it already has."""
        with self._finish_lock:
            if not self._done.is_set():
                self._on_finish.append(callback)
                return
        callback(self)

    def attach_conditional(self, branch, on_attach: Callable[[], None] | None = None) -> bool:
        """Add a conditional branch (5.6.1) unless this motion has ended; False (nothing added) if it has.

        Atomic with :meth:`conditionals` once the motion has ended: a branch is either seen by
        the trajectory level that ended it or refused here, never lost in between.
        ``on_attach`` runs under the same lock just before the branch is added.
        """
        with self._finish_lock:
            if self.status not in ("queued", "running"):
                return False
            if on_attach is not None:
                on_attach()
            self.conditional.append(branch)
            return True

    def conditionals(self) -> list:
        """The conditional branches attached so far (a copy; see :meth:`attach_conditional`)."""
        with self._finish_lock:
            return list(self.conditional)

    def wait(self, timeout: float | None = None) -> bool:
        """Block until this request completes; True if it did."""
        return self._done.wait(timeout)

    def repeated(self) -> "Request":
        """The repetition the generator runs when the queue is empty: same position, held (5.2)."""
        return Request(self.position, self.snap, replace(self.params, travel_time=None, config=None, free=None),
                       self.serial, repeat=True, status="running")
