"""Event flag triples (thesis 5.6.3): start, stop and status flags that synchronise the motions of one or several arms.

An ``EFT`` belongs to one motion request (``eft = move_ev(arm, position)``):

* **start** (set by ``start_ev``, by default when the move is issued): the motion may not
  begin until it holds a start code; the trajectory level then starts it as soon as it is
  ready and copies the start code into **status** (rule 1).
* **stop** (set by ``stop_ev``): halts the motion and initiates the next queued one; the
  trajectory level sets it to ``DONE`` when the motion ends naturally. After the end the
  stop code is copied into **status** (rule 2). Set before the start flag, it deletes the
  motion from the queue without moving (rule 3).
* Start codes are positive, stop codes negative, ``NULL`` (0) is reserved and nobody may
  set it (rules 4, 5): ``status_ev(eft) > 0`` means running, ``< 0`` ended.

Across arms, ``move_ev(arm_b, q, start=eft_a)`` makes B's motion wait for A's: the trajectory
level that ends A's motion sets B's start flag in the same sample, with no round trip
through the planning level; B's generator, holding at rest, looks at its queue every
sample and starts the motion at its next sample. ``start_ev(code, e1, e2)`` sets several
flags at once (each arm's generator sees them at its next sample), so motions of different
arms start (or, with ``stop_ev``, stop) together. Conditional motions (5.6.1, arms from
``rccl.adaptive.open``) inherit the EFT of the nominal motion they replace.

Works on arms from ``rccl.open`` and ``rccl.adaptive.open``: the stop flag is the request's
per-sample watch (``watch``), which the trajectory generator calls once per sample
and which ends the motion through the generator's early exit (``abort``), as a limit or a
monitor does on an adaptive arm. Misuse is refused at once: an object that is not a live EFT
(``UnknownEvent``), a wait or a chain of start conditions that can never be satisfied
(``Deadlock``, naming the motions in the cycle), bad codes.

Across processes and hosts (each arm served by its own process, the planning level in
another), ``rccl.bus.planning`` offers the same primitives over the Zenoh bus; the arm's
process learns of each flag change through ``add_listener`` and publishes it.

Thesis -> Python: ``move_ev(robot, position, params)`` -> ``move_ev(arm, position, start=START)``;
``start_ev(code, count, eft...)`` -> ``start_ev(code, *efts)``; ``stop_ev`` likewise;
``status_ev(eft)`` -> ``status_ev(eft)``; ``free_ev(count, eft...)`` -> ``free_ev(*efts)``;
``stop_abort(robot)`` -> ``stop_abort(arm)``; waiting on a status -> ``wait_ev(eft)``.
"""
from __future__ import annotations

import itertools
import threading
import time
from typing import Any, Callable

from .conditional import choose
from .ending import MotionEnd
from .exceptions import MotionError, RCCLError
from .motion import Request
from .queue import HOLD, TAKE, QueuePolicy
from .position import Position
from .generator import MotionGenerator

# --- codes (rule 4: start codes > 0, stop codes < 0; rule 5: NULL is reserved) ------------
NULL = 0
START = 1          # the default start code, set by move_ev unless postponed
DONE = -1          # the motion ended naturally (set by the trajectory level)
FAULT = -2         # the trajectory level refused or stopped it (an error: see the request's .error)
ABORTED = -3       # stop_abort flushed it, or a conditional motion replaced it (5.6.1)
LIMIT = -4         # a force or deviation limit ended it (5.4.1; request.ended says which)
MONITOR = -5       # a monitor function ended it (5.4.2; its code is in request.ended)
_RESERVED_NAMES = {NULL: "NULL", START: "START", DONE: "DONE", FAULT: "FAULT", ABORTED: "ABORTED",
                   LIMIT: "LIMIT", MONITOR: "MONITOR"}


class EventError(RCCLError):
    """Misuse of the event flag triples (bad code, an arm that cannot take them, freeing a live one)."""


