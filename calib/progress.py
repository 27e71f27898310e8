"""Progress of long calibration work (reading logs, recording a campaign): a rich bar on a
terminal, plain lines elsewhere.

Drawn on stderr, so the tables printed on stdout stay clean. On a terminal (and not in CI,
``$CI`` set) a bar is drawn and removed when the work is done. Elsewhere (stderr a pipe or a
file, CI) :class:`Steps` writes one line per step and, during a long step, a line every
:data:`LINE_EVERY_S` seconds with how far it is (a friction log is minutes of silence
otherwise); :func:`progress` (seconds of reading logs) writes nothing there. ``-q`` turns
both off.
"""
from __future__ import annotations

import os
import sys
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from typing import TextIO, TypeVar

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

T = TypeVar("T")

LINE_EVERY_S = 30.0    # s between the lines that say how far a long step is (not a terminal)
BAR_EVERY_S = 0.25     # s between updates of a step's own bar (terminal)


def wanted(stream: TextIO | None = None) -> bool:
    """True when a progress bar helps: ``stream`` (stderr) is a terminal and not in CI."""
    out = stream or sys.stderr
    return out.isatty() and not os.environ.get("CI")


def mode(enabled: bool | None, stream: TextIO | None = None) -> str:
    """How long work shows its progress on ``stream``: "bar" (a terminal, or ``enabled`` True),
    "lines" (``enabled`` None and not a terminal) or "off" (``enabled`` False: ``-q``)."""
    if enabled is False:
        return "off"
    return "bar" if enabled or wanted(stream) else "lines"


def _bar(out: TextIO) -> Progress:
    # drawn only when wanted (a terminal, or enabled=True): rich must then treat ``out`` as
    # one, whatever its own detection says (force_terminal=False would hide the bar)
    console = Console(file=out, force_terminal=True)
    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn())
    return Progress(*columns, console=console, transient=True)


def progress(items: Iterable[T], total: int, label: str, enabled: bool | None = None,
             stream: TextIO | None = None, name: Callable[[T], str] | None = None) -> Iterator[T]:
    """Yield ``items`` while a bar ``label ━━━━  k/total  elapsed`` advances on ``stream``;
    with ``name``, the label says which item is in hand (``label: name(item)``).

    ``enabled=None`` decides with :func:`wanted`; ``False`` (``-q``) never draws. For work of
    minutes per item, use :class:`Steps` (lines where there is no terminal)."""
    out = stream or sys.stderr
    on = wanted(out) if enabled is None else enabled
    if not on:
        yield from items
        return
    with _bar(out) as bar:
        task = bar.add_task(label, total=total)
        for item in items:
            if name is not None:
                bar.update(task, description=f"{label}: {name(item)}")
            yield item
            bar.advance(task)


class Steps:
    """Progress of ``total`` long steps (the logs of a campaign) on ``stream`` (stderr), in the
    :func:`mode` ``enabled`` gives. Use as a context manager: :meth:`start` each step by name,
    :meth:`within` reports how far the step in hand is (cycles done of its total; cheap, any
    thread, throttled here), :meth:`finish` closes it. "lines" writes ``[k/total] name`` at each
    start and a line every :data:`LINE_EVERY_S` s while a step runs (its share done when
    :meth:`within` was called, else its elapsed time alone)."""

    def __init__(self, total: int, label: str, enabled: bool | None = None,
                 stream: TextIO | None = None, every_s: float | None = None) -> None:
        self.out = stream or sys.stderr
        self.mode = mode(enabled, self.out)
        self.total, self.label = total, label
        self.every_s = LINE_EVERY_S if every_s is None else every_s
        self.k, self.name, self.t0, self.t_step = 0, "", time.monotonic(), time.monotonic()
        self.done, self.of = 0, 0
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._bar: Progress | None = None
        self._task = self._step_task = None
        self._last_bar = 0.0
        self._ticker: threading.Thread | None = None

    def __enter__(self) -> "Steps":
        if self.mode == "bar":
            self._bar = _bar(self.out).__enter__()
            self._task = self._bar.add_task(self.label, total=self.total)
        elif self.mode == "lines":
            self._ticker = threading.Thread(target=self._tick, name="calib-progress", daemon=True)
            self._ticker.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        if self._ticker is not None:
            self._ticker.join()
        if self._bar is not None:
            self._bar.__exit__(*exc)

    def start(self, name: str) -> None:
        """Step ``name`` begins (the k-th of ``total``)."""
        with self._lock:
            self.k, self.name, self.t_step, self.done, self.of = self.k + 1, name, time.monotonic(), 0, 0
        if self._bar is not None:
            self._bar.update(self._task, description=f"{self.label}: {name}")
            if self._step_task is not None:
                self._bar.remove_task(self._step_task)
            self._step_task = None
        elif self.mode == "lines":
            self._line(f"[{self.k}/{self.total}] {name} (started at {self._elapsed()})")

    def within(self, done: int, of: int) -> None:
        """The step in hand has done ``done`` of ``of`` (cycles of a measurement program)."""
        self.done, self.of = done, of
        if self._bar is None:
            return
        now = time.monotonic()
        if now - self._last_bar < BAR_EVERY_S and done < of:
            return
        self._last_bar = now
        with self._lock:
            if self._step_task is None:
                self._step_task = self._bar.add_task(f"  {self.name} (cycles)", total=of)
            self._bar.update(self._step_task, completed=done, total=of)

    def finish(self) -> None:
        """The step in hand is done."""
        if self._bar is not None:
            self._bar.advance(self._task)

    def _elapsed(self) -> str:
        return f"{(time.monotonic() - self.t0) / 60:.1f} min"

    def _line(self, text: str) -> None:
        print(f"{self.label} {text}", file=self.out, flush=True)

    def _tick(self) -> None:
        """Not a terminal: a line every ``every_s`` s about the step in hand."""
        while not self._stop.wait(self.every_s):
            with self._lock:
                if not self.name:
                    continue
                share = f"{100 * self.done / self.of:.0f} % of {self.of} cycles, " if self.of else ""
                text = (f"[{self.k}/{self.total}] {self.name}: {share}"
                        f"{time.monotonic() - self.t_step:.0f} s in this step, {self._elapsed()} in all")
            self._line(text)
