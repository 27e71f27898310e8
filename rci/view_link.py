"""The link to a live 3D view: a child process fed over a pipe, so that the process being viewed never waits on it.

The view itself is the package ``rcci.view`` (the scene, its process, replay, screenshots, an
RCCL program's live plan); this module is only what a viewed process needs to feed it, the
way ``rci.link`` is what a controller needs to reach a robot: simula (``simula --view``) and
``rcci.view.plan.show`` use it, and it imports nothing of the view.

``ViewFeed("puma260", env=[...], port=8080)`` starts ``python -m rcci.view.process`` (a fresh
interpreter running an ``rcci.view.scene.ArmView``: viser's server, its websocket and the scene
updates live there), waits for the address it prints and keeps it as ``feed.url``.
``feed.follow(sample)`` then calls ``sample()`` from a thread of its own ``hz`` times a
second (30 by default) and writes what it returns, one JSON line, to the child's stdin::

    {"q": [...]}                      joint values (rad or m): move the arm
    {"status": "text"}                the panel's line (Markdown)
    {"paths": {"name": [[points, [r, g, b]], ...]}}   polylines, each name replaced ([] removes)
    {"target": [[4x4]] | null}        the target frame (base frame, m), or none

Why a process and a sampling thread: the viewed process is simula's real-time loop or
an RCI control task. The only work added to it is one short-lived thread waking
``hz`` times a second to copy a few numbers (a snapshot: ``sample`` must only read) and
write them to a pipe; viser's asyncio server, its message encoding and the scene
bookkeeping run in the child, where they cannot hold this interpreter's lock while a
tick is due. When the child is slow the writing thread blocks in ``write`` (which does
not hold the lock) and the next snapshot simply replaces the missed ones; when the child
is gone (the browser tab does not matter, only the child) the thread ends quietly.

Scheduling: the sampling thread holds the interpreter lock for some tens of
microseconds per wake-up. Were it an ordinary thread, a busy machine (a browser drawing
in software, other programs) could preempt it in that window, and a real-time thread
waiting for the lock would wait as long as the scheduler keeps it off the CPU (a
priority inversion). So the thread asks for SCHED_FIFO at ``priority`` 1, the lowest
real-time priority: no ordinary process preempts it while it holds the lock, and every
real-time thread (simula's loop at 70, RCI's control task at 80) still comes first.
Without the privilege it stays an ordinary thread, as everything else in the process
then is. The child is never real-time: it drops any policy it would inherit.

The child ends when its stdin closes (``feed.close()``, or the parent's exit), so it
never outlives the program it shows.
"""
from __future__ import annotations

import atexit
import json
import os
import subprocess
import sys
import threading
import time
from typing import Callable, Sequence

from .child_output import Silent, first_lines

DEFAULT_VIEW_PORT = 8080      # viser's; a busy port moves the view to the next free one (the URL says which)
DEFAULT_HZ = 30.0
START_TIMEOUT = 30.0


class ViewError(RuntimeError):
    """The view's process did not start (viser missing, a bad robot or environment word)."""


FEED_PRIORITY = 1            # SCHED_FIFO priority of the sampling thread (see the module docstring)


def not_realtime() -> None:
    """Drop a SCHED_FIFO/RR policy inherited from a real-time process (this thread only; quietly)."""
    try:
        if os.sched_getscheduler(0) != os.SCHED_OTHER:
            os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    except (AttributeError, OSError):
        pass


def _lowest_realtime(priority: int) -> None:
    """This thread to SCHED_FIFO ``priority`` (0: an ordinary thread); quietly unchanged where not allowed."""
    if priority <= 0:
        not_realtime()
        return
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except (AttributeError, OSError):
        pass


