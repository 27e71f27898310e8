"""A process's heartbeat on the Zenoh bus (``rccl.bus.arm``'s arm processes, ``rccl.bus.planning``'s planning levels).

A thread of its own says the process is alive every ``HEARTBEAT_S``: it publishes a small
JSON payload on a key (``rcci/CELL/arm/ARM/alive``, ``rcci/CELL/planner/ID/alive``) and,
before each beat, tells its owner how long it has been since the previous one. A gap much
longer than ``HEARTBEAT_S`` means this process was stopped (SIGSTOP), hung or starved that
long: whoever watches the beats heard nothing meanwhile. Under SCHED_FIFO at ``priority``
(> 0, where the OS allows) a beat leaves on time on a loaded machine.
"""
from __future__ import annotations

import sys
import threading
import time
from typing import Callable

from rci.bus import encode
from rci.realtime import RealtimeStatus, set_fifo

HEARTBEAT_S = 0.05       # an arm process, and a planning level, says it is alive this often (s)


class Heartbeat:
    """Publish ``payload(n, now)`` on ``key`` every ``HEARTBEAT_S`` (``n`` counts the beats from
    1, ``now`` is ``time.monotonic()``), after ``on_beat(now, gap)`` (``gap``: s since the
    previous beat, or since ``start``). ``last``: ``time.monotonic()`` of the last beat."""

    def __init__(self, session, key: str, payload: Callable[[int, float], dict],
                 on_beat: Callable[[float, float], None], priority: int = 0, name: str = "alive") -> None:
        import zenoh
        self.session, self.key, self.priority = session, key, int(priority)
        self._payload, self._on_beat = payload, on_beat
        self._block = zenoh.CongestionControl.BLOCK
        self._stop = threading.Event()
        self.last = time.monotonic()
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)

    def start(self) -> None:
        self.last = time.monotonic()
        self._thread.start()

    def stop(self, timeout: float = 2.0) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout)

    def _run(self) -> None:
        if self.priority > 0:
            set_fifo(self.priority, RealtimeStatus())
        n = 0
        while not self._stop.wait(HEARTBEAT_S):
            now = time.monotonic()
            self._on_beat(now, now - self.last)
            self.last = now
            n += 1
            try:
                self.session.put(self.key, encode(self._payload(n, now)), congestion_control=self._block,
                                 express=True)
            except Exception as exc:
                if self.session.is_closed():
                    return             # the process is leaving the bus: nothing more to say
                print(f"{self.key}: heartbeat not published: {exc}", file=sys.stderr)