class UnknownEvent(EventError):
    """The object is not a live event flag triple (never one, or freed by ``free_ev``)."""


class Deadlock(EventError):
    """A wait or a start condition that can never be satisfied; the message names the motions involved."""


def code_name(code: int) -> str:
    return _RESERVED_NAMES.get(code, str(code))


class EFT:
    """An event flag triple bound to one motion request. Read ``start``, ``stop``, ``status``, ``state``."""

    def __init__(self, serial: int, arm: str, request: Request) -> None:
        self.serial = serial
        self.arm = arm
        self.request = request
        self._start = NULL
        self._stop = NULL
        self._status = NULL
        self.freed = False
        self.after: EFT | None = None         # start when this one ends (set by move_ev(start=eft) / start_after)
        self.after_code = START
        self._followers: list[EFT] = []
        self.t_start_set: float | None = None  # time.monotonic() when its start flag was set (s)
        self.t_started: float | None = None   # time.monotonic() when the trajectory level began it (s)
        self.t_ended: float | None = None     # ... and when it ended (s): for ordering across arms
        self.traj_started: float | None = None  # the arm's trajectory time (s) of the sample it began in
        self.traj_ended: float | None = None    # ... and ended in (comparable across arms of a lockstep Workcell)
        self.version = 0                        # counts the changes of its flags (listeners see each one)

    @property
    def start(self) -> int:
        return self._start

    @property
    def stop(self) -> int:
        return self._stop

    @property
    def status(self) -> int:
        """NULL (pending), the start code (active) or the stop code (completed). Read-only."""
        return self._status

    @property
    def state(self) -> str:
        s = self._status
        return "pending" if s == NULL else ("active" if s > 0 else "completed")

    @property
    def where(self) -> str:
        return getattr(self.request.position, "name", "?")

    def __repr__(self) -> str:
        return (f"EFT(#{self.serial} arm {self.arm!r} to {self.where}: start {code_name(self._start)}, "
                f"stop {code_name(self._stop)}, status {code_name(self._status)})")

    def describe(self) -> str:
        return f"motion #{self.serial} of arm {self.arm!r} to {self.where}"


# --- the registry (the thesis's "system" that allocates EFTs) -------------------------------
_lock = threading.RLock()
_changed = threading.Condition(_lock)
_serial = itertools.count(1)
_live: dict[int, EFT] = {}                      # id(eft) -> eft
_arms: dict[int, "_ArmEvents"] = {}             # id(arm) -> its state
_listeners: list[Callable[[EFT], None]] = []    # called (under the lock) when an EFT's flags change


def add_listener(listener: Callable[[EFT], None]) -> None:
    """Call ``listener(eft)`` each time a flag of an EFT of this process changes (the motion is
    queued, a start or stop flag is set, it begins, it ends). Called under the flags' lock, from
    the planning level or the arm's control level: it must return at once and never wait (copy
    what it needs and hand it to a thread, as ``rccl.bus.arm`` does to publish the flags)."""
    with _lock:
        _listeners.append(listener)


def remove_listener(listener: Callable[[EFT], None]) -> None:
    with _lock:
        if listener in _listeners:
            _listeners.remove(listener)


def _notify(eft: EFT) -> None:
    """``eft``'s flags changed (caller holds the lock)."""
    eft.version += 1
    for listener in tuple(_listeners):
        listener(eft)


def _check_live(eft: Any, where: str) -> EFT:
    if not isinstance(eft, EFT):
        raise UnknownEvent(f"{where}: {eft!r} is not an event flag triple (use the EFT move_ev returned)")
    if eft.freed or id(eft) not in _live:
        raise UnknownEvent(f"{where}: {eft.describe()} was freed by free_ev; its flags no longer exist")
    return eft


