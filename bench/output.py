"""Where a benchmark's Markdown report goes: printed, and written to a file unless ``-``."""
from __future__ import annotations

from pathlib import Path


def emit(text: str, out: str) -> None:
    """Print ``text`` and write it to ``out`` (its folder made if missing); ``out == "-"`` prints only."""
    print(text)
    if out != "-":
        Path(out).parent.mkdir(parents=True, exist_ok=True)
        Path(out).write_text(text)