class ViewFeed:
    """A view in a child process; ``url``, ``send(**msg)``, ``follow(sample, hz)``, ``close()``."""

    def __init__(self, robot: str = "puma260", *, env: Sequence[str] = (), host: str = "127.0.0.1",
                 port: int = DEFAULT_VIEW_PORT, title: str = "", start_timeout: float = START_TIMEOUT,
                 collision: bool = False) -> None:
        argv = [sys.executable, "-m", "rcci.view.process", "--robot", robot, "--host", host, "--port", str(port),
                "--title", title] + (["--collision"] if collision else [])
        for spec in env:
            argv += ["--env", spec]
        self.proc = subprocess.Popen(argv, stdin=subprocess.PIPE, stdout=subprocess.PIPE, bufsize=0)
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.errors = 0
        self.url = self._read_url(start_timeout)
        atexit.register(self.close)

    def _read_url(self, timeout: float) -> str:
        try:
            (line,), _ = first_lines(self.proc, 1, timeout)
        except Silent as e:
            if e.exit_code is not None:
                raise ViewError(f"the view exited with code {e.exit_code} before it was ready "
                                "(see its message above)") from None
            self.close()
            raise ViewError(f"the view did not start within {timeout} s") from None
        if not line.startswith("view "):
            self.close()
            raise ViewError(f"the view said {line!r} instead of its address")
        self.proc.stdout.close()          # the child prints nothing more to it
        return line.split(" ", 1)[1]

    def alive(self) -> bool:
        return self.proc.poll() is None

    def send(self, **msg) -> bool:
        """Write one message (blocks while the child's pipe is full); False once the child is gone."""
        try:
            line = (json.dumps(msg, separators=(",", ":"), allow_nan=False) + "\n").encode()
        except ValueError:               # NaN or infinity: not a state worth drawing, dropped
            return True
        with self._lock:
            if self.proc.stdin is None or self.proc.stdin.closed:
                return False
            try:
                self.proc.stdin.write(line)
            except (BrokenPipeError, OSError, ValueError):
                return False
        return True

    def follow(self, sample: Callable[[], dict | None], hz: float = DEFAULT_HZ,
               priority: int = FEED_PRIORITY) -> None:
        """Call ``sample()`` ``hz`` times a second from a daemon thread and send what changed in what it
        returns (None: nothing); the thread runs at SCHED_FIFO ``priority`` where allowed (0: never)."""
        if self._thread is not None:
            raise RuntimeError("this view already follows a sample function")
        period = 1.0 / float(hz)
        sent: dict[str, str] = {}        # the last value sent of each key (JSON): only changes go out

        def run() -> None:
            _lowest_realtime(priority)
            next_t = time.monotonic()
            while not self._stop.is_set():
                try:
                    msg = sample() or {}
                except Exception as exc:   # a sample that fails must not end the program being viewed
                    self.errors += 1
                    if self.errors == 1:
                        print(f"view: the sample function failed ({exc!r}); the view may lag", file=sys.stderr)
                    msg = {}
                changed = {}
                for key, value in msg.items():
                    text = json.dumps(value, separators=(",", ":"))
                    if sent.get(key) != text:
                        sent[key] = text
                        changed[key] = value
                if changed and not self.send(**changed):
                    return
                next_t += period
                delay = next_t - time.monotonic()
                if delay < 0:                    # fell behind (blocked on a slow child): start afresh
                    next_t, delay = time.monotonic(), 0.0
                self._stop.wait(delay)

        self._thread = threading.Thread(target=run, name="view feed", daemon=True)
        self._thread.start()

    def close(self, timeout: float = 3.0) -> None:
        """Stop following, close the child's stdin (it exits) and wait for it; idempotent."""
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout)
        with self._lock:
            if self.proc.stdin is not None and not self.proc.stdin.closed:
                try:
                    self.proc.stdin.close()
                except OSError:
                    pass
        try:
            self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self.proc.terminate()
            try:
                self.proc.wait(timeout)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(timeout)
        atexit.unregister(self.close)

    def __enter__(self) -> "ViewFeed":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