class _StopWatch:
    """The stop flag, looked at by the arm's trajectory generator once per sample while the motion
    runs (the request's ``watch``): a stop code ends the motion in that sample."""

    def __init__(self, eft: EFT) -> None:
        self.eft = eft

    def __call__(self, gen) -> MotionEnd | None:
        code = self.eft._stop
        if code == NULL:
            return None
        return MotionEnd("stop", "stop_ev", code=code, t=gen.t, sample=gen.samples)


class EventGate(QueuePolicy):
    """The arm's queue policy (``MotionQueue.set_policy``): the start gate of rule 1 and the
    queued-stop deletion of rule 3; it binds each EFT to the request ``move_ev`` queues.

    ``admit`` runs under the queue's lock and reads the flags without the global lock; the
    global lock is taken only in ``taken`` (outside the queue's lock), so the two are never
    nested (move_ev holds neither while it queues)."""

    def __init__(self, events: "_ArmEvents") -> None:
        self.events = events
        self.next_eft: EFT | None = None      # set by move_ev around arm.move: the request it queues gets it
        self.cleared_head: Request | None = None

    def queued(self, item: Request) -> None:
        eft = self.next_eft
        if eft is not None:
            self.next_eft = None
            eft.request = item
            _bind(eft, item)

    def admit(self, head: Request):
        eft = head.eft
        if eft is None:
            return TAKE
        if eft._stop != NULL:            # rule 3: stopped before it started: delete it
            return MotionError(f"{head.position.name}: deleted from the queue by its stop flag "
                               f"({code_name(eft._stop)}) before it started")
        if eft._start == NULL:           # rule 1: not yet: the arm holds, the queue waits
            return HOLD
        return TAKE

    def taken(self, item: Request) -> None:
        eft = item.eft
        if eft is not None:
            with _lock:
                eft._status = eft._start     # the motion begins: start code -> status
                eft.t_started = time.monotonic()
                eft.traj_started = self.events.arm.gen.t
                _notify(eft)
                _changed.notify_all()

    def cleared(self, items: list) -> None:
        self.cleared_head = items[0] if items else None


EventQueue = EventGate    # the name this policy had when it was a queue subclass


def _bind(eft: EFT, req: Request) -> None:
    """Attach ``eft`` to ``req``: the stop watch, the completion callback."""
    req.eft = eft
    req.watch = _StopWatch(eft)
    req.on_finish(lambda r: _finished(eft, r))


class _ArmEvents:
    """What the event flags keep per arm: its name, its queue, its EFTs in queue order."""

    def __init__(self, arm, name: str) -> None:
        gen = getattr(arm, "gen", None)
        if not isinstance(gen, MotionGenerator):
            raise EventError(f"arm {name!r}: event flag triples need an arm whose RCCL control is running "
                             "(from rccl.open or rccl.adaptive.open, inside its with block)")
        self.arm = arm
        self.name = name
        self.efts: list[EFT] = []
        self.gate = EventGate(self)
        gen.queue.set_policy(self.gate)


def attach(arm, name: str | None = None) -> str:
    """Prepare ``arm`` (from ``rccl.open`` or ``rccl.adaptive.open``) for event flag triples; returns its name.

    Called by ``move_ev`` on first use (name = the robot's name, made unique); call it
    yourself to choose the name used in messages.
    """
    with _lock:
        ae = _arms.get(id(arm))
        if ae is not None:
            if name is not None and name != ae.name:
                raise EventError(f"attach: this arm is already attached as {ae.name!r}")
            return ae.name
        base = name or getattr(arm, "robot", "arm")
        taken = {a.name for a in _arms.values()}
        if name is not None and name in taken:
            raise EventError(f"attach: another arm is already named {name!r}")
        final = base
        for i in itertools.count(2):
            if final not in taken:
                break
            final = f"{base}#{i}"
        _arms[id(arm)] = _ArmEvents(arm, final)
        return final


