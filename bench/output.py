"""Where a benchmark's Markdown report goes (printed, and written to a file unless ``-``), and
the progress bar of its long loops."""
from __future__ import annotations

import os
import sys
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import TypeVar

from rich.console import Console
from rich.progress import track

T = TypeVar("T")


def emit(text: str, out: str) -> None:
    """Print ``text`` and write it to ``out`` (its folder made if missing); ``out == "-"`` prints only."""
    print(text)
    if out != "-":
        Path(out).parent.mkdir(parents=True, exist_ok=True)
        Path(out).write_text(text)


def progress(items: Sequence[T], label: str) -> Iterator[T]:
    """Yield ``items`` under a rich progress bar on stderr, drawn only for a person at a
    terminal (not in a pipe, not in CI)."""
    shown = sys.stderr.isatty() and not os.environ.get("CI")
    yield from track(items, description=label, total=len(items), transient=True, disable=not shown,
                     console=Console(stderr=True))
