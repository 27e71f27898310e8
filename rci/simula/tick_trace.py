"""simula's tick trace: per-tick wall-clock timestamps of the real-time loop, for timing studies."""
from __future__ import annotations

import numpy as np


class TickTrace:
    """Real-time mode: per-tick wall-clock timestamps (time.monotonic, shared with the controller).

    Enabled by the environment variable ``RCI_SIMULA_TRACE=<file.npz>``; written when the
    server closes. One row per tick: ``deadline`` (the tick's scheduled time), ``sent`` (its
    HOW written), ``chg`` (the CHG answering that HOW read, 0 if none in time), ``late`` (1 if
    the tick found no CHG for the previous HOW), ``spin`` (when the busy-wait before the tick
    began: a late value means the select() wake-up was late), ``prep`` (seconds spent
    preparing the next HOW after the CHG came in). Compare with the controller's
    ``CycleTiming.arrival`` to split a late cycle between the two processes and the link.
    """

    def __init__(self, path: str, capacity: int = 1 << 18) -> None:
        self.path = path
        self.deadline = np.zeros(capacity)
        self.sent = np.zeros(capacity)
        self.chg = np.zeros(capacity)
        self.late = np.zeros(capacity, dtype=np.int8)
        self.spin = np.zeros(capacity)
        self.prep = np.zeros(capacity)
        self.cur_spin = 0.0
        self.n = 0
        self.capacity = capacity

    def tick(self, deadline: float, sent: float, late: bool) -> None:
        if self.n < self.capacity:
            self.deadline[self.n], self.sent[self.n], self.late[self.n] = deadline, sent, late
            self.spin[self.n] = self.cur_spin
            self.n += 1

    def got_chg(self, t: float) -> None:
        if 0 < self.n <= self.capacity:
            self.chg[self.n - 1] = t

    def prepared(self, seconds: float) -> None:
        if 0 < self.n <= self.capacity:
            self.prep[self.n - 1] = seconds

    def save(self) -> None:
        n = self.n
        np.savez(self.path, deadline=self.deadline[:n], sent=self.sent[:n], chg=self.chg[:n],
                 late=self.late[:n], spin=self.spin[:n], prep=self.prep[:n])
