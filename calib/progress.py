"""A one-line progress bar on stderr for long fits (silent when stderr is not a terminal)."""
from __future__ import annotations

import sys
import time
from collections.abc import Iterable, Iterator
from typing import TextIO, TypeVar

T = TypeVar("T")


def progress(items: Iterable[T], total: int, label: str, enabled: bool | None = None,
             stream: TextIO | None = None) -> Iterator[T]:
    """Yield ``items``, drawing ``label [#####.....] k/total  elapsed`` as they go.

    ``enabled=None`` draws only when the stream is a terminal, so logs and pipes stay
    clean; the bar is erased at the end.
    """
    out = stream or sys.stderr
    on = out.isatty() if enabled is None else enabled
    start = time.monotonic()
    width = 30
    k = 0
    for k, item in enumerate(items, 1):
        yield item
        if on:
            filled = int(width * k / max(total, 1))
            out.write(f"\r{label} [{'#' * filled}{'.' * (width - filled)}] {k}/{total}"
                      f"  {time.monotonic() - start:5.1f} s")
            out.flush()
    if on:
        out.write("\r" + " " * (len(label) + width + 30) + "\r")
        out.flush()
