"""The motion queue (thesis 5.2, Figure 5.1): requests from the planning level, served by the trajectory level.

A plain FIFO shared by two threads. The planning level ``put``s requests and never blocks;
the trajectory generator ``get``s one when it nears the end of its current segment, and
finds ``None`` when the queue is empty (then it repeats the last request: the arm holds).

A ``QueuePolicy`` (``set_policy``) is the supported way to change what ``get`` hands out:
it may hold the head request back (a start gate) or delete it before it starts, and it is
told when requests are queued, taken and cleared (``rccl.events`` uses this for the event
flags of thesis 5.6.3).
"""
from __future__ import annotations

import collections
import threading
from typing import Generic, TypeVar

T = TypeVar("T")

TAKE = "take"   # QueuePolicy.admit: hand the head request out
HOLD = "hold"   # QueuePolicy.admit: keep it (and everything behind it) queued; get returns None


class QueuePolicy:
    """What a queue hands out and when; the default takes every request in order.

    ``admit`` runs under the queue's lock (it must not take other locks that are ever held
    while calling into the queue); the other hooks run outside it.
    """

    def queued(self, item) -> None:
        """``item`` is about to be appended (planning level, in ``put``)."""

    def admit(self, head):
        """TAKE, HOLD, or an exception: delete ``head`` unstarted (it is finished with that error)."""
        return TAKE

    def taken(self, item) -> None:
        """``get`` handed ``item`` out (trajectory level)."""

    def cleared(self, items: list) -> None:
        """``clear`` removed ``items`` (oldest first)."""


class MotionQueue(Generic[T]):
    """Thread-safe FIFO of motion requests, served through a ``QueuePolicy``."""

    def __init__(self, policy: QueuePolicy | None = None) -> None:
        self._items: collections.deque[T] = collections.deque()
        self._lock = threading.Lock()
        self.policy = policy if policy is not None else QueuePolicy()
        #: motion checks made since the last ``put`` (rccl.adaptive: limit, evalfn, add_check);
        #: the next request put takes them (5.4.1, 5.4.2: "for the next motion only")
        self.pending: list = []

    def set_policy(self, policy: QueuePolicy) -> None:
        """Serve the queue through ``policy`` from the next ``get`` on (requests already queued included)."""
        with self._lock:
            self.policy = policy

    def put(self, item: T, *, take_pending: bool = True) -> None:
        """Append ``item`` (planning level); it takes the pending motion checks unless ``take_pending`` is False
        (a conditional branch queued by the trajectory level)."""
        if take_pending and self.pending:
            item.checks.extend(self.pending)
            self.pending = []
        self.policy.queued(item)
        with self._lock:
            self._items.append(item)

    def push_front(self, item: T) -> None:
        """Put a request back at the head (the generator defers one it will start from rest)."""
        with self._lock:
            self._items.appendleft(item)

    def get(self) -> T | None:
        """The oldest admitted request, or None if the queue is empty or its head is held
        (never blocks: it runs at the control level). Requests the policy deletes are finished
        with its error, outside the lock."""
        dropped: list = []
        out = None
        with self._lock:
            policy = self.policy
            while self._items:
                verdict = policy.admit(self._items[0])
                if verdict == TAKE:
                    out = self._items.popleft()
                    break
                if verdict == HOLD:
                    break
                dropped.append((self._items.popleft(), verdict))
        if out is not None:
            policy.taken(out)
        for item, error in dropped:
            item.finish(error)
        return out

    def peek(self) -> T | None:
        with self._lock:
            return self._items[0] if self._items else None

    def snapshot(self) -> list[T]:
        """The requests waiting, oldest first (a copy: for viewers and diagnostics, any thread)."""
        with self._lock:
            return list(self._items)

    def clear(self) -> list[T]:
        """Remove and return every queued request (used when a fault stops the arm)."""
        with self._lock:
            items = list(self._items)
            self._items.clear()
        self.policy.cleared(items)
        return items

    def __len__(self) -> int:
        return len(self._items)