def detach(arm) -> None:
    """Forget an arm (after it is closed)."""
    with _lock:
        ae = _arms.pop(id(arm), None)
        if ae is not None:
            for e in ae.efts:
                _live.pop(id(e), None)


def _events_of(arm) -> _ArmEvents:
    attach(arm)
    return _arms[id(arm)]


# --- the primitives -----------------------------------------------------------------------
def move_ev(arm, position: Position, *, start: int | EFT | None = START, after_code: int = START) -> EFT:
    """``move`` with an event flag triple: queue a motion of ``arm`` to ``position``; return its EFT.

    ``start``: a start code (default ``START``: the motion may begin when ready), None to
    postpone it (``start_ev`` later), or another EFT: begin when that motion ends (its
    stop code, unless it was FAULT or ABORTED), with start code ``after_code``. The motion
    parameters are the arm's current ones (setvel, setmod, ...), as for ``move``.
    """
    ae = _events_of(arm)
    source = None
    if isinstance(start, EFT):
        source = _check_live(start, "move_ev(start=...)")
        check_start_code(after_code, "move_ev(after_code=...)")
    elif start is not None:
        check_start_code(start, "move_ev(start=...)")
    q = ae.gate
    eft = EFT(next(_serial), ae.name, None)         # its request is bound in EventGate.queued
    if source is not None:
        eft.after, eft.after_code = source, after_code
    elif start is not None:
        eft._start = int(start)
        eft.t_start_set = time.monotonic()
    # not under the global lock: move() checks the path (milliseconds) and the arm's trajectory
    # level takes that lock when a motion ends
    q.next_eft = eft
    try:
        arm.move(position)
    finally:
        q.next_eft = None
    if eft.request is None:                         # pragma: no cover - move() always queues or raises
        raise EventError("move_ev: the motion was not queued")
    with _lock:
        _live[id(eft)] = eft
        ae.efts.append(eft)
        if source is not None:
            source._followers.append(eft)
            if source._status < 0:                  # it already ended: decide now
                _fire(source, eft)
        _notify(eft)
        _changed.notify_all()
    return eft


def start_after(target: EFT, source: EFT, code: int = START) -> None:
    """Make ``target``'s motion start when ``source``'s ends (its start flag must not be set yet).

    Raises ``Deadlock`` if ``source`` already (through its own start condition or the motions
    queued before it on its arm) waits for ``target``.
    """
    with _lock:
        target = _check_live(target, "start_after(target)")
        source = _check_live(source, "start_after(source)")
        check_start_code(code, "start_after(code)")
        if target._start != NULL or target.after is not None:
            raise EventError(f"start_after: {target.describe()} already has a start condition "
                             f"(start {code_name(target._start)})")
        path = _waits_for(source, target)
        if path is not None:
            chain = " -> ".join(e.describe() for e in [target] + path)
            raise Deadlock(f"start_after: {chain}: the motions would wait for each other forever")
        target.after, target.after_code = source, code
        source._followers.append(target)
        if source._status < 0:
            _fire(source, target)
        _changed.notify_all()


def start_ev(code: int, *efts: EFT) -> None:
    """Set the start flag of every EFT given to ``code`` (> 0), all at once."""
    check_start_code(code, "start_ev")
    with _lock:
        checked = [_check_live(e, f"start_ev(argument {i + 2})") for i, e in enumerate(efts)]
        for e in checked:
            e._start = int(code)
            e.t_start_set = time.monotonic()
            _notify(e)
        _changed.notify_all()


def stop_ev(code: int, *efts: EFT) -> None:
    """Set the stop flag of every EFT given to ``code`` (< 0), all at once: each motion halts at its
    arm's next sample (or, not yet started, is deleted from the queue)."""
    check_stop_code(code, "stop_ev")
    with _lock:
        checked = [_check_live(e, f"stop_ev(argument {i + 2})") for i, e in enumerate(efts)]
        for e in checked:
            if e._status >= 0:            # an ended motion keeps its stop code
                e._stop = int(code)
                _notify(e)
        _changed.notify_all()


