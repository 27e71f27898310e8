"""The control configuration: every setting of a session's control cycle, validated once, immutable.

A session builds one ``ControlConfig`` from its keyword arguments (``rci.Session(url, robot,
rate_hz=..., timeout=..., ...)``) and hands it to each control task it starts; the task
reads its settings from there and nowhere else. Changing a setting makes a new record
(``Session.configure``, between controls; the recorder also during one), so what a
running control uses cannot change under it half-way through a cycle.

The sample rate here is the rate a control *starts* at (START). While a control runs,
the rate is the robot's: each HOW says the rate at which the robot executes the CHG
answering it (docs/protocol.md), and the control task follows it (``ControlTask.rate_hz``).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

from .checks import CommandLimits
from .rate import check_rate_hz
from .realtime import RealtimeSettings

OVERRUN_MODES = ("error", "count", "auto")
#: late cycles in a row that end a control by default, and the time their run may span at high rates
DEFAULT_LATE_LIMIT = 3
LATE_SPAN_S = 0.02


def _seconds(name: str, value: object, none_means: str | None = None) -> None:
    """ValueError unless ``value`` is a finite number of seconds > 0 (or None when ``none_means``)."""
    if value is None and none_means:
        return
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not (0 < value < math.inf):
        alt = f" or None ({none_means})" if none_means else ""
        raise ValueError(f"{name} must be a number of seconds > 0{alt}, not {value!r}")


@dataclass(frozen=True)
class ControlConfig:
    """How a session's controls run (SI units; docs/rci.md, "Session options").

    ``rate_hz`` the rate a control starts at, 4..1000 Hz; ``timeout`` s without a HOW before
    R_TIMEOUT (None: two periods, at least ``min_timeout``, and against a lockstep simulator
    at least ``lockstep_timeout``); ``start_timeout`` s for the robot's WELCOME and first HOW;
    ``overrun`` the lateness policy: ``"error"`` ends a control after ``late_limit`` late
    cycles in a row, ``"count"`` only counts them, ``"auto"`` is ``"error"`` against a
    real-time robot and ``"count"`` against a lockstep simulator; ``late_limit`` (None: 3, or
    20 ms worth of cycles at high rates); ``watchdog`` end a control whose function hangs;
    ``limits`` the A.5.1 range checks (``"model"``, a ``CommandLimits``, or None: off);
    ``max_commands`` per cycle (R_TOOMANY); ``recorder`` an ``rci.recorder.Recorder`` that logs
    every cycle, or None; ``realtime`` what is asked of the operating system; ``lockstep``
    whether the robot is a lockstep simulator (from its WELCOME; set by the session).
    """

    rate_hz: int = 36
    timeout: float | None = None
    min_timeout: float = 0.02
    start_timeout: float = 2.0
    lockstep_timeout: float = 0.25
    overrun: str = "auto"
    late_limit: int | None = None
    watchdog: bool = True
    limits: str | CommandLimits | None = "model"
    max_commands: int = 16
    recorder: Any = field(default=None, compare=False)
    realtime: RealtimeSettings = field(default_factory=RealtimeSettings)
    lockstep: bool = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "rate_hz", check_rate_hz(self.rate_hz, "rate_hz"))
        _seconds("timeout", self.timeout, "twice the period, at least min_timeout")
        for name in ("min_timeout", "start_timeout", "lockstep_timeout"):
            _seconds(name, getattr(self, name))
        if self.overrun not in OVERRUN_MODES:
            raise ValueError(f"overrun must be 'error', 'count' or 'auto', not {self.overrun!r}")
        ll = self.late_limit
        if ll is not None and (isinstance(ll, bool) or not isinstance(ll, int) or ll < 1):
            raise ValueError(f"late_limit must be None (automatic) or an integer >= 1, not {ll!r}")
        mc = self.max_commands
        if isinstance(mc, bool) or not isinstance(mc, int) or mc < 1:
            raise ValueError(f"max_commands must be an integer >= 1, not {mc!r}")
        if not (self.limits is None or self.limits == "model" or isinstance(self.limits, CommandLimits)):
            raise ValueError(f"limits must be 'model', a CommandLimits or None, not {self.limits!r}")
        if not isinstance(self.realtime, RealtimeSettings):
            raise ValueError(f"realtime must be a RealtimeSettings, not {self.realtime!r}")

    @classmethod
    def build(cls, *, realtime: bool = True, priority: int = 80, gc: str = "freeze",
              lock_memory: bool = True, switch_interval: float | None = 2e-4, **options: Any) -> "ControlConfig":
        """The record for ``rci.Session``'s flat keyword arguments (the real-time ones grouped)."""
        rt = RealtimeSettings(realtime=realtime, priority=priority, gc=gc, lock_memory=lock_memory,
                              switch_interval=switch_interval)
        return cls(realtime=rt, **options)

    def changed(self, **changes: Any) -> "ControlConfig":
        """A new record with ``changes`` (the names of ``build``), validated like the first."""
        rt_names = {f.name for f in dataclasses.fields(RealtimeSettings)} - {"realtime"}
        rt_changes = {k: changes.pop(k) for k in list(changes) if k in rt_names}
        if isinstance(changes.get("realtime"), bool):
            rt_changes["realtime"] = changes.pop("realtime")
        unknown = set(changes) - {f.name for f in dataclasses.fields(self)}
        if unknown:
            raise TypeError(f"unknown control settings {sorted(unknown)}")
        rt = dataclasses.replace(self.realtime, **rt_changes) if rt_changes else self.realtime
        return dataclasses.replace(self, realtime=rt, **changes)

    # --- what the settings mean at a given rate ------------------------------------------
    @property
    def period(self) -> float:
        """The period a control starts with, s."""
        return 1.0 / self.rate_hz

    @property
    def late_policy(self) -> str:
        """``"error"`` or ``"count"``: ``overrun`` with ``"auto"`` resolved for this robot."""
        if self.overrun == "auto":
            return "count" if self.lockstep else "error"
        return self.overrun

    def timeout_for(self, period: float) -> float:
        """Seconds without a HOW before R_TIMEOUT, for a cycle of ``period`` s."""
        if self.timeout is not None:
            return self.timeout
        floor = max(self.min_timeout, self.lockstep_timeout if self.lockstep else 0.0)
        return max(2.0 * period, floor)

    def late_limit_for(self, rate_hz: float) -> int:
        """Late cycles in a row that end a control at ``rate_hz`` (``late_limit``, or 3 and up to
        20 ms worth of cycles at high rates: 5 at 250 Hz, 20 at 1 kHz, like libfranka's 20
        lost packets at 1 kHz)."""
        if self.late_limit is not None:
            return self.late_limit
        return max(DEFAULT_LATE_LIMIT, int(round(LATE_SPAN_S * rate_hz)))

    def user_hang_limit(self, period: float) -> float:
        """Seconds a control function may run after its cycle began before the watchdog ends the
        control (two periods; against a lockstep simulator, which waits for it, at least 2 s)."""
        return 2 * period if self.late_policy == "error" else max(2 * period, 2.0)
