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

    __slots__ = ("name", "_count", "_cond")

    def __init__(self, name: str = "event") -> None:
        self.name = name
        self._count = 0
        self._cond = threading.Condition()

    @property
    def count(self) -> int:
        return self._count

    def signal(self) -> None:
        """Decrement (called by the trajectory level when a motion completes) and wake waiters."""
        with self._cond:
            self._count -= 1
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
