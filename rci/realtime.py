"""Real-time set-up for the control task: SCHED_FIFO, memory locking, GC and GIL settings.

Each measure is tried and, where the OS refuses (no privilege, not Linux), skipped; the
outcome is reported in a ``RealtimeStatus`` so a program (and the bench) can say what it
actually ran with.
"""
from __future__ import annotations

import ctypes
import ctypes.util
import gc
import os
import sys
import threading
from dataclasses import dataclass, field

MCL_CURRENT = 1
MCL_FUTURE = 2
GC_MODES = ("freeze", "off", "leave")


@dataclass
class RealtimeStatus:
    """What the real-time set-up achieved (each entry: True, or a reason string)."""

    sched_fifo: bool | str = "not tried"
    mlockall: bool | str = "not tried"
    gc: str = "not tried"
    switch_interval: float = 0.0
    notes: list[str] = field(default_factory=list)

    def summary(self) -> str:
        return (f"SCHED_FIFO: {self.sched_fifo}; mlockall: {self.mlockall}; gc: {self.gc}; "
                f"GIL switch interval: {self.switch_interval * 1e6:.0f} us")


@dataclass(frozen=True)
class RealtimeSettings:
    """What a control asks of the operating system (each measure tried, skipped where refused).

    ``realtime``: put the control thread under SCHED_FIFO at ``priority`` (1..99; the link's
    own threads run one above it); ``gc``: the collector during a control (``GCControl``:
    ``"freeze"``, ``"off"``, ``"leave"``); ``lock_memory``: mlockall while the session is
    open; ``switch_interval``: the GIL switch interval during a control, s (None: leave it).
    """

    realtime: bool = True
    priority: int = 80
    gc: str = "freeze"
    lock_memory: bool = True
    switch_interval: float | None = 2e-4

    @property
    def link_priority(self) -> int:
        """SCHED_FIFO priority for the link's own threads (0: none): just above the control thread."""
        return min(self.priority + 1, 99) if self.realtime else 0

    def __post_init__(self) -> None:
        if isinstance(self.priority, bool) or not isinstance(self.priority, int) or not 1 <= self.priority <= 99:
            raise ValueError(f"priority must be an integer 1..99 (SCHED_FIFO), not {self.priority!r}")
        if self.gc not in GC_MODES:
            raise ValueError(f"gc must be one of {GC_MODES}, not {self.gc!r}")
        si = self.switch_interval
        if si is not None and (isinstance(si, bool) or not isinstance(si, (int, float)) or not 0 < si < 1):
            raise ValueError(f"switch_interval must be None or a number of seconds in (0, 1), not {si!r}")


_mlocked = False


def lock_memory(status: RealtimeStatus) -> None:
    """mlockall(MCL_CURRENT | MCL_FUTURE) once per process, so the control task never page-faults."""
    global _mlocked
    if _mlocked:
        status.mlockall = True
        return
    if not sys.platform.startswith("linux"):
        status.mlockall = f"not available on {sys.platform}"
        return
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        if libc.mlockall(MCL_CURRENT | MCL_FUTURE) != 0:
            err = ctypes.get_errno()
            status.mlockall = f"refused: {os.strerror(err)}"
            return
    except OSError as e:
        status.mlockall = f"unavailable: {e}"
        return
    _mlocked = True
    status.mlockall = True


def unlock_memory() -> None:
    """munlockall(): undo ``lock_memory`` when the session that asked for it closes."""
    global _mlocked
    if not _mlocked:
        return
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        libc.munlockall()
    except OSError:
        pass
    _mlocked = False


def set_fifo(priority: int, status: RealtimeStatus) -> None:
    """Put the *calling thread* under SCHED_FIFO at ``priority`` (Linux: pid 0 = this thread)."""
    if not hasattr(os, "sched_setscheduler"):
        status.sched_fifo = f"not available on {sys.platform}"
        return
    try:
        lo, hi = os.sched_get_priority_min(os.SCHED_FIFO), os.sched_get_priority_max(os.SCHED_FIFO)
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(max(lo, min(hi, priority))))
        status.sched_fifo = True
    except (PermissionError, OSError) as e:
        status.sched_fifo = f"refused: {e.strerror or e}"


