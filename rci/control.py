"""The RCI control task (thesis Figure 2.2): one thread running the control cycle.

Each cycle: read the robot's HOW frame and check it, fill ``how``, call f1, check and
send ``chg`` (then clear its commands), call f2, record, and wait for the next HOW. Any
failure ends the control with a termination code (A.5.1): the task sends an implicit
release (stop + end, and power off when the error is severe), then tells the session,
which tells the planning level. Faults are blamed on the party that caused them
(docs/safety.md): the link (severe, a link code), the robot (severe, R_ROBOT), or the
user's control functions (R_USERFUNC, R_BADCMD, R_NANCMD, R_OVERRUN: the arm stops,
power stays as it was).

The task owns its ``ControlConfig`` (rci.control_config: rate, timeouts, lateness policy,
checks, recorder, real-time settings), built by the session; it reaches the session only
through the ``ControlOwner`` protocol below (the records, the timing, the termination).

The rate (docs/protocol.md, "Timing: one cycle"): a HOW's ``rate_hz`` is the rate at which
the robot executes the CHG answering it, so the task's period for a cycle is always the
rate of the cycle's HOW (``ControlTask.rate_hz``, the one place the running rate is kept).
A ``chg.rate`` command changes nothing here when it is sent: the robot runs that CHG at the
old rate, and the next HOW carries the new one.

Lateness policy (docs/rci.md, "Late cycles"): a cycle is late when the robot reports
that its CHG came late or never, or when the control task's own work overran the
period. Isolated late cycles are counted, not fatal; ``late_limit`` late cycles in a
row end the control (against a real-time robot; a lockstep simulator only counts).

A watchdog thread ends the control with R_OVERRUN when a user function has not returned
two periods after its cycle began (an infinite loop in f1 cannot be interrupted in
Python, but the arm can still be released around it).
"""
from __future__ import annotations

import sys
import threading
import time
import traceback
from typing import Any, Callable, Protocol

import numpy as np

from . import codes, protocol
from .checks import Checker, CheckFailed
from .chg import Chg
from .control_config import ControlConfig
from .exceptions import ChecksumError, LinkClosed, ProtocolError, SequenceGap
from .how import How
from .link import Link
from .rate import check_rate_hz
from .realtime import GCControl, RealtimeStatus, set_fifo
from .timing import CycleTiming

ControlFunction = Callable[[], object]


class ControlOwner(Protocol):
    """What a control task reaches of the session that started it (``rci.session.Session``)."""

    how: How                    # refilled in place each cycle
    chg: Chg                    # sent and cleared each cycle
    q: np.ndarray | None        # joint angles of the latest how, rad
    terminate: Any              # A.5.2: a control function sets it to end the control
    checker: Checker
    timing: CycleTiming
    rt_status: RealtimeStatus

    def next_msg_seq(self) -> int: ...

    def control_terminated(self, term: codes.Termination, task: "ControlTask") -> None: ...


class _PrevCycle:
    """What the lateness policy needs to know about the cycle before the current HOW."""

    __slots__ = ("overran", "duration", "user", "send_delay")

    def __init__(self) -> None:
        self.overran = False
        self.duration = self.user = self.send_delay = 0.0


class _RobotClock:
    """The robot's clock as the control task sees it: when each HOW was due, and the robot's
    overrun counter at the last HOW (the CHGs it got late or never since)."""

    __slots__ = ("due", "seq", "robot_over0")

    def __init__(self) -> None:
        self.due: float | None = None          # when the latest HOW was due (host clock, s)
        self.seq = 0
        self.robot_over0: int | None = None

    def read(self, seq: int, t_arr: float, robot_overruns: int, period: float) -> tuple[float, int]:
        """(lateness of HOW ``seq`` in s, CHGs the robot got late or missed since the last HOW).

        ``period`` is the period of the cycle the previous HOW began (its ``rate_hz``): the
        robot sends HOW ``seq`` that long after it, whatever rate HOW ``seq`` announces.
        """
        if self.due is None:
            self.due = t_arr                   # the first HOW sets the schedule
        else:
            self.due += ((seq - self.seq) & 0xFFFFFFFF) * period
        self.seq = seq
        if self.robot_over0 is None:
            self.robot_over0 = robot_overruns
        robot_late = (robot_overruns - self.robot_over0) & 0xFFFFFFFF
        self.robot_over0 = robot_overruns
        return t_arr - self.due, robot_late


