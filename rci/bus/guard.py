"""Bounded work under floods: a token bucket and a bounded hand-over queue for Zenoh callbacks.

A Zenoh callback runs on one of Zenoh's threads (real time, above the control loop, in
simula and the controller): whatever a peer sends, it must do a bounded amount of work.
A query or request that needs real work is handed over here to a thread of its own through
a queue of bounded length; what does not fit is dropped and counted (the sender's query
ends with no answer), and the thread takes at most ``rate`` items a second.
"""
from __future__ import annotations

import threading
import time
from collections import deque
from typing import Any, Callable


class TokenBucket:
    """At most ``rate`` events a second on average, ``burst`` at once (time.monotonic)."""

    def __init__(self, rate: float, burst: float) -> None:
        self.rate, self.burst = float(rate), float(burst)
        self._tokens = float(burst)
        self._t = time.monotonic()

    def take(self) -> bool:
        now = time.monotonic()
        self._tokens = min(self.burst, self._tokens + (now - self._t) * self.rate)
        self._t = now
        if self._tokens >= 1.0:
            self._tokens -= 1.0
            return True
        return False

    def wait_time(self) -> float:
        """Seconds until a token is there (0 if one is)."""
        return max(0.0, (1.0 - self._tokens) / self.rate)


class BoundedWorker:
    """Items handed over by callbacks (``offer``), handled by one daemon thread at most
    ``rate`` a second; at most ``capacity`` wait, the newest beyond that are dropped and
    counted in ``dropped``. ``handle(item)`` runs on the worker's thread; what it raises
    is counted in ``failed`` and does not stop the worker."""

    def __init__(self, name: str, handle: Callable[[Any], None], capacity: int = 32, rate: float = 200.0,
                 burst: float = 32.0) -> None:
        self._handle = handle
        self._items: deque = deque()
        self.capacity = int(capacity)
        self._bucket = TokenBucket(rate, burst)
        self._ready = threading.Condition()
        self._stop = False
        self.offered = 0
        self.dropped = 0
        self.failed = 0
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    def offer(self, item: Any) -> bool:
        """Hand ``item`` over (a Zenoh callback's only work); False if it was dropped."""
        with self._ready:
            self.offered += 1
            if len(self._items) >= self.capacity:
                self.dropped += 1
                return False
            self._items.append(item)
            self._ready.notify()
        return True

    def _run(self) -> None:
        while True:
            with self._ready:
                while not self._items and not self._stop:
                    self._ready.wait(0.5)
                if self._stop:
                    self._items.clear()
                    return
                item = self._items.popleft()
            if not self._bucket.take():
                time.sleep(self._bucket.wait_time())
                self._bucket.take()
            try:
                self._handle(item)
            except Exception:
                self.failed += 1
            del item

    def close(self) -> None:
        with self._ready:
            self._stop = True
            self._ready.notify_all()
        self._thread.join(2.0)


class Lanes:
    """Items handed over by callbacks in two lanes for one thread to take: the first lane
    (what is proved to come from the one sender that matters, e.g. the planning level that
    holds an arm) is taken ahead of the other, so a flood in the other lane delays it by one
    item at most. Each lane holds at most its capacity; what does not fit is dropped and
    counted in ``dropped``."""

    def __init__(self, first_capacity: int, other_capacity: int) -> None:
        self._lanes: tuple[deque, deque] = (deque(), deque())
        self._capacity = (int(first_capacity), int(other_capacity))
        self._ready = threading.Condition()
        self.dropped = 0

    def offer(self, item: Any, first: bool = False) -> bool:
        """Hand ``item`` over (a Zenoh callback's only work); False if it was dropped."""
        lane = 0 if first else 1
        with self._ready:
            if len(self._lanes[lane]) >= self._capacity[lane]:
                self.dropped += 1
                return False
            self._lanes[lane].append(item)
            self._ready.notify()
        return True

    def take(self, timeout: float) -> Any:
        """The next item, the first lane's before the other's; None after ``timeout`` s without one."""
        with self._ready:
            if not (self._lanes[0] or self._lanes[1]):
                self._ready.wait(timeout)
            for lane in self._lanes:
                if lane:
                    return lane.popleft()
        return None


class Episodes:
    """Reports a flood once, with its count: ``poll()`` returns one line when a count that
    rose has stayed still for ``quiet_s`` (the episode is over), else None.

    ``count()`` returns the running total; ``describe()`` says what was counted."""

    def __init__(self, what: str, count: Callable[[], int], describe: Callable[[], str], quiet_s: float = 1.0) -> None:
        self.what = what
        self._count, self._describe = count, describe
        self.quiet_s = quiet_s
        self._reported = 0            # the total at the end of the last episode reported
        self._seen = 0
        self._since = 0.0             # when the episode began
        self._changed = 0.0           # when the count last rose
        self.lines: list[str] = []    # every report made, oldest first

    def poll(self, now: float | None = None) -> str | None:
        n = self._count()
        now = time.monotonic() if now is None else now
        if n != self._seen:
            if self._seen == self._reported:
                self._since = now
            self._seen, self._changed = n, now
            return None
        if n == self._reported or now - self._changed < self.quiet_s:
            return None
        line = (f"{self.what}: {n - self._reported} rejected over {self._changed - self._since:.1f} s "
                f"(total {n}: {self._describe()})")
        self._reported = n
        self.lines.append(line)
        return line
