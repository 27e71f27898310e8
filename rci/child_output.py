"""The first lines a child process prints on stdout, read within a deadline: how simula, its
tools and the 3D view announce their addresses to the process that started them."""
from __future__ import annotations

import os
import select
import subprocess
import time


class Silent(Exception):
    """The child printed fewer than the lines wanted: ``exit_code`` is None if the deadline
    passed with the child still running, else the code it exited with."""

    def __init__(self, exit_code: int | None) -> None:
        super().__init__("the deadline passed" if exit_code is None else f"exited with code {exit_code}")
        self.exit_code = exit_code


def first_lines(proc: subprocess.Popen, want: int, timeout: float) -> tuple[list[str], list[str]]:
    """Read ``proc``'s stdout (an unbuffered pipe) until ``want`` whole lines arrived or
    ``timeout`` seconds passed; returns (those lines stripped, any further complete or partial
    lines already read, empty ones dropped). Raises ``Silent`` otherwise; the caller decides
    whether to stop the child."""
    fd = proc.stdout.fileno()
    deadline = time.monotonic() + timeout
    buf = b""
    while buf.count(b"\n") < want:
        ready, _, _ = select.select([fd], [], [], max(0.0, deadline - time.monotonic()))
        if not ready:
            raise Silent(None)
        data = os.read(fd, 4096)
        if not data:
            raise Silent(proc.wait())
        buf += data
    lines = buf.decode("utf-8", "replace").split("\n")
    return [x.strip() for x in lines[:want]], [x for x in lines[want:] if x]
