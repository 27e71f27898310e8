"""Shared data and channels between a workcell's tasks (thesis 2.4.2.2), inside one process.

``Shared`` (mode t1: the latest value of each name) and ``Channel`` (modes t2, t3: a bounded
FIFO from one task to another), as ``rci.multi.Workcell`` gives them to its arms' control
tasks and its planning level; ``rci.bus`` has the same two across processes and hosts.
"""
from __future__ import annotations

import collections
import itertools
import threading
from typing import Any, Callable, Hashable

import numpy as np

from .exceptions import RCIError

OVERFLOW = ("drop_oldest", "block", "error")


class MultiError(RCIError):
    """Misuse of the multi-robot primitives (unknown arm, bad option, wrong level)."""


class ChannelFull(MultiError):
    """A send on a full channel whose overflow policy is "error" (or "block" from a control task)."""



def snapshot(value: Any) -> Any:
    """A copy safe to hand to another task: arrays copied (containers walked), others as they are.

    Messages should be immutable or arrays; a mutable object other than these is passed by
    reference, as in the thesis's shared memory.
    """
    if isinstance(value, np.ndarray):
        return value.copy()
    if isinstance(value, (list, tuple)):
        return type(value)(snapshot(v) for v in value)
    if isinstance(value, dict):
        return {k: snapshot(v) for k, v in value.items()}
    return value


# --- shared data (t1) ----------------------------------------------------------------
class Shared:
    """Shared data between the control tasks and the planning level (thesis 2.4.2.2, mode t1).

    ``put(name, value)`` / ``get(name, default)`` (also ``shared[name]``). Each value is
    written and read as one unit under a lock (the "several bytes nondivisibly" RCI needs),
    and copied (arrays), so a reader never sees half of an update. With ``deferred=True``
    (a lockstep workcell) writes are held until ``commit()``, called at each sample barrier.
    """

    def __init__(self, deferred: bool = False) -> None:
        self._values: dict[Hashable, Any] = {}
        self._pending: dict[Hashable, Any] = {}
        self._lock = threading.Lock()
        self.deferred = deferred

    def put(self, name: Hashable, value: Any) -> None:
        v = snapshot(value)
        with self._lock:
            (self._pending if self.deferred else self._values)[name] = v

    def get(self, name: Hashable, default: Any = None) -> Any:
        with self._lock:
            v = self._values.get(name, default)
        return snapshot(v)

    def __getitem__(self, name: Hashable) -> Any:
        with self._lock:
            if name not in self._values:
                raise KeyError(f"shared data has no {name!r} (yet): names are {sorted(map(str, self._values))}")
            v = self._values[name]
        return snapshot(v)

    def __setitem__(self, name: Hashable, value: Any) -> None:
        self.put(name, value)

    def __contains__(self, name: Hashable) -> bool:
        with self._lock:
            return name in self._values

    def commit(self) -> None:
        """Make the deferred writes visible (lockstep sample barrier)."""
        with self._lock:
            if self._pending:
                self._values.update(self._pending)
                self._pending.clear()


# --- channels (t2, t3) -----------------------------------------------------------------
class Channel:
    """A FIFO from one task to another (thesis 2.4.2.2 "data channels", modes t2 and t3).

    ``capacity`` messages at most; on overflow ``"drop_oldest"`` (t3 asynchronous: the
    oldest is lost and counted in ``dropped``), ``"block"`` (t3 synchronous, and t2 with a
    large capacity: the sender waits; only the planning level may wait, a control task gets
    ``ChannelFull``), or ``"error"`` (``ChannelFull``). ``receive()`` returns the oldest
    message or None; only the planning level may pass a ``timeout`` to wait for one.
    With ``deferred`` (lockstep) a message sent in sample n is receivable from sample n + 1.
    """

    def __init__(self, sender: str, receiver: str, capacity: int = 16, overflow: str = "drop_oldest", *,
                 deferred: bool = False, is_control_thread: Callable[[], bool] = lambda: False) -> None:
        if overflow not in OVERFLOW:
            raise MultiError(f"channel {sender}->{receiver}: overflow must be one of {OVERFLOW}, not {overflow!r}")
        if int(capacity) < 1:
            raise MultiError(f"channel {sender}->{receiver}: capacity must be >= 1, not {capacity!r}")
        self.sender, self.receiver = sender, receiver
        self.capacity = int(capacity)
        self.overflow = overflow
        self.deferred = deferred
        self.dropped = 0
        self.sent = 0
        self._items: collections.deque[tuple[int, Any]] = collections.deque()
        self._pending: list[tuple[int, Any]] = []
        self._cond = threading.Condition()
        self._in_control = is_control_thread
        self._stamp = itertools.count()

    def __repr__(self) -> str:
        return f"Channel({self.sender!r} -> {self.receiver!r}, {len(self)}/{self.capacity}, {self.overflow})"

    def __len__(self) -> int:
        return len(self._items) + len(self._pending)

    def send(self, message: Any, timeout: float | None = None, *, stamp: int | None = None) -> None:
        """Queue ``message`` (a copy of its arrays). Never blocks in a control task.

        None cannot be sent: ``receive()`` returns None for "no message".
        """
        if message is None:
            raise MultiError(f"channel {self.sender}->{self.receiver}: None cannot be sent "
                             "(receive() returns None for 'no message')")
        item = (next(self._stamp) if stamp is None else stamp, snapshot(message))
        with self._cond:
            if len(self) >= self.capacity:
                if self.overflow == "drop_oldest":
                    if self._items:
                        self._items.popleft()
                    else:
                        self._pending.pop(0)
                    self.dropped += 1
                elif self.overflow == "error" or self._in_control():
                    why = "" if self.overflow == "error" else " (a control task never waits)"
                    raise ChannelFull(f"channel {self.sender}->{self.receiver} is full "
                                      f"({self.capacity} messages){why}")
                else:
                    if not self._cond.wait_for(lambda: len(self) < self.capacity, timeout):
                        raise ChannelFull(f"channel {self.sender}->{self.receiver}: still full after {timeout} s")
            (self._pending if self.deferred else self._items).append(item)
            self.sent += 1
            self._cond.notify_all()

    def peek_stamp(self) -> int | None:
        with self._cond:
            return self._items[0][0] if self._items else None

    def receive(self, timeout: float = 0.0) -> Any:
        """The oldest message, or None if there is none (after waiting ``timeout`` s, planning level only)."""
        if timeout and self._in_control():
            raise MultiError(f"channel {self.sender}->{self.receiver}: a control task must not wait in receive()")
        with self._cond:
            if not self._items and timeout:
                self._cond.wait_for(lambda: bool(self._items), timeout)
            if not self._items:
                return None
            msg = self._items.popleft()[1]
            self._cond.notify_all()
            return msg

    def commit(self) -> None:
        with self._cond:
            if self._pending:
                self._items.extend(self._pending)
                self._pending.clear()
                self._cond.notify_all()


# --- the workcell -----------------------------------------------------------------------
