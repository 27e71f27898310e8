"""The RCI control task (thesis Figure 2.2): one thread running the control cycle.

Each cycle: read the robot's HOW frame and check it, fill ``how``, call f1, check and
send ``chg`` (then clear its commands), call f2, record, and wait for the next HOW. Any
failure ends the control with a termination code (A.5.1): the task sends an implicit
release (stop + end, and power off when the error is severe), then tells the session,
which tells the planning level.

A watchdog thread ends the control with R_OVERRUN when a user function has not returned
two periods after its cycle began (an infinite loop in f1 cannot be interrupted in
Python, but the arm can still be released around it).
"""
from __future__ import annotations

import sys
import threading
import time
import traceback
from typing import TYPE_CHECKING, Callable

import numpy as np

from . import codes, protocol
from .checks import Checker, Fault
from .chg import Chg, rate_hz
from .exceptions import ChecksumError, LinkClosed, ProtocolError, SequenceGap
from .how import How
from .realtime import GCControl, RealtimeStatus, set_fifo

if TYPE_CHECKING:  # pragma: no cover
    from .session import Session

ControlFunction = Callable[[], object]


def _describe_exception(e: BaseException) -> str:
    """``Type: message (file:line in function)`` for the innermost user frame."""
    tb = traceback.extract_tb(e.__traceback__)
    where = ""
    if tb:
        fr = tb[-1]
        where = f" ({fr.filename}:{fr.lineno} in {fr.name})"
    return f"{type(e).__name__}: {e}{where}"


