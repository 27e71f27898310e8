"""Progress of long calibration work (reading logs, recording them) as a rich progress bar.

Drawn on stderr only for a person watching: not when stderr is a pipe or a file, not in
CI (``$CI`` set), not under ``-q``. The bar is removed when the work is done, so the
printed tables that follow stay clean.
"""
from __future__ import annotations

import os
import sys
from collections.abc import Callable, Iterable, Iterator
from typing import TextIO, TypeVar

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

T = TypeVar("T")


def wanted(stream: TextIO | None = None) -> bool:
    """True when a progress display helps: ``stream`` (stderr) is a terminal and not in CI."""
    out = stream or sys.stderr
    return out.isatty() and not os.environ.get("CI")


def progress(items: Iterable[T], total: int, label: str, enabled: bool | None = None,
             stream: TextIO | None = None, name: Callable[[T], str] | None = None) -> Iterator[T]:
    """Yield ``items`` while a bar ``label ━━━━  k/total  elapsed`` advances on ``stream``;
    with ``name``, the label says which item is in hand (``label: name(item)``), so a long
    item (a recording of minutes) shows what is running while its elapsed time counts.

    ``enabled=None`` decides with :func:`wanted`; ``False`` (``-q``) never draws.
    """
    out = stream or sys.stderr
    on = wanted(out) if enabled is None else enabled
    if not on:
        yield from items
        return
    # drawn only when wanted (a terminal, or enabled=True): rich must then treat ``out`` as
    # one, whatever its own detection says (force_terminal=False would hide the bar)
    console = Console(file=out, force_terminal=True)
    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn())
    with Progress(*columns, console=console, transient=True) as bar:
        task = bar.add_task(label, total=total)
        for item in items:
            if name is not None:
                bar.update(task, description=f"{label}: {name(item)}")
            yield item
            bar.advance(task)
