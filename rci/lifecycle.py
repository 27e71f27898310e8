"""The planning level's side of a control, shared by a session and a workcell: the primitive
guard, signal handling (the termination signal and Ctrl-C) and termination delivery.

A control ends on an error in its control thread, after the implicit release; the
planning level is then told at once, even when blocked in ``wait()``, ``time.sleep`` or
``input()``: the control thread sends ``TERM_SIGNAL`` to the main thread, whose handler
runs the user's ``on_error`` (A.5.5's ``user_hangup``). Delivery waits while a primitive
is in progress (a primitive is never cut in half) and happens when it returns. Without
signals (opened outside the main thread, or ``signals=False``) the next ``wait()`` or
primitive delivers it. Ctrl-C is A.5.3's ``user_interrupt``: ``on_interrupt``, or by
default release with power off, close, print and exit with status 130.

``rci.session.Session`` and ``rci.multi.Workcell`` each hold one ``Lifecycle`` and are its
``LifecycleHost``: they say what a termination means for them (the exception, the
message, how to shut down) and the lifecycle does the rest the same way for both.

The signal handlers are the process's, one pair for every lifecycle with signals on
(two arms opened side by side in one program each get their terminations delivered; a
second session no longer replaces the first one's handler): the termination signal
delivers whatever is waiting in any of them, Ctrl-C interrupts all of them.
"""
from __future__ import annotations

import signal
import threading
import time
from dataclasses import dataclass
from typing import Any, Callable, Iterator, Protocol
from contextlib import contextmanager

from . import codes
from .exceptions import ControlTerminated

TERM_SIGNAL = signal.SIGUSR1   # the thesis used SIGHUP; SIGUSR1 does not collide with terminal hangups

_installed: list["Lifecycle"] = []      # lifecycles whose signals are on, oldest first (main thread only)
_saved_handlers: dict[int, Any] = {}    # the process's handlers before the first of them
_interrupt_pending = False              # Ctrl-C came during a primitive: acted on when it returns


@dataclass(frozen=True)
class Delivery:
    """What the program is told about one termination: the exception ``on_error="raise"``
    raises, the code and message the default handler prints, and whether it was severe
    (the default handler then closes with power off)."""

    error: ControlTerminated
    code: int
    message: str
    severe: bool


class LifecycleHost(Protocol):
    """A session or a workcell, as its lifecycle sees it."""

    on_error: Any                                # callable, "raise", or None (print and exit 1)
    on_interrupt: Callable[[], Any] | None       # None: release, power off, close, exit 130

    def delivery(self, termination: Any) -> Delivery: ...

    def before_delivery(self, termination: Any) -> None: ...

    def shut(self, power_off: bool) -> None: ...

    @property
    def in_control(self) -> bool: ...            # a control of the host is in progress


def run_on_error(on_error: Any, error: ControlTerminated, code: int, message: str, severe: bool,
                 close: Callable[[bool], None], argument: Any) -> None:
    """The one way a control's end on an error reaches the program: ``on_error == "raise"``
    raises ``error``; None (the thesis's default handler) prints ``TERMINATE/ code message``,
    closes (``close(severe)``: power off after a severe error) and exits with status 1; a
    callable is called with ``argument``."""
    if on_error == "raise":
        raise error
    if on_error is None:
        codes.print_terminate_code(code, message)
        close(severe)
        raise SystemExit(1)
    on_error(argument)