class ControlTask(threading.Thread):
    """Runs the control cycles of one control (from RCIcontrol to release or termination)."""

    def __init__(self, session: "Session", f1: ControlFunction | None, f2: ControlFunction | None) -> None:
        super().__init__(name="rci-control", daemon=True)
        self.s = session
        self.f1 = f1
        self.f2 = f2
        self.link = session.link
        self.period = 1.0 / session.rate_hz
        self.release_requested = False
        self.release_power_off = False
        self.started = threading.Event()       # first HOW handled (or failure)
        self.finished = threading.Event()
        self.send_lock = threading.Lock()
        self.ended = False                     # release or termination sent; no more cycles
        self.seq = None                        # seq of the latest HOW
        self.answered = True                   # CHG(seq) sent
        self.in_user = False                   # inside f1 or f2
        self.cycle_start = 0.0
        self.cycles = 0
        self.gc = GCControl(session.gc_mode)
        self.rt = RealtimeStatus()
        self._how_buf = How(pos=np.zeros(session.nj, dtype=np.int64), adcr=np.zeros(session.nadc, dtype=np.int64))
        self._seqcheck = protocol.SequenceChecker()

    # --- helpers ------------------------------------------------------------------
    def _send_chg(self, seq: int, payload: bytes) -> None:
        with self.send_lock:
            if self.ended:
                return
            self.link.send(protocol.CHG, seq, payload)
            self.answered = True

    def terminate(self, code: int, detail: str, *, link_ok: bool = True) -> None:
        """End the control on an error: implicit release, then tell the session. Idempotent."""
        with self.send_lock:
            if self.ended:
                return
            self.ended = True
            if link_ok and self.seq is not None:
                rel = Chg(nj=self.s.nj)
                rel.stop.com = 1
                rel.end.com = 1
                if codes.is_severe(code):
                    rel.power_off.com = 1
                try:
                    self.link.send(protocol.CHG, self.seq, protocol.encode_chg(rel))
                except (LinkClosed, OSError):
                    pass
        self.s._control_terminated(codes.Termination(code, detail, self.seq if self.seq is not None else -1), self)
        self.started.set()

    def request_release(self, power_off: bool) -> None:
        """Planning level: end the control at the next cycle (RCIrelease)."""
        self.release_power_off = power_off
        self.release_requested = True
        self.link.wake()

    def _send_release(self) -> None:
        rel = Chg(nj=self.s.nj)
        rel.end.com = 1
        rel.stop.com = 1
        if self.release_power_off:
            rel.power_off.com = 1
        with self.send_lock:
            if self.ended:
                return
            self.ended = True
            if self.seq is not None:
                try:
                    self.link.send(protocol.CHG, self.seq, protocol.encode_chg(rel))
                except (LinkClosed, OSError):
                    pass

    # --- the thread -----------------------------------------------------------------
    def run(self) -> None:
        s = self.s
        if s.realtime:
            set_fifo(s.priority, self.rt)
        self.rt.mlockall = s.rt_status.mlockall
        saved_interval = sys.getswitchinterval()
        if s.switch_interval:
            sys.setswitchinterval(s.switch_interval)
        self.rt.switch_interval = sys.getswitchinterval()
        self.gc.apply(self.rt)
        s.rt_status = self.rt
        watchdog = threading.Thread(target=self._watchdog, name="rci-watchdog", daemon=True)
        try:
            # the watchdog starts before START, not after: creating a thread under
            # mlockall(MCL_FUTURE) faults in and locks its whole stack (8 MiB by default),
            # which took 1-2 ms and made the first cycles miss their deadline at 1 kHz
            if s.watchdog:
                watchdog.start()
            try:
                self.link.send(protocol.START, s._next_msg_seq(), protocol.Start(s.rate_hz).encode())
            except LinkClosed as e:
                self.terminate(codes.make_code(codes.R_BTEST, codes.F_COMM | codes.F_SEVERE), str(e), link_ok=False)
                return
            self._loop()
        except BaseException as e:  # a bug in RCI itself must still release the arm
            self.terminate(codes.make_code(codes.R_BTEST, codes.F_SEVERE), f"internal error: {_describe_exception(e)}")
        finally:
            self.gc.restore()
            sys.setswitchinterval(saved_interval)
            self.finished.set()
            self.started.set()
            s._control_thread_done(self)

    def _watchdog(self) -> None:
        # at most 20 wake-ups a second: each takes the GIL and forces the control thread to
        # give it up (200 us switch interval); waking every 2 ms doubled the p99 jitter at
        # 1 kHz in bench/rci_loop.py. A function that never returns is caught within
        # 2 periods + 50 ms; one that returns late is caught by the control thread at once.
        interval = max(2 * self.period, 0.05)
        while not self.finished.wait(interval):
            if self.ended:
                return
            # overruns counted only (lockstep simulator): a function that has not returned
            # after 2 s is hung all the same, and the simulator waits for it forever
            limit = 2 * self.period if self.s.overrun == "error" else max(2 * self.period, 2.0)
            if self.in_user and time.monotonic() - self.cycle_start > limit:
                self.terminate(codes.make_code(codes.R_OVERRUN, codes.F_USER),
                               f"user function still running {time.monotonic() - self.cycle_start:.3f} s after its cycle began "
                               f"(period {self.period:.4f} s)")
                return

    def _loop(self) -> None:
        s = self.s
        link = self.link
        how = s.how
        chg = s.chg
        buf = self._how_buf
        checker = s.checker
        checker.reset()
        timing = s.timing
        timing.reset()
        recorder_get = lambda: s.recorder  # noqa: E731  (may be set or cleared while running)
        first_timeout = s.start_timeout
        t_base = None
        seq_base = 0
        robot_over0 = None
        while True:
            if self.ended:
                return
            if self.release_requested:
                self._send_release()
                return
            timeout = first_timeout if not self.started.is_set() else s.timeout_for(self.period)
            t_wait = time.monotonic()
            try:
                frame = link.recv(timeout)
                while frame is None and not self.release_requested and not self.ended \
                        and time.monotonic() - t_wait < timeout:   # a stray wake-up: keep waiting
                    frame = link.recv(timeout - (time.monotonic() - t_wait))
            except ChecksumError as e:
                self.terminate(codes.make_code(codes.R_CHKSUM, codes.F_COMM | codes.F_SEVERE), str(e))
                return
            except LinkClosed as e:
                self.terminate(codes.make_code(codes.R_BTEST, codes.F_COMM | codes.F_SEVERE),
                               f"link lost: {e}", link_ok=False)
                return
            except ProtocolError as e:
                self.terminate(codes.make_code(codes.R_BTEST, codes.F_COMM | codes.F_SEVERE), str(e))
                return
            t_arr = time.monotonic()
            if frame is None:
                if self.release_requested:
                    self._send_release()
                    return
                if self.ended:
                    return
                self.terminate(codes.make_code(codes.R_TIMEOUT, codes.F_COMM | codes.F_SEVERE),
                               f"no HOW from the robot for {timeout:.3f} s")
                return
            if frame.type == protocol.ERROR:
                try:
                    msg = protocol.ErrorMsg.decode(frame.payload)
                    text = f"robot error {msg.code}: {msg.text}"
                except ProtocolError as e:
                    text = f"robot sent an unreadable ERROR frame ({e})"
                self.terminate(codes.make_code(codes.R_ROBOT, codes.F_ROBOT | codes.F_SEVERE), text, link_ok=True)
                return
            if frame.type != protocol.HOW:
                self.terminate(codes.make_code(codes.R_BTEST, codes.F_COMM | codes.F_SEVERE),
                               f"unexpected {frame.name} frame during control")
                return
            # --- read and check the incoming data -----------------------------------
            self.cycle_start = t_arr
            try:
                self._seqcheck.check(frame.seq)
            except SequenceGap as e:
                self.seq = frame.seq
                self.answered = False
                timing.missed += (e.got - e.expected) & 0xFFFFFFFF
                self.terminate(codes.make_code(codes.R_SEQGAP, codes.F_COMM | codes.F_SEVERE), str(e))
                return
            self.seq = frame.seq
            self.answered = False
            try:
                protocol.decode_how(frame.payload, frame.seq, into=buf)
                if buf.nj != s.nj:
                    raise ProtocolError(f"HOW has {buf.nj} joints, session opened with {s.nj}")
            except ProtocolError as e:
                self.terminate(codes.make_code(codes.R_BTEST, codes.F_COMM | codes.F_SEVERE), f"bad HOW frame: {e}")
                return
            buf.received = t_arr
            if buf.rate_hz and buf.rate_hz != round(1.0 / self.period):
                self.period = 1.0 / buf.rate_hz     # the robot keeps the clock: follow its rate
                s.rate_hz = buf.rate_hz
                t_base = None
            if t_base is None:
                t_base, seq_base = t_arr, frame.seq
            if robot_over0 is None:
                robot_over0 = buf.robot_overruns
            lateness = t_arr - (t_base + ((frame.seq - seq_base) & 0xFFFFFFFF) * self.period)
            if buf.robot_overruns != robot_over0:
                timing.missed += (buf.robot_overruns - robot_over0) & 0xFFFFFFFF
                robot_over0 = buf.robot_overruns
                if s.overrun == "error":
                    self.terminate(codes.make_code(codes.R_OVERRUN, codes.F_USER),
                                   f"robot reports a late or missing CHG (robot_overruns = {buf.robot_overruns})")
                    return
            try:
                q = checker.check_how(buf, self.period)
            except Fault as f:
                how.copy_from(buf)
                self.terminate(f.code, f.detail)
                return
            how.copy_from(buf)
            s.q = q
            if not self.started.is_set():
                self.started.set()
            # --- user function 1 ----------------------------------------------------
            t_user = 0.0
            if self.f1 is not None:
                spent = self._call_user(self.f1, "f1")
                if spent is None or self.ended:
                    return
                t_user += spent
            if s.terminate and self._user_terminate():
                return
            # --- check and send chg ------------------------------------------------
            with chg.lock:
                try:
                    new_checking = checker.check_chg(chg, how, q, self.period)
                    payload = protocol.encode_chg(chg)
                except Fault as f:
                    chg.clear()
                    self.terminate(f.code, f.detail)
                    return
                except ValueError as e:
                    chg.clear()
                    self.terminate(codes.make_code(codes.R_NANCMD, codes.F_USER), str(e))
                    return
                new_rate = rate_hz(int(round(float(chg.rate.value)))) if chg.rate.com else None
                chg.clear()
            checker.checking = new_checking
            try:
                self._send_chg(frame.seq, payload)
            except LinkClosed as e:
                self.terminate(codes.make_code(codes.R_BTEST, codes.F_COMM | codes.F_SEVERE),
                               f"link lost: {e}", link_ok=False)
                return
            if new_rate is not None and new_rate != s.rate_hz:
                s.rate_hz = new_rate           # the next HOW comes at the new rate
                self.period = 1.0 / new_rate
                t_base = None
            # --- user function 2 ----------------------------------------------------
            if self.f2 is not None:
                spent = self._call_user(self.f2, "f2")
                if spent is None or self.ended:
                    return
                t_user += spent
            if s.terminate and self._user_terminate():
                return
            # --- bookkeeping -------------------------------------------------------
            t_end = time.monotonic()
            duration = t_end - t_arr
            timing.add(t_arr, lateness, duration, t_user, self.period)
            self.cycles += 1
            rec = recorder_get()
            if rec is not None:
                rec.append(how, payload, lateness, duration)
            if duration > self.period:
                timing.overruns += 1
                if s.overrun == "error":
                    self.terminate(codes.make_code(codes.R_OVERRUN, codes.F_USER),
                                   f"cycle took {duration * 1e3:.2f} ms, period {self.period * 1e3:.2f} ms "
                                   f"(user functions {t_user * 1e3:.2f} ms)")
                    return

    def _call_user(self, fn, name: str) -> float | None:
        """Run one user control function; its duration in seconds, or None if it raised
        (the control is then terminated with R_USERFUNC)."""
        t0 = time.monotonic()
        self.in_user = True
        try:
            fn()
        except Exception as e:
            self.in_user = False  # before terminate, so the watchdog does not see a hung function
            self.terminate(codes.make_code(codes.R_USERFUNC, codes.F_USER), f"in {name}: {_describe_exception(e)}")
            return None
        self.in_user = False
        return time.monotonic() - t0

    def _user_terminate(self) -> bool:
        """A.5.2: the control functions set ``session.terminate`` to force an error."""
        code = int(self.s.terminate)
        if not code:
            return False
        self.terminate(code, "set by a control function (A.5.2)")
        return True
