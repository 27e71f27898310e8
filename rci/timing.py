"""Per-cycle timing of the control task: lateness, period jitter, duration, user time.

The control task writes one entry per cycle into preallocated arrays (no allocation in
the cycle); the planning level reads ``last`` values or asks for a ``summary`` (a record whose fields are
seconds and counts, printed as a table in milliseconds). Times are host ``time.monotonic()``
seconds.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(repr=False)
class TimingSummary:
    """Statistics over the recorded cycles (all times in seconds)."""

    cycles: int
    period: float
    missed: int                 # cycles the robot saw without a timely chg, plus sequence gaps
    overruns: int               # cycles whose work exceeded the period (controller side)
    jitter_p50: float           # |interval between HOW arrivals - period|
    jitter_p99: float
    jitter_max: float
    lateness_p99: float
    duration_p50: float         # HOW arrival to end of f2
    duration_p99: float
    duration_max: float
    overhead_p50: float         # RCI's own work per cycle (duration minus user functions)
    overhead_p99: float
    user_share_p50: float       # share of the period left to user code: 1 - overhead/period
    user_share_p99: float       # (computed with the p99 overhead: the worst-case budget)
    late_cycles: int = 0        # cycles late by the lateness policy (robot saw its CHG late, or work overran)
    late_run_max: int = 0       # the longest run of late cycles in a row
    late_limit: int = 0         # late cycles in a row that end the control (0: not set / never reached)
    duplicates: int = 0         # HOW frames received twice (ignored)

    def as_dict(self) -> dict:
        return dict(self.__dict__)

    def table(self) -> str:
        """The summary as a short table in milliseconds, for a person (``print(s.timing.summary())``)."""
        rate = f" at {1.0 / self.period:.0f} Hz, period {_ms(self.period)}" if self.period > 0 else ""
        rows = [("HOW interval jitter", self.jitter_p50, self.jitter_p99, self.jitter_max),
                ("lateness", None, self.lateness_p99, None),
                ("cycle duration", self.duration_p50, self.duration_p99, self.duration_max),
                ("RCI overhead", self.overhead_p50, self.overhead_p99, None)]
        lines = [f"timing over {self.cycles} cycles{rate}",
                 f"{'':20}{'p50':>11}{'p99':>11}{'max':>11}"]
        lines += [f"{name:20}" + "".join(f"{_ms(v) if v is not None else '-':>11}" for v in values)
                  for name, *values in rows]
        lines.append(f"{'share left to user':20}{self.user_share_p50:>11.1%}{self.user_share_p99:>11.1%}{'-':>11}")
        limit = f" of {self.late_limit} allowed" if self.late_limit else ""
        lines.append(f"missed {self.missed}, overruns {self.overruns}, late {self.late_cycles} "
                     f"(longest run {self.late_run_max}{limit}), duplicate HOWs {self.duplicates}")
        return "\n".join(lines)

    # a person at a prompt sees the table, not 19 fields of 17-digit seconds; as_dict() for programs
    __str__ = table
    __repr__ = table


def _ms(seconds: float) -> str:
    """Seconds as milliseconds with three decimals (microsecond resolution)."""
    return f"{seconds * 1e3:.3f} ms"


class CycleTiming:
    """Ring of per-cycle timings kept by the control task."""

    def __init__(self, capacity: int = 1 << 17) -> None:
        self.capacity = capacity
        self.arrival = np.zeros(capacity)
        self.lateness = np.zeros(capacity)
        self.duration = np.zeros(capacity)
        self.user_time = np.zeros(capacity)
        self.period = np.zeros(capacity)
        self.count = 0
        self.missed = 0
        self.overruns = 0
        self.late_cycles = 0
        self.late_run_max = 0
        self.late_limit = 0
        self.duplicates = 0
        self.last_lateness = 0.0
        self.last_duration = 0.0
        self.last_user_time = 0.0

    def reset(self) -> None:
        self.count = 0
        self.missed = 0
        self.overruns = 0
        self.late_cycles = 0
        self.late_run_max = 0
        self.late_limit = 0
        self.duplicates = 0

    def add(self, arrival: float, lateness: float, duration: float, user_time: float, period: float) -> None:
        i = self.count % self.capacity
        self.arrival[i] = arrival
        self.lateness[i] = lateness
        self.duration[i] = duration
        self.user_time[i] = user_time
        self.period[i] = period
        self.last_lateness, self.last_duration, self.last_user_time = lateness, duration, user_time
        self.count += 1

    def _window(self) -> slice:
        n = min(self.count, self.capacity)
        return slice(0, n)

    def summary(self, skip: int = 0) -> TimingSummary:
        """Statistics over the cycles kept (the newest ``capacity``), ignoring the first ``skip``."""
        n = min(self.count, self.capacity)
        if self.count > self.capacity:
            order = np.roll(np.arange(self.capacity), -(self.count % self.capacity))
        else:
            order = np.arange(n)
        order = order[skip:]
        if len(order) < 2:
            z = 0.0
            return TimingSummary(len(order), float(self.period[order[-1]]) if len(order) else 0.0,
                                 self.missed, self.overruns, z, z, z, z, z, z, z, z, z, 1.0, 1.0,
                                 self.late_cycles, self.late_run_max, self.late_limit, self.duplicates)
        arr, per = self.arrival[order], self.period[order]
        jit = np.abs(np.diff(arr) - per[1:])
        dur, usr = self.duration[order], self.user_time[order]
        ovh = np.maximum(dur - usr, 0.0)
        period = float(np.median(per))
        q = lambda x, p: float(np.percentile(x, p))  # noqa: E731
        return TimingSummary(
            cycles=len(order), period=period, missed=self.missed, overruns=self.overruns,
            jitter_p50=q(jit, 50), jitter_p99=q(jit, 99), jitter_max=float(jit.max()),
            lateness_p99=q(self.lateness[order], 99),
            duration_p50=q(dur, 50), duration_p99=q(dur, 99), duration_max=float(dur.max()),
            overhead_p50=q(ovh, 50), overhead_p99=q(ovh, 99),
            user_share_p50=1.0 - q(ovh, 50) / period, user_share_p99=1.0 - q(ovh, 99) / period,
            late_cycles=self.late_cycles, late_run_max=self.late_run_max, late_limit=self.late_limit,
            duplicates=self.duplicates)