class Lifecycle:
    """The primitive guard, the signal handlers and the delivery of terminations of one host."""

    def __init__(self, host: LifecycleHost, *, signals: bool = True,
                 interrupt_text: str = "interrupt") -> None:
        self.host = host
        self.use_signals = signals
        self.interrupt_text = interrupt_text
        self.lock = threading.RLock()
        self.busy = 0                              # primitives in progress (nested)
        self.termination: Any = None               # the termination waiting for, or given, delivery
        self.delivered: Any = None                 # the last termination delivered
        self.event = threading.Event()             # set when a termination waits for delivery
        self._main_ident: int | None = None

    # --- terminations -----------------------------------------------------------------
    def reset(self) -> None:
        """A new control starts: nothing is waiting for delivery."""
        self.termination = None
        self.delivered = None
        self.event.clear()

    def terminated(self, termination: Any) -> None:
        """A control thread reports a termination (after its release): record it and tell the
        main thread (with the termination signal, when signals are on)."""
        self.termination = termination
        self.event.set()
        if self.signals_active and self._main_ident is not None:
            try:
                signal.pthread_kill(self._main_ident, TERM_SIGNAL)
            except (ProcessLookupError, OSError):
                pass

    def mark_delivered(self) -> None:
        """The termination recorded was delivered by someone else (a workcell, for its arms)."""
        self.delivered = self.termination

    def deliver(self) -> None:
        """Run the host's ``on_error`` for a termination not yet delivered, unless a primitive is
        in progress (it is delivered when that returns)."""
        t = self.termination
        if t is None or self.delivered is t or self.busy:
            return
        self.delivered = t
        host = self.host
        host.before_delivery(t)
        d = host.delivery(t)
        run_on_error(host.on_error, d.error, d.code, d.message, d.severe, host.shut, t)

    def deliver_here(self) -> None:
        """Deliver from this thread if it may: the main thread, or any thread without signals
        (with signals the main thread's handler delivers)."""
        if threading.current_thread() is threading.main_thread() or not self.signals_active:
            self.deliver()

    # --- primitives -------------------------------------------------------------------------
    @contextmanager
    def primitive(self) -> Iterator[None]:
        """Around each primitive (open, control, release, close ...): one at a time; a
        termination or Ctrl-C that comes meanwhile is acted on when the outermost one returns."""
        with self.lock:
            self.busy += 1
            try:
                yield
            finally:
                self.busy -= 1
        if self.busy == 0 and threading.current_thread() is threading.main_thread():
            global _interrupt_pending
            if _interrupt_pending and not any(lc.busy for lc in _installed):
                _interrupt_pending = False
                _interrupt_all()
            self.deliver()

    # --- waiting ----------------------------------------------------------------------------
    def wait(self, seconds: float | None, until: Callable[[], bool] | None, poll: float) -> bool:
        """Block the planning level ``seconds`` (None: while a control runs) or until ``until()``;
        True if ``until`` became true. A termination is delivered as soon as it happens."""
        deadline = None if seconds is None else time.monotonic() + seconds
        while True:
            self.deliver_here()
            if until is not None and until():
                return True
            now = time.monotonic()
            if deadline is not None and now >= deadline:
                return False
            if until is None and deadline is None and not self.host.in_control:
                return False
            if self.termination is not None and self.delivered is self.termination:
                # delivered to a handler that returned: keep waiting out the time, quietly
                self.event.clear()
            if until is None and self.termination is None:
                # nothing to poll: sleep in one block until a termination or the deadline, so
                # the planning thread does not keep taking the GIL from the control threads
                # (without a deadline, look again at 10 Hz: another thread may release)
                self.event.wait(0.1 if deadline is None else max(deadline - now, 0.0))
                continue
            step = poll if deadline is None else min(poll, deadline - now)
            time.sleep(max(step, 0.0))

    # --- signals ----------------------------------------------------------------------------
    @property
    def signals_active(self) -> bool:
        return self in _installed

    def install_signals(self) -> None:
        """Take the termination signal and SIGINT for this lifecycle too (main thread only, once,
        if signals are on); the first lifecycle installs the process's handlers."""
        if self in _installed or not self.use_signals or threading.current_thread() is not threading.main_thread():
            return
        self._main_ident = threading.main_thread().ident
        if not _installed:
            _saved_handlers[TERM_SIGNAL] = signal.signal(TERM_SIGNAL, _on_term_signal)
            _saved_handlers[signal.SIGINT] = signal.signal(signal.SIGINT, _on_sigint)
        _installed.append(self)

    def restore_signals(self) -> None:
        """This lifecycle leaves the signals; the last one gives back the handlers it found."""
        if self not in _installed or threading.current_thread() is not threading.main_thread():
            return
        _installed.remove(self)
        if not _installed:
            for sig, old in _saved_handlers.items():
                signal.signal(sig, old if old is not None else signal.SIG_DFL)
            _saved_handlers.clear()

    def handle_interrupt(self) -> None:
        """A.5.3 user_interrupt for this host, or the default: release (power off), close,
        print, exit 130."""
        _interrupt([self])


def _on_term_signal(signum, frame) -> None:
    for lc in list(_installed):
        lc.deliver()


def _on_sigint(signum, frame) -> None:
    global _interrupt_pending
    if any(lc.busy for lc in _installed):
        _interrupt_pending = True        # a primitive is never cut in half
        return
    _interrupt_all()


def _interrupt_all() -> None:
    _interrupt(list(reversed(_installed)))


def _interrupt(lifecycles: list[Lifecycle]) -> None:
    """Ctrl-C: each host's ``on_interrupt``; the hosts without one are released with power off
    and closed, and then the program prints TERMINATE and exits with status 130. With no host
    left (a Ctrl-C that came during the last one's close, kept until that primitive returned),
    the program gets Python's own KeyboardInterrupt: it was dropped before, and a campaign that
    opens one session after another went on as if nothing had been pressed."""
    if not lifecycles:
        raise KeyboardInterrupt
    plain = [lc for lc in lifecycles if lc.host.on_interrupt is None]
    for lc in lifecycles:
        if lc.host.on_interrupt is not None:
            lc.host.on_interrupt()
    if not plain:
        return
    for lc in plain:
        lc.host.shut(True)
    codes.print_terminate_code(codes.make_code(codes.R_INTERRUPT), plain[0].interrupt_text)
    raise SystemExit(130)
