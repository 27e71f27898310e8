"""An RCI session: the A.3 primitives open / control / release / close, in Python.

``Session`` owns the robot link, the ``how`` and ``chg`` records, the control task and the
error delivery to the planning level. Thesis -> Python:

* ``RCIopen()``            -> ``s = Session(url, robot); s.open()``  (or ``with rci.open(...) as s``)
* ``RCIcontrol(f1, f2)``   -> ``s.control(f1, f2)``
* ``RCIrelease(power_off)`` -> ``s.release(power_off)``
* ``RCIclose(power_off)``  -> ``s.close(power_off)``
* ``RCIterminate``         -> ``s.terminate`` (code) and ``s.termination`` (code + detail)
* ``user_hangup``          -> ``s.on_error`` (callable, ``"raise"``, or None = print and exit)
* ``user_interrupt``       -> ``s.on_interrupt``

When the control ends on an error, the control task has already released the arm; the
planning level is then told at once (``rci.lifecycle``: the termination signal, the
primitive guard, Ctrl-C, shared with ``rci.multi``). The default prints
``TERMINATE/ <message> / <reason>`` and exits with status 1; ``on_error="raise"`` raises
``ControlTerminated`` in the main thread wherever it is (the Python form of A.5.5's longjmp).

Every setting of the control cycle is one immutable ``ControlConfig`` (rci.control_config),
validated once here and owned by each control task the session starts.
"""
from __future__ import annotations

import atexit
import os
import threading
import time
from typing import Any, Callable

import numpy as np

from . import codes, protocol
from .checks import Checker, CommandLimits
from .chg import Chg
from .control import ControlTask
from .control_config import ControlConfig
from .exceptions import (AlreadyOpen, BadFunction, ControlInProgress, ControlTerminated, DeviceError,
                         LinkClosed, NoControl, NotOpen, ProtocolError, RobotBusy, RobotRefused, Timeout)
from .how import How
from .lifecycle import Delivery, Lifecycle
from .link import Link, open_link
from .realtime import RealtimeStatus, lock_memory, unlock_memory
from .timing import CycleTiming

#: how long control() waits for an ended control's thread that is past its user functions (s)
FINISH_WAIT = 10.0


