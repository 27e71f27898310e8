"""Synchronisation between the planning and trajectory levels: RCCL's event flags (thesis 5.3.3).

An ``Event`` is a counter. The trajectory generator decrements it each time it completes a
motion request that carries it (a position's ``end``); ``waitfor`` increments it and then
blocks until it drops below one. So a ``waitfor`` issued after the motion already ended
returns at once (the counter went to -1 and comes back to 0), exactly as in RCCL.

While it waits, ``waitfor`` keeps asking ``fault()`` (the running session's error check),
so a fault at the control level reaches the planning level promptly instead of leaving
it blocked forever.
"""
from __future__ import annotations

import threading
import time
from typing import Callable


class Event:
    """An RCCL event flag (a counter); thread safe."""

    __slots__ = ("name", "_count", "_pending", "_cond")

    def __init__(self, name: str = "event") -> None:
        self.name = name
        self._count = 0
        self._pending = 0          # queued motions that will signal it (see ``expect``)
        self._cond = threading.Condition()

    @property
    def count(self) -> int:
        return self._count

    @property
    def pending(self) -> int:
        """Motions queued or running that will signal this event when they end."""
        return self._pending

    def expect(self) -> None:
        """A motion that signals this event at its end was queued (planning level)."""
        with self._cond:
            self._pending += 1

    def will_signal(self) -> bool:
        """Whether a ``wait`` can end: a signal not yet waited for, or a motion that will signal."""
        return self._count < 0 or self._pending > 0

    def signal(self) -> None:
        """Decrement (called by the trajectory level when a motion completes) and wake waiters."""
        with self._cond:
            self._count -= 1
            self._pending = max(0, self._pending - 1)
            self._cond.notify_all()

    def wait(self, fault: Callable[[], None] | None = None, timeout: float | None = None,
             poll: float = 0.02) -> None:
        """Increment, then block until the count is below one (thesis ``waitfor``).

        ``fault`` is called every ``poll`` seconds and may raise to abort the wait (the
        count is restored). ``timeout`` (s) raises ``TimeoutError`` naming the event.
        """
        deadline = None if timeout is None else time.monotonic() + timeout
        with self._cond:
            self._count += 1
            try:
                while self._count >= 1:
                    if fault is not None:
                        fault()
                    if deadline is not None and time.monotonic() > deadline:
                        raise TimeoutError(f"waitfor({self.name}): not signalled within {timeout} s")
                    self._cond.wait(poll)
            except BaseException:
                self._count -= 1
                raise

    def __repr__(self) -> str:
        return f"Event({self.name!r}, count={self._count})"