def pin_to_cpus(cpus: set[int], pid: int = 0) -> bool | str:
    """Restrict ``pid`` (0: the calling thread; threads it starts inherit it) to ``cpus``.

    Returns True, or the reason it could not be done. Why: on a kernel built with
    ``preempt=none`` (this machine's default, see docs/rci.md "Timing") a real-time task
    woken onto a CPU where an ordinary task is inside a long system call waits until that
    call ends (0.9 ms measured). Keeping the controller and simula on one CPU makes each
    hand-off a wake-up on the CPU the sender is already running on, where it takes effect
    at once.
    """
    if not hasattr(os, "sched_setaffinity"):
        return f"not available on {sys.platform}"
    try:
        os.sched_setaffinity(pid, cpus)
    except (OSError, ValueError) as e:
        return f"refused: {e}"
    return True


class GCControl:
    """Keeps the cyclic garbage collector out of the control cycles.

    ``freeze`` (default) collects the young generations (the planning level's recent garbage),
    moves every existing object out of the collector's reach (gc.freeze) and raises the
    generation-0 threshold, so collections are rare and short. Not a full collection: its cost
    grows with the whole heap (0.17-0.3 s for a million small dicts holding lists, 2 million objects,
    on a quiet machine here: ``x = [{'a': [i]} for i in range(10**6)]`` then time
    ``gc.collect()``; seconds under load: a notebook or a planner that has loaded SymPy paid it at every control start); garbage
    that was already old stays frozen until the control ends and the heap is unfrozen;
    ``off`` disables the collector during a control (the planning level may call
    ``gc.collect()`` itself); ``leave`` changes nothing. ``restore`` undoes it.

    The collector is process-wide, so the settings are reference counted across every
    GCControl of the process: the first control task to start applies them (one collection),
    later ones find them in place, and only the last to end undoes
    them. A second arm starting or stopping therefore never stalls or unprotects
    another arm's running control.
    """

    _lock = threading.Lock()
    _holders = 0                    # GCControls currently applied
    _saved: tuple | None = None     # the process's settings before the first apply
    _was_enabled = True
    _active_mode = "leave"

    def __init__(self, mode: str = "freeze") -> None:
        if mode not in GC_MODES:
            raise ValueError(f"gc mode must be 'freeze', 'off' or 'leave', not {mode!r}")
        self.mode = mode
        self._applied = False

    def apply(self, status: RealtimeStatus) -> None:
        if self.mode == "leave":            # takes no part in the process's settings
            status.gc = "left as is"
            return
        if self._applied:
            return
        cls = GCControl
        with cls._lock:
            self._applied = True
            cls._holders += 1
            if cls._holders > 1:
                status.gc = f"{cls._active_mode}: already set by another control task"
                return
            cls._saved = gc.get_threshold()
            cls._was_enabled = gc.isenabled()
            cls._active_mode = self.mode
            if self.mode == "freeze":
                gc.collect(1)                # the young generations only (class docstring)
                gc.freeze()
                gc.set_threshold(50_000, 50, 100)
                status.gc = "frozen, gen0 threshold 50000"
            else:
                gc.collect()
                gc.disable()
                status.gc = "disabled during control"

    def restore(self) -> None:
        if not self._applied:
            return
        cls = GCControl
        with cls._lock:
            self._applied = False
            cls._holders -= 1
            if cls._holders > 0 or cls._saved is None:
                return
            gc.set_threshold(*cls._saved)
            if cls._active_mode == "freeze":
                gc.unfreeze()
            if cls._was_enabled:
                gc.enable()
            cls._saved = None
            cls._active_mode = "leave"
