"""Start and stop a simula process from Python (tests, examples, ``make demo``), race-free.

``with SimulaProcess("-p", lockstep=True) as sim: open_link(sim.url) ...`` starts
``python -m rci.simula --port 0 ...``, waits for the address it prints on stdout line 1
(and the control channel on line 2), and kills the process on exit. ``sim.command(
"state")`` talks to the control channel; ``sim.lines`` collects the rest of stdout (``-v``
output) without ever letting the pipe fill up. ``ToolProcess`` is the same for any tool
that prints its address and control channel that way (``rci.simula.proxy``).
"""
from __future__ import annotations

import json
import socket
import subprocess
import sys
import threading

from ..child_output import Silent, first_lines
from .exceptions import StartError


class ToolProcess:
    """A running tool that prints its address (line 1) and ``control <url>`` (line 2); always stopped."""

    def __init__(self, argv: list[str], start_timeout: float = 30.0) -> None:
        self.argv = argv
        self.start_timeout = start_timeout
        self.proc: subprocess.Popen | None = None
        self.url = ""
        self.control_url = ""
        self.lines: list[str] = []
        self._ctl: socket.socket | None = None
        self._ctl_buf = b""

    def start(self) -> "ToolProcess":
        self.proc = subprocess.Popen(self.argv, stdout=subprocess.PIPE, stdin=subprocess.DEVNULL, bufsize=0)
        want = 1 if "--no-control" in self.argv else 2
        try:
            head, rest = first_lines(self.proc, want, self.start_timeout)
        except Silent as e:
            if e.exit_code is not None:
                raise StartError(f"{self.argv[2]} exited with code {e.exit_code} before printing its address: "
                                 f"{self.argv}") from None
            self.stop()
            raise StartError(f"{self.argv[2]} did not print its address within {self.start_timeout} s: "
                             f"{self.argv}") from None
        self.lines.extend(rest)
        self.url = head[0]
        if len(head) > 1 and head[1].startswith("control "):
            self.control_url = head[1].split(" ", 1)[1]
        threading.Thread(target=self._drain, daemon=True).start()
        return self

    def _drain(self) -> None:
        assert self.proc is not None and self.proc.stdout is not None
        for line in self.proc.stdout:
            self.lines.append(line.decode("utf-8", "replace").rstrip("\n"))

    def command(self, line: str, timeout: float = 5.0) -> dict:
        """Send one control-channel command and return its JSON reply."""
        if not self.control_url:
            raise StartError(f"this {self.argv[2]} has no control channel")
        if self._ctl is None:
            host, port = self.control_url.removeprefix("socket://").rsplit(":", 1)
            self._ctl = socket.create_connection((host, int(port)), timeout=timeout)
        self._ctl.settimeout(timeout)
        self._ctl.sendall((line.strip() + "\n").encode())
        while b"\n" not in self._ctl_buf:
            data = self._ctl.recv(65536)
            if not data:
                raise StartError(f"{self.argv[2]} closed the control channel")
            self._ctl_buf += data
        raw, _, self._ctl_buf = self._ctl_buf.partition(b"\n")
        return json.loads(raw)

    def alive(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    def stop(self, timeout: float = 5.0) -> int | None:
        """Terminate (then kill) the process; returns its exit code."""
        if self._ctl is not None:
            self._ctl.close()
            self._ctl = None
        if self.proc is None:
            return None
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(timeout)
        return self.proc.returncode

    def __enter__(self) -> "ToolProcess":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()


class SimulaProcess(ToolProcess):
    """A running simula (``python -m rci.simula --port 0 ...``)."""

    def __init__(self, *args: str, robot: str = "puma260", lockstep: bool = True, seed: int = 0,
                 pty: bool = False, start_timeout: float = 30.0) -> None:
        argv = [sys.executable, "-m", "rci.simula", "--robot", robot, "--seed", str(seed), *args]
        if lockstep:
            argv.append("--lockstep")
        argv += ["--pty"] if pty else ["--port", "0"]
        super().__init__(argv, start_timeout)