def _is_zero(value: object) -> bool:
    """True for a session.terminate that asks for nothing (0, the usual case)."""
    if value is False:
        return True
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool) and value == 0


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

    def __init__(self, owner: ControlOwner, link: Link, config: ControlConfig, nj: int, nadc: int,
                 f1: ControlFunction | None, f2: ControlFunction | None) -> None:
        super().__init__(name="rci-control", daemon=True)
        self.s = owner
        self.config = config
        self.nj = nj
        self.f1 = f1
        self.f2 = f2
        self.link = link
        self.rate_hz = config.rate_hz          # the rate of the cycle in progress: its HOW's (Hz)
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
        self.gc = GCControl(config.realtime.gc)
        self.rt = RealtimeStatus()
        self._how_buf = How(pos=np.zeros(nj, dtype=np.int64), adcr=np.zeros(nadc, dtype=np.int64))
        self._seqcheck = protocol.SequenceChecker()

    @property
    def period(self) -> float:
        """The period of the cycle in progress, s (1 / the rate its HOW announced)."""
        return 1.0 / self.rate_hz

    def use_recorder(self, recorder) -> None:
        """Log the cycles from the next one into ``recorder`` (None: stop); the one setting a
        running control takes (the configuration record is replaced whole, never edited)."""
        self.config = self.config.changed(recorder=recorder)

    # --- helpers ------------------------------------------------------------------
    def _send_chg(self, seq: int, payload: bytes) -> None:
        with self.send_lock:
            if self.ended:
                return
            self.link.send(protocol.CHG, seq, payload)
            self.answered = True

    def terminate(self, code: int, detail: str | Callable[[], str], *, link_ok: bool = True) -> None:
        """End the control on an error: implicit release, then tell the session. Idempotent.

        The release goes out first; ``detail`` may be a function that builds the message
        afterwards (a traceback's description takes a fraction of a millisecond).
        """
        with self.send_lock:
            if self.ended:
                return
            self.ended = True
            if link_ok and self.seq is not None:
                rel = Chg(nj=self.nj)
                rel.stop.com = 1
                rel.end.com = 1
                if codes.is_severe(code):
                    rel.power_off.com = 1
                try:
                    self.link.send(protocol.CHG, self.seq, protocol.encode_chg(rel))
                except (LinkClosed, OSError):
                    pass
        text = detail() if callable(detail) else detail
        self.s.control_terminated(codes.Termination(code, text, self.seq if self.seq is not None else -1), self)
        self.started.set()

    def request_release(self, power_off: bool) -> None:
        """Planning level: end the control at the next cycle (RCIrelease)."""
        self.release_power_off = power_off
        self.release_requested = True
        self.link.wake()

    def send_release(self) -> None:
        """Send the release now (end, stop; power off if asked): the cycle loop's release, and the
        session's fallback when the control thread is stuck in a user function."""
        rel = Chg(nj=self.nj)
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
        rt = self.config.realtime
        if rt.realtime:
            set_fifo(rt.priority, self.rt)
        self.rt.mlockall = s.rt_status.mlockall
        saved_interval = sys.getswitchinterval()
        if rt.switch_interval:
            sys.setswitchinterval(rt.switch_interval)
        self.rt.switch_interval = sys.getswitchinterval()
        self.gc.apply(self.rt)
        s.rt_status = self.rt
        watchdog = threading.Thread(target=self._watchdog, name="rci-watchdog", daemon=True)
        try:
            # the watchdog starts before START, not after: creating a thread under
            # mlockall(MCL_FUTURE) faults in and locks its whole stack (8 MiB by default),
            # which took 1-2 ms and made the first cycles miss their deadline at 1 kHz
            if self.config.watchdog:
                watchdog.start()
            try:
                self.link.send(protocol.START, s.next_msg_seq(), protocol.Start(self.config.rate_hz).encode())
            except LinkClosed as e:
                self.terminate(codes.make_code(codes.R_BTEST, codes.F_COMM | codes.F_SEVERE), str(e), link_ok=False)
                return
            self._loop()
        except BaseException as e:  # a bug in RCI itself must still release the arm
            self.terminate(codes.make_code(codes.R_BTEST, codes.F_SEVERE),
                           lambda e=e: f"internal error: {_describe_exception(e)}")
        finally:
            self.gc.restore()
            sys.setswitchinterval(saved_interval)
            self.finished.set()
            self.started.set()

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
            limit = self.config.user_hang_limit(self.period)
            if self.in_user and time.monotonic() - self.cycle_start > limit:
                self.terminate(codes.make_code(codes.R_OVERRUN, codes.F_USER),
                               f"user function still running {time.monotonic() - self.cycle_start:.3f} s after its cycle began "
                               f"(period {self.period:.4f} s)")
                return

    def _loop(self) -> None:
        """The cycles: wait for a HOW, take it in, f1, answer with the CHG, f2, book-keep."""
        s = self.s
        s.checker.reset()
        timing = s.timing
        timing.reset()
        timing.late_limit = self.config.late_limit_for(self.rate_hz) if self.config.late_policy == "error" else 0
        clock = _RobotClock()
        prev = _PrevCycle()
        self.late_run = 0
        self.run_overran = False
        self.run_slowest = (0.0, 0.0)          # (duration, user time) of the slowest overrun of the run
        while True:
            if self.ended:
                return
            if self.release_requested:
                self.send_release()
                return
            frame = self._receive()
            if frame is None:
                return
            t_arr = time.monotonic()
            if self.seq is not None and frame.seq == self.seq:
                timing.duplicates += 1          # the same HOW twice (the link repeated it): answered already
                continue
            lateness = self._take_how(frame, t_arr, clock, prev)
            if lateness is None:
                return
            # --- user function 1, the CHG, user function 2 -------------------------------
            t_user = 0.0
            if self.f1 is not None:
                spent = self._call_user(self.f1, "f1")
                if spent is None or self.ended:
                    return
                t_user += spent
            if not _is_zero(s.terminate) and self._user_terminate():
                return
            payload = self._answer(frame.seq, t_arr, prev)
            if payload is None:
                return
            if self.f2 is not None:
                spent = self._call_user(self.f2, "f2")
                if spent is None or self.ended:
                    return
                t_user += spent
            if not _is_zero(s.terminate) and self._user_terminate():
                return
            # --- bookkeeping ------------------------------------------------------------
            duration = time.monotonic() - t_arr
            timing.add(t_arr, lateness, duration, t_user, self.period)
            self.cycles += 1
            rec = self.config.recorder         # may be set or cleared while running (use_recorder)
            if rec is not None:
                rec.append(s.how, payload, lateness, duration)
            prev.overran = duration > self.period
            prev.duration, prev.user = duration, t_user
            if prev.overran:
                timing.overruns += 1

    def _receive(self):
        """Wait for the robot's next HOW frame; None if the control ended meanwhile (released,
        or terminated here: a link fault, a timeout, the robot's ERROR, an unexpected frame)."""
        # the HOW that follows a rate command ends the cycle in progress, whose period is still
        # that of its own HOW (the robot runs a CHG at the rate of the HOW it answers)
        config = self.config
        timeout = config.start_timeout if not self.started.is_set() else config.timeout_for(self.period)
        link_fault = codes.make_code(codes.R_BTEST, codes.F_COMM | codes.F_SEVERE)
        t_wait = time.monotonic()
        try:
            frame = self.link.recv(timeout)
            while frame is None and not self.release_requested and not self.ended \
                    and time.monotonic() - t_wait < timeout:   # a stray wake-up: keep waiting
                frame = self.link.recv(timeout - (time.monotonic() - t_wait))
        except ChecksumError as e:
            self.terminate(codes.make_code(codes.R_CHKSUM, codes.F_COMM | codes.F_SEVERE), str(e))
            return None
        except LinkClosed as e:
            self.terminate(link_fault, f"link lost: {e}", link_ok=False)
            return None
        except ProtocolError as e:
            self.terminate(link_fault, str(e))
            return None
        if frame is None:
            if self.release_requested:
                self.send_release()
            elif not self.ended:
                self.terminate(codes.make_code(codes.R_TIMEOUT, codes.F_COMM | codes.F_SEVERE),
                               f"no HOW from the robot for {timeout:.3f} s")
            return None
        if frame.type == protocol.ERROR:
            code = codes.make_code(codes.R_ROBOT, codes.F_ROBOT | codes.F_SEVERE)
            try:
                msg = protocol.ErrorMsg.decode(frame.payload)
                text = f"robot error {msg.code}: {msg.text}"
                code = codes.for_status(msg.code)
            except ProtocolError as e:
                text = f"robot sent an unreadable ERROR frame ({e})"
            self.terminate(code, text, link_ok=True)
            return None
        if frame.type != protocol.HOW:
            self.terminate(link_fault, f"unexpected {frame.name} frame during control")
            return None
        return frame

    def _take_how(self, frame, t_arr: float, clock: "_RobotClock", prev: "_PrevCycle") -> float | None:
        """A new HOW: check its sequence, decode and check it into ``session.how``, follow the
        robot's rate, apply the lateness policy. Its lateness (s) against the robot's clock, or
        None if the control ended on it."""
        s = self.s
        buf = self._how_buf
        self.cycle_start = t_arr
        try:
            self._seqcheck.check(frame.seq)
        except SequenceGap as e:
            self.seq = frame.seq
            self.answered = False
            s.timing.missed += (e.got - e.expected) & 0xFFFFFFFF
            self.terminate(codes.make_code(codes.R_SEQGAP, codes.F_COMM | codes.F_SEVERE), str(e))
            return None
        self.seq = frame.seq
        self.answered = False
        try:
            protocol.decode_how(frame.payload, frame.seq, into=buf)
            if buf.nj != self.nj:
                raise ProtocolError(f"HOW has {buf.nj} joints, session opened with {self.nj}")
            if buf.rate_hz:                    # 0: a robot that does not say (the rate stays)
                check_rate_hz(buf.rate_hz, "its rate_hz")
        except (ProtocolError, ValueError) as e:
            self.terminate(codes.make_code(codes.R_BTEST, codes.F_COMM | codes.F_SEVERE), f"bad HOW frame: {e}")
            return None
        buf.received = t_arr
        # the cycle that just ended ran at the previous HOW's rate; the one this HOW begins runs
        # at the rate it announces (the robot keeps the clock: follow it)
        ended_period = self.period
        if buf.rate_hz:
            self.rate_hz = buf.rate_hz
        lateness, robot_late = clock.read(frame.seq, t_arr, buf.robot_overruns, ended_period)
        s.timing.missed += robot_late
        if self._late(robot_late, prev, lateness):
            return None
        try:
            q = s.checker.check_how(buf, ended_period)
        except CheckFailed as f:
            s.how.copy_from(buf)
            self.terminate(f.code, f.detail)
            return None
        s.how.copy_from(buf)
        s.q = q
        if not self.started.is_set():
            self.started.set()
        return lateness

    def _answer(self, seq: int, t_arr: float, prev: "_PrevCycle") -> bytes | None:
        """Check ``session.chg`` (at the period of HOW ``seq``, the rate the robot executes it
        at, a rate command included), send it as the CHG for HOW ``seq`` and clear its
        commands. The payload sent, or None if the control ended here."""
        s = self.s
        chg = s.chg
        checker = s.checker
        with chg.lock:
            try:
                new_checking = checker.check_chg(chg, s.how, s.q, self.period)
                payload = protocol.encode_chg(chg)
            except CheckFailed as f:
                self._discard_commands(chg)
                self.terminate(f.code, f.detail)
                return None
            except (ValueError, TypeError, AttributeError) as e:
                self._discard_commands(chg)
                self.terminate(codes.make_code(codes.R_BADCMD, codes.F_USER), f"chg: {e}")
                return None
            chg.clear()
        checker.checking = new_checking
        prev.send_delay = time.monotonic() - t_arr
        try:
            self._send_chg(seq, payload)
        except LinkClosed as e:
            self.terminate(codes.make_code(codes.R_BTEST, codes.F_COMM | codes.F_SEVERE),
                           f"link lost: {e}", link_ok=False)
            return None
        return payload

    @staticmethod
    def _discard_commands(chg: Chg) -> None:
        """After a bad chg: drop this cycle's commands and mend any entry user code replaced,
        so the next control of the session starts from a sound record."""
        chg.repair()
        chg.clear()

    def _late(self, robot_late: int, prev: "_PrevCycle", lateness: float) -> bool:
        """Apply the lateness policy at a HOW; True if it ended the control.

        The previous cycle was late if the robot reports CHGs late or missing since the last
        HOW, or if the control task's own work overran the period. ``late_limit`` late cycles
        in a row end the control, blamed on the user's functions if a cycle of the run overran
        (the late cycles after an overrun are its backlog), else on the link (the CHGs were
        computed in time but did not reach the robot in time).
        """
        s = self.s
        timing = s.timing
        late = max(robot_late, 1 if prev.overran else 0)
        if not late:
            self.late_run = 0
            return False
        if self.late_run == 0:
            self.run_overran = False
            self.run_slowest = (0.0, 0.0)
        if prev.overran and prev.duration > self.run_slowest[0]:
            self.run_slowest = (prev.duration, prev.user)
        self.run_overran = self.run_overran or prev.overran      # the backlog of an overrun is the overrun's
        self.late_run += late
        timing.late_cycles += late
        timing.late_run_max = max(timing.late_run_max, self.late_run)
        limit = self.config.late_limit_for(self.rate_hz)
        policy = self.config.late_policy
        timing.late_limit = limit if policy == "error" else 0
        if policy != "error" or self.late_run < limit:
            return False
        period_ms = self.period * 1e3
        if self.run_overran:
            self.terminate(codes.make_code(codes.R_OVERRUN, codes.F_USER),
                           f"{self.late_run} late cycles in a row (limit {limit}), begun or prolonged by control "
                           f"cycles longer than the period; the slowest took {self.run_slowest[0] * 1e3:.2f} ms of a "
                           f"{period_ms:.2f} ms period, {self.run_slowest[1] * 1e3:.2f} ms of it in the control functions")
        else:
            self.terminate(codes.make_code(codes.R_CHGLATE, codes.F_COMM | codes.F_SEVERE),
                           f"{self.late_run} late cycles in a row (limit {limit}): the robot got no CHG in time "
                           f"although the last was sent {prev.send_delay * 1e3:.2f} ms after its HOW "
                           f"(period {period_ms:.2f} ms); this HOW came {lateness * 1e3:.2f} ms after its time: "
                           f"frames lost or delayed between host and robot, or the control thread not scheduled")
        return True

    def _call_user(self, fn, name: str) -> float | None:
        """Run one user control function; its duration in seconds, or None if it raised
        (the control is then terminated with R_USERFUNC). Whatever it raises, SystemExit and
        KeyboardInterrupt included, is the user function's fault, not the link's."""
        t0 = time.monotonic()
        self.in_user = True
        try:
            fn()
        except BaseException as e:  # noqa: BLE001 - sys.exit() in f1 ends the control, not RCI
            self.in_user = False  # before terminate, so the watchdog does not see a hung function
            hint = ""
            if isinstance(e, (SystemExit, KeyboardInterrupt)):
                hint = f" ({type(e).__name__} in a control function ends the control, not the program)"
            self.terminate(codes.make_code(codes.R_USERFUNC, codes.F_USER),
                           lambda e=e: f"in {name}: {_describe_exception(e)}{hint}")
            return None
        self.in_user = False
        return time.monotonic() - t0

    def _user_terminate(self) -> bool:
        """A.5.2: the control functions set ``session.terminate`` to force an error."""
        raw = self.s.terminate
        if isinstance(raw, (int, np.integer)) and not isinstance(raw, bool):
            code = int(raw)
            if code == 0:
                return False
            if 0 < code <= 0xFFFFFFFF:
                self.terminate(code, "set by a control function (A.5.2)")
                return True
        self.terminate(codes.make_code(codes.R_USERFUNC, codes.F_USER),
                       f"s.terminate = {raw!r:.40} set by a control function is not a termination code "
                       f"(A.5.2: a positive integer, codes >= {codes.R_USER_BASE:#x} are the programmer's own)")
        return True