def status_ev(eft: EFT) -> int:
    """The status flag: NULL (0) pending, the start code (> 0) running, the stop code (< 0) ended."""
    return _check_live(eft, "status_ev")._status


def free_ev(*efts: EFT) -> None:
    """Give EFTs back to the system; their motions must have ended."""
    with _lock:
        checked = [_check_live(e, f"free_ev(argument {i + 1})") for i, e in enumerate(efts)]
        busy = [e for e in checked if e._status >= 0]
        if busy:
            raise EventError("free_ev: " + "; ".join(f"{e.describe()} has not ended (status {code_name(e._status)})"
                                                     for e in busy))
        for e in checked:
            e.freed = True
            _live.pop(id(e), None)
            for ae in _arms.values():
                if e in ae.efts:
                    ae.efts.remove(e)


def stop_abort(arm) -> None:
    """Flush ``arm``'s motion queue and bring it to a halt; every EFT not yet ended gets ABORTED."""
    ae = _events_of(arm)
    with _lock:
        for e in ae.efts:
            if e._status >= 0 and e._stop == NULL:
                e._stop = ABORTED
                _notify(e)
    for r in arm.gen.queue.clear():
        r.finish(MotionError(f"{r.position.name}: not run, stop_abort flushed the queue of arm {ae.name!r}"))
    arm.gen.abort(MotionEnd("stop", "stop_abort", code=ABORTED, t=arm.gen.t, sample=arm.gen.samples))
    with _lock:
        _changed.notify_all()


def wait_ev(eft: EFT, *, started: bool = False, timeout: float | None = None, poll: float = 0.02) -> int:
    """Block the planning level until ``eft``'s motion has ended (``started=True``: has begun); its status.

    Raises ``Deadlock`` at once when nothing but this (blocked) planning level could ever
    start the motion: its start flag, or that of a motion it waits for, is unset with no
    start condition. Arm faults are delivered while waiting (the arm's ``check``).
    """
    eft = _check_live(eft, "wait_ev")
    done = (lambda: eft._status != NULL) if started else (lambda: eft._status < 0)
    deadline = None if timeout is None else time.monotonic() + timeout
    arm = _arm_named(eft.arm)
    with _lock:
        while not done():
            why = never_starts(eft)
            if why is not None:
                raise Deadlock(f"wait_ev: {eft.describe()} can never {'start' if started else 'end'}: {why}")
            if deadline is not None and time.monotonic() > deadline:
                raise TimeoutError(f"wait_ev: {eft!r} after {timeout} s")
            _changed.wait(poll)
            if arm is not None and hasattr(arm, "check"):
                _lock.release()
                try:
                    arm.check()
                finally:
                    _lock.acquire()
        return eft._status


# --- internals ---------------------------------------------------------------------------------
def check_start_code(code: Any, where: str) -> None:
    """Rule 4 for every form of the API (rccl.event_flags): a start code is an int > 0."""
    if not isinstance(code, int) or isinstance(code, bool) or code <= 0:
        raise EventError(f"{where}: start codes are positive integers (rule 4; NULL = 0 is reserved), got {code!r}")


def check_stop_code(code: Any, where: str) -> None:
    """Rule 4 for every form of the API (rccl.event_flags): a stop code is an int < 0."""
    if not isinstance(code, int) or isinstance(code, bool) or code >= 0:
        raise EventError(f"{where}: stop codes are negative integers (rule 4; NULL = 0 is reserved), got {code!r}")


def _arm_named(name: str):
    for ae in _arms.values():
        if ae.name == name:
            return ae.arm
    return None