class Session:
    """One RCI session with one robot (or simula) over one link.

    Parameters (SI units): ``rate_hz`` sample rate (4..1000 Hz; the thesis's 9/18/36/72 are
    all valid); ``limits`` for the A.5.1 checks: ``"model"`` (from ``models`` and
    ``rci.conversions``), a ``CommandLimits``, or None (range checks off); ``timeout`` s without a
    HOW before R_TIMEOUT (default two periods, at least ``min_timeout``; against a lockstep
    simulator at least ``lockstep_timeout``, since its cycles are not wall-clock time);
    ``overrun`` what late cycles do (docs/rci.md, "Late cycles"): ``"error"`` ends the control
    after ``late_limit`` late cycles in a row (R_OVERRUN when the control functions overran,
    R_CHGLATE when the commands were in time but did not reach the robot in time),
    ``"count"`` only counts them, ``"auto"`` (default) is ``"error"`` against a real-time robot
    and ``"count"`` against a lockstep simulator, where a slow cycle harms nothing;
    ``late_limit`` late cycles in a row that end the control (default None: 3, or 20 ms
    worth of cycles at high rates, like libfranka's 20 lost packets at 1 kHz);
    ``takeover`` take the robot over from a crashed owner whose control the robot's
    watchdog has stopped (docs/protocol.md, "Ownership"); ``realtime`` try SCHED_FIFO at ``priority`` for
    the control thread; ``gc`` ``"freeze"``/``"off"``/``"leave"``; ``lock_memory`` mlockall;
    ``signals`` deliver errors and Ctrl-C through signals when opened in the main thread.

    The control settings are validated once into ``self.config`` (a ``ControlConfig``);
    ``configure(...)`` changes them between controls. ``rate_hz`` is the rate of the control
    in progress (the robot's, from its latest HOW), else the rate the next control starts at.
    """

    def __init__(self, url: str, robot: str = "puma260", *, rate_hz: int = 36,
                 limits: str | CommandLimits | None = "model", timeout: float | None = None,
                 min_timeout: float = 0.02, start_timeout: float = 2.0, overrun: str = "auto",
                 late_limit: int | None = None, lockstep_timeout: float = 0.25, takeover: bool = False,
                 realtime: bool = True, priority: int = 80, gc: str = "freeze",
                 lock_memory: bool = True, switch_interval: float | None = 2e-4,
                 signals: bool = True, watchdog: bool = True, max_commands: int = 16,
                 on_error: Callable[[codes.Termination], Any] | str | None = None,
                 on_interrupt: Callable[[], Any] | None = None, client: str = "rci") -> None:
        self.config = ControlConfig.build(
            rate_hz=rate_hz, limits=limits, timeout=timeout, min_timeout=min_timeout, start_timeout=start_timeout,
            overrun=overrun, late_limit=late_limit, lockstep_timeout=lockstep_timeout, realtime=realtime,
            priority=priority, gc=gc, lock_memory=lock_memory, switch_interval=switch_interval, watchdog=watchdog,
            max_commands=max_commands)
        self.url = url
        self.robot = robot
        self.takeover = takeover
        self.on_error = on_error
        self.on_interrupt = on_interrupt
        self.client = client
        self.lifecycle = Lifecycle(self, signals=signals)
        # state
        self.link: Link | None = None
        self.welcome: protocol.Welcome | None = None
        self.nj = 6
        self.nadc = 16
        self.how = How()
        self.chg = Chg()
        self.q: np.ndarray | None = None          # joint angles of the latest how (rad), when limits are known
        self.checker: Checker | None = None
        self.timing = CycleTiming()
        self.rt_status = RealtimeStatus()
        self.terminate = 0                        # RCIterminate: 0, or the code of the last termination
        self._task: ControlTask | None = None
        # called with the Termination in the control thread, after the implicit release (rci.multi
        # uses it to release the other arms of a workcell at once); must be quick, must not raise
        self.termination_listeners: list[Callable[[codes.Termination], Any]] = []
        # (f1, f2) -> (f1, f2) applied by control(): lets rci.multi put its sample barrier around the
        # functions a layer above (RCCL's Arm) gives to control()
        self.control_wrapper: Callable[[Any, Any], tuple[Any, Any]] | None = None
        self._msg_seq = 0

    # --- small helpers --------------------------------------------------------------
    def next_msg_seq(self) -> int:
        """The next message sequence number (HELLO, START, BYE: docs/protocol.md); the control
        task takes one for START."""
        self._msg_seq = (self._msg_seq + 1) & 0xFFFFFFFF
        return self._msg_seq

    def configure(self, **changes: Any) -> None:
        """Change control settings (the names of ``Session(...)``: ``rate_hz=``, ``timeout=``,
        ``gc=`` ...) for the controls started from now on; validated like the first. Refused
        while a control runs (``record`` changes the recorder of a running control)."""
        if self.in_control:
            raise ControlInProgress("configure(): a control is in progress; release it first")
        if "signals" in changes:
            self.lifecycle.use_signals = bool(changes.pop("signals"))
        self.config = self.config.changed(**changes)

    def timeout_for(self, period: float) -> float:
        """Seconds without a HOW before R_TIMEOUT, for a sample period in s."""
        return self.config.timeout_for(period)

    def late_limit_for(self, rate_hz: float) -> int:
        """Late cycles in a row that end a control at ``rate_hz`` (``ControlConfig.late_limit_for``)."""
        return self.config.late_limit_for(rate_hz)

    @property
    def rate_hz(self) -> int:
        """The sample rate, Hz: the robot's, from the latest HOW, while a control runs; else the
        rate the next control starts at."""
        t = self._task
        return t.rate_hz if t is not None and not t.ended else self.config.rate_hz

    @property
    def lockstep(self) -> bool:
        """True when the robot is a lockstep simulator (known once open)."""
        return self.config.lockstep

    @property
    def recorder(self):
        """The ``rci.recorder.Recorder`` logging every cycle, or None."""
        t = self._task
        return t.config.recorder if t is not None and not t.ended else self.config.recorder

    @property
    def termination(self) -> codes.Termination | None:
        """The termination of the last control that ended on an error (None if it did not)."""
        return self.lifecycle.termination

    @property
    def is_open(self) -> bool:
        return self.link is not None

    @property
    def in_control(self) -> bool:
        """True while a control is in progress (not released, not terminated)."""
        t = self._task
        return t is not None and not t.ended

    @property
    def control_task(self) -> ControlTask | None:
        """The control task of the control in progress, or of the last one (None before any)."""
        return self._task

    def mark_delivered(self) -> None:
        """The termination recorded has been delivered by the caller (a workcell delivers its
        arms' terminations itself): this session will not deliver it again."""
        self.lifecycle.mark_delivered()

    @property
    def period(self) -> float:
        """The sample period, s (1 / ``rate_hz``)."""
        return 1.0 / self.rate_hz

    def record(self, recorder) -> None:
        """Log every control cycle into ``recorder`` (an ``rci.recorder.Recorder``); None stops.
        Takes effect at the next cycle of a running control, and for every later control.
        A recorder made for another joint count than the robot's is refused (ValueError)."""
        if recorder is not None and self.link is not None and getattr(recorder, "nj", self.nj) != self.nj:
            raise ValueError(f"record: the recorder of {recorder.path} holds {recorder.nj} joints, the "
                             f"{self.robot} has {self.nj}: make it with Recorder(..., nj={self.nj})")
        self.config = self.config.changed(recorder=recorder)
        t = self._task
        if t is not None and not t.ended:
            t.use_recorder(recorder)

    # --- A.3 primitives -------------------------------------------------------------
    def open(self) -> "Session":
        """RCIopen: open the link, greet the robot, prepare the control task."""
        with self._primitive():
            if self.link is not None:
                raise AlreadyOpen(f"session with {self.url} is already open")
            # a real-time session's link threads (the Zenoh bus has some) run just above its control thread
            link = open_link(self.url, priority=self.config.realtime.link_priority)
            try:
                link.drain()
                link.send(protocol.HELLO, self.next_msg_seq(),
                          protocol.Hello(self.robot, self.config.rate_hz, self.client, os.getpid(), self.takeover).encode())
                welcome = self._await_welcome(link)
            except (LinkClosed, OSError) as e:
                link.close()
                raise DeviceError(f"{self.url}: link closed while opening the session: {e}") from None
            except BaseException:
                link.close()
                raise
            if welcome.robot != self.robot:
                link.close()
                raise RobotRefused(0, f"asked for robot {self.robot!r}, {self.url} is {welcome.robot!r}")
            self.welcome = welcome
            self.config = self.config.changed(lockstep=welcome.mode == protocol.MODE_LOCKSTEP)
            self.nj, self.nadc = welcome.nj, welcome.nadc
            self.how = How(pos=np.zeros(self.nj, dtype=np.int64), adcr=np.zeros(self.nadc, dtype=np.int64))
            self.how.state = welcome.state
            self.how.rate_hz = welcome.rate_hz
            self.chg = Chg(nj=self.nj)
            limits = self.config.limits
            if limits == "model":
                try:
                    limits = CommandLimits.for_robot(self.robot)
                except BaseException:
                    link.close()
                    raise
            self.checker = Checker(self.nj, self.nadc, limits if isinstance(limits, CommandLimits) else None,
                                   max_commands=self.config.max_commands)
            self.link = link
            if self.config.realtime.lock_memory:
                lock_memory(self.rt_status)
            self.lifecycle.install_signals()
            atexit.register(self._atexit)
            return self

    def _await_welcome(self, link: Link) -> protocol.Welcome:
        start_timeout = self.config.start_timeout
        deadline = time.monotonic() + start_timeout
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                raise Timeout(f"{self.url}: no answer to HELLO within {start_timeout} s (is the robot/simula running?)")
            try:
                frame = link.recv(left)
            except LinkClosed as e:
                raise DeviceError(f"{self.url}: link closed during HELLO: {e}") from None
            except ProtocolError:
                continue        # garbage before the answer: keep looking until the deadline
            if frame is None:
                continue
            if frame.type == protocol.WELCOME:
                return protocol.Welcome.decode(frame.payload)
            if frame.type == protocol.ERROR:
                msg = protocol.ErrorMsg.decode(frame.payload)
                if msg.code == codes.ST_BUSY:
                    raise RobotBusy(msg.code, f"{self.url}: {msg.text}")
                raise RobotRefused(msg.code, msg.text)
            # HOW frames of an earlier program may still be in flight: ignore them

    def control(self, f1: Callable[[], Any] | None = None, f2: Callable[[], Any] | None = None) -> None:
        """RCIcontrol: start control cycles calling f1 (before chg is sent) and f2 (after).

        Either may be None (the thesis's ``dummy``). Returns once the first cycle ran.
        Raises NotOpen, ControlInProgress, BadFunction, Timeout (no HOW from the robot).
        """
        with self._primitive():
            if self.link is None:
                raise NotOpen("control(): the session is not open")
            if self.in_control:
                raise ControlInProgress("control(): a control is already in progress")
            old = self._task
            if old is not None and old.is_alive():
                # a thread still in a user function may never return: 1 s; one past them has
                # released the arm and only restores the process's settings (the collector's,
                # whose next collection can take a second in a large process): wait it out
                old.finished.wait(timeout=1.0 if old.in_user else FINISH_WAIT)
                if old.is_alive():
                    raise ControlInProgress("control(): the previous control function has not returned yet"
                                            if old.in_user else
                                            f"control(): the previous control's thread has not finished "
                                            f"after {FINISH_WAIT:.0f} s")
            for name, f in (("f1", f1), ("f2", f2)):
                if f is not None and not callable(f):
                    raise BadFunction(f"control(): {name} = {f!r} is not callable")
            if self.control_wrapper is not None:
                f1, f2 = self.control_wrapper(f1, f2)
            self.terminate = 0
            self.lifecycle.reset()
            try:
                self.link.drain()
            except LinkClosed as e:
                raise DeviceError(f"{self.url}: {e}") from None
            task = ControlTask(self, self.link, self.config, self.nj, self.nadc, f1, f2)
            self._task = task
            task.start()
            task.started.wait(self.config.start_timeout + 1.0)
            t = self.termination
            if t is not None and t.number == codes.R_TIMEOUT and task.seq is None:
                self.lifecycle.mark_delivered()
                raise Timeout(f"control(): {t.detail}")

    def release(self, power_off: bool = False) -> None:
        """RCIrelease: end the control in progress; arm power off if ``power_off``."""
        with self._primitive():
            if self.link is None:
                raise NotOpen("release(): the session is not open")
            task = self._task
            if task is None or task.ended:
                raise NoControl("release(): no control is in progress")
            task.request_release(power_off)
            self.finish_release(task)

    def finish_release(self, task: ControlTask) -> None:
        """Wait for ``task`` to end after its release was requested; if its thread is stuck in a
        user function, send the release around it. Used by :meth:`release` and by a workcell,
        which asks all its arms first and then waits for each."""
        task.finished.wait(max(1.0, 4 * self.timeout_for(task.period)))
        if not task.ended:
            task.send_release()

    def close(self, power_off: bool = False) -> None:
        """RCIclose: release any control (power off if asked), say BYE, close the link."""
        with self._primitive():
            if self.link is None:
                raise NotOpen("close(): the session is not open")
            was_controlling = self.in_control
            if was_controlling:
                self.release(power_off)
            # after a severe termination the release asked for power off; say it again in BYE in
            # case that release was lost on the way (docs/safety.md)
            severe = self.termination is not None and self.termination.severe
            link = self.link
            try:
                link.send(protocol.BYE, self.next_msg_seq(),
                          protocol.Bye((power_off and was_controlling) or severe).encode())
                deadline = time.monotonic() + 0.5
                while time.monotonic() < deadline:
                    try:
                        frame = link.recv(deadline - time.monotonic())
                    except LinkClosed:
                        break               # the robot (or the link) is gone: nothing to wait for
                    except ProtocolError:
                        continue
                    if frame is None or frame.type == protocol.BYE:
                        break
            except (LinkClosed, OSError):
                pass
            self.link = None
            link.close()
            if self.config.realtime.lock_memory and self.rt_status.mlockall is True:
                unlock_memory()      # mlockall is process-wide: give it back with the session
            self.lifecycle.restore_signals()
            atexit.unregister(self._atexit)

    # --- context manager ------------------------------------------------------------
    def __enter__(self) -> "Session":
        if self.link is None:
            self.open()
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.close_quietly(power_off=exc_type is not None and exc_type is not SystemExit)

    def close_quietly(self, power_off: bool = False) -> None:
        """Release and close whatever state the session is in; never raises (at exit, or a
        workcell closing its arms after one of them failed)."""
        try:
            if self.in_control:
                self.release(power_off)
        except Exception:
            pass
        try:
            if self.link is not None:
                self.close(power_off)
        except Exception:
            link, self.link = self.link, None
            if link is not None:
                link.close()
            self.lifecycle.restore_signals()

    def _atexit(self) -> None:
        self.close_quietly(power_off=False)

    # --- waiting at the planning level --------------------------------------------
    def wait(self, seconds: float | None = None, until: Callable[[], bool] | None = None,
             poll: float = 0.005) -> bool:
        """Block the planning level for ``seconds`` or until ``until()`` is true.

        Returns True if ``until`` became true, False on timeout. A termination of the
        control is delivered (``on_error``) as soon as it happens.
        """
        return self.lifecycle.wait(seconds, until, poll)

    # --- termination delivery (rci.lifecycle) ---------------------------------------
    def control_terminated(self, term: codes.Termination, task: ControlTask) -> None:
        """The control task (its thread or its watchdog) reports the end of its control on an
        error, after the implicit release: record it, tell the listeners, signal the main thread."""
        self.terminate = term.code
        self.lifecycle.termination = term
        for listener in list(self.termination_listeners):
            listener(term)
        self.lifecycle.terminated(term)

    def _deliver(self) -> None:
        self.lifecycle.deliver()

    def delivery(self, t: codes.Termination) -> Delivery:
        """LifecycleHost: what the program is told about ``t``."""
        where = f" (cycle {t.cycle})" if t.cycle >= 0 else ""
        message = f"{t.detail}{where}" if t.detail else f"control ended{where}"
        return Delivery(ControlTerminated(t), t.code, message, t.severe)

    def before_delivery(self, t: codes.Termination) -> None:
        """LifecycleHost: the arm is already released; give the control thread a moment to
        finish, but do not wait for a user function that may never return."""
        task = self._task
        if task is not None and task is not threading.current_thread():
            task.finished.wait(min(0.1, 2 * task.period))

    def shut(self, power_off: bool) -> None:
        """LifecycleHost: release and close whatever state the session is in."""
        self.close_quietly(power_off=power_off)

    def _primitive(self):
        return self.lifecycle.primitive()


def open(url: str, robot: str = "puma260", **options: Any) -> Session:  # noqa: A001 (thesis name)
    """RCIopen as a function: an opened ``Session`` (also usable in a ``with`` block)."""
    return Session(url, robot, **options).open()