def _finished(eft: EFT, req: Request) -> None:
    """Request.finish of ``eft``'s request (trajectory level, or the planning level on recover)."""
    with _lock:
        if eft.request is not req:
            return
        dropper = req.dropped_by
        ae = next((a for a in _arms.values() if a.name == eft.arm), None)
        if dropper is not None and ae is not None and ae.gate.cleared_head is req and eft._stop == NULL:
            branch = choose(dropper.conditional, dropper.ended)
            if branch is not None:          # 5.6.3: the conditional motion inherits the nominal motion's EFT
                eft.request = branch.request
                _bind(eft, branch.request)
                _changed.notify_all()
                return
        if eft._stop == NULL:
            ended = req.ended
            if req.error is None and ended is not None and ended.reason in ("limit", "monitor"):
                eft._stop = LIMIT if ended.reason == "limit" else MONITOR
            elif req.error is None:
                eft._stop = DONE
            elif dropper is not None:
                eft._stop = ABORTED
            else:
                eft._stop = FAULT
        eft._status = eft._stop
        eft.t_ended = time.monotonic()
        if ae is not None:
            eft.traj_ended = ae.arm.gen.t
        _notify(eft)
        for f in eft._followers:
            _fire(eft, f)
        _changed.notify_all()


def _fire(source: EFT, target: EFT) -> None:
    """``source`` ended: start ``target`` unless ``source`` failed or was aborted."""
    if target.after is source and target._start == NULL and source._status not in (FAULT, ABORTED):
        target._start = target.after_code
        target.t_start_set = time.monotonic()
        _notify(target)


def _predecessor(e: EFT) -> EFT | None:
    """The EFT queued just before ``e`` on its arm that has not ended (``e`` cannot start before it ends)."""
    for a in _arms.values():
        if a.name == e.arm:
            lst = a.efts
            i = lst.index(e) if e in lst else 0
            for p in reversed(lst[:i]):
                if p._status >= 0:
                    return p
            return None
    return None


def _deps(e: EFT) -> list[EFT]:
    """The motions ``e`` waits for before it can start (none once it started or its stop flag is set)."""
    if e._status != NULL or e._stop != NULL:
        return []
    out = []
    p = _predecessor(e)
    if p is not None:
        out.append(p)
    if e._start == NULL and e.after is not None and e.after._status >= 0:
        out.append(e.after)
    return out


def _waits_for(e: EFT, target: EFT, seen: set | None = None) -> list[EFT] | None:
    """A chain from ``e`` to ``target`` through start dependencies, or None."""
    if e is target:
        return [e]
    seen = seen if seen is not None else set()
    if id(e) in seen:
        return None
    seen.add(id(e))
    for d in _deps(e):
        chain = _waits_for(d, target, seen)
        if chain is not None:
            return [e] + chain
    return None


def never_starts(e, predecessor: Callable = None, seen: set | None = None) -> str | None:
    """Why the motion of EFT ``e`` can never start (or end), or None if it can.

    Reads only the public flags (``start``, ``stop``, ``status``, ``after``, ``describe()``),
    so it serves local EFTs and rccl.bus.planning' remote ones alike; ``predecessor(e)``: the
    motion queued before ``e`` on its arm that has not ended (default: this process's queues)."""
    predecessor = predecessor or _predecessor
    if e.status != NULL or e.stop != NULL:      # started, or stopped: it will end
        return None
    seen = seen if seen is not None else set()
    if id(e) in seen:
        return f"{e.describe()} waits for itself"
    seen.add(id(e))
    if e.start == NULL:
        if e.after is None:
            return f"the start flag of {e.describe()} is not set and nothing will set it (start_ev it first)"
        src = e.after
        if src.status in (FAULT, ABORTED):
            return f"{e.describe()} waits for {src.describe()}, which ended {code_name(src.status)}"
        why = never_starts(src, predecessor, seen)
        if why is not None:
            return f"{e.describe()} waits for {src.describe()}; {why}"
    p = predecessor(e)
    if p is not None:
        why = never_starts(p, predecessor, seen)
        if why is not None:
            return f"{e.describe()} is queued behind {p.describe()}; {why}"
    return None
