"""simula's robot side of the RCI link: sessions over TCP, a pty or the Zenoh bus, real-time and lockstep cycles.

One controller at a time owns the arm (docs/protocol.md, "Ownership"): another one is
refused with a BUSY error naming the owner, and the running control is not disturbed; a
crashed owner can be taken over explicitly once the robot's watchdog has stopped its
control. The arm and its state outlive every session, as A.7 asks ("remember its state
from one program to the next"). The protocol is docs/protocol.md (frames from
``rci.protocol``); the control channel is ``rci.simula.control``. Single-threaded: one
``select`` loop serves the link, the control channel and the real-time clock, so a run
is easy to reason about; no socket operation in it blocks.

Safety (docs/safety.md): the release flags of any CHG with a valid checksum are obeyed
whatever its sequence number; a release takes effect when it arrives (real time: a step
computed ahead for the period in progress is rewound to that instant; lockstep: at the
instant of the HOW it answers). A corrupt frame from the owner during a control, its
connection closing, or the watchdog end the control with the arm held and power off.

Why this module is long: it is one state machine, the robot side of docs/protocol.md:
who owns the arm, when a tick happens, and which frame ends a control are decided
together, under one set of invariants (release flags obeyed whatever the sequence, the
watchdog, lockstep pacing); the endpoints (TCP, pty, Zenoh) and their byte pipes are in
listeners/ and the control channel in control.py.
"""
from __future__ import annotations

import gc
from collections import deque
import os
import select
import sys
import time
from dataclasses import dataclass, field

import numpy as np

from .. import codes, protocol
from ..chg import Chg
from ..rate import RateChange, check_rate_hz
from ..exceptions import ProtocolError, VersionError
from ..how import How
from .arm import N_ADC, SimulatedArm
from .listeners import ClientTransport, Listener, open_listener
from .control import ControlChannel
from .tick_trace import TickTrace

SERVER_NAME = "simula 2"
WATCHDOG_CYCLES = 5        # real-time mode: missing CHGs in a row before the arm is stopped
LOCKSTEP_WATCHDOG_S = 3.0  # lockstep: wall-clock seconds without a CHG before the control is ended
SPIN_S = 0.0002            # real-time mode: busy-wait the last 200 us before a tick (jitter)
MAX_PENDING = 8            # connections that have not (yet) been welcomed
PENDING_TIMEOUT_S = 10.0   # a connection that says nothing is closed after this long
LOG_BURST = 5              # diagnostics of one kind per second; the rest are counted
TICK_HISTORY = 256         # HOWs remembered (seq, time sent, joint angles) for the events command


@dataclass
class Client:
    """Protocol state of one connected controller (the owner, or one not yet welcomed)."""

    transport: ClientTransport
    decoder: protocol.FrameDecoder = field(default_factory=protocol.FrameDecoder)
    welcomed: bool = False        # HELLO accepted: this client owns the arm
    running: bool = False         # a control is in progress (START .. end)
    msg_seq: int = 0
    bad_frames: int = 0
    hello: protocol.Hello | None = None
    connected: float = field(default_factory=time.monotonic)
    faulted: bool = False         # the robot itself ended this owner's control (watchdog, corrupt frame)

    def describe(self) -> str:
        h = self.hello
        who = f"pid {h.pid}" if h is not None and h.pid else "pid unknown"
        name = f", program {h.client!r}" if h is not None and h.client else ""
        where = f" at {self.transport.address}" if self.transport.address else ""
        return f"{who}{where}{name}"


class Server:
    """Serves one arm to successive controllers, one owner at a time; call :meth:`serve_forever`."""

    def __init__(self, arm: SimulatedArm, robot: str, *, lockstep: bool = False, verbose: bool = False,
                 rate_hz: int = 36, watchdog: int = WATCHDOG_CYCLES, watchdog_time: float = 0.1,
                 lockstep_watchdog: float = LOCKSTEP_WATCHDOG_S, out=None, err=None) -> None:
        self.arm = arm
        self.robot = robot
        self.lockstep = lockstep
        self.verbose = verbose
        self.rate = check_rate_hz(rate_hz, "simula rate_hz")   # the rate of the period in progress (Hz)
        self.watchdog = watchdog
        self.watchdog_time = watchdog_time
        self.lockstep_watchdog = lockstep_watchdog
        self.out = out or sys.stdout
        self.err = err or sys.stderr
        self.listener: Listener | None = None   # where controllers connect (rci.simula.listeners)
        self.session: Client | None = None      # the owner (or, on a pty, the line's one client)
        self.pending: list[Client] = []         # connections not welcomed (yet)
        self.control: ControlChannel | None = None
        self.seq = 0                  # HOW cycle counter, never restarts (docs/protocol.md)
        self.overruns = 0             # cycles of this control whose CHG was late or missing
        self.missed = 0               # ... in a row (the watchdog's count)
        self.stale = 0                # CHGs for an older cycle, or after the control ended (ignored)
        self.duplicates = 0           # second CHGs for the cycle in progress (ignored)
        self.got_chg = True
        self.next_tick = 0.0
        self.next_report = 1.0
        self.last_idle = time.monotonic()
        self.last_tick_wall = 0.0     # when the latest HOW was sent (real time: the tick)
        self.last_chg_wall = 0.0      # when the latest CHG of the running control came in
        self.stopping = False
        # a rate command of the CHG just executed: that CHG runs at ``rate``; the next HOW
        # carries the new rate and begins the first period at it (_begin_period)
        self._rate_change: RateChange | None = None
        # real-time mode: the next HOW frame, computed as soon as the CHG that decides it is
        # in, so a tick only writes bytes (the arm step and the encoding, ~75 us at 1 kHz,
        # used to sit between the tick and the HOW and added their variation to the jitter)
        self._prepared: tuple[How, bytes] | None = None
        # (arm state before the latest step made for a CHG, that CHG's seq): a release that
        # arrives during that period rewinds the step to the instant it really takes effect
        self._rewind: tuple[tuple, int] | None = None
        self.ticks: deque = deque(maxlen=TICK_HISTORY)     # [seq, wall time sent or None, q]
        self._took_effect = 0.0       # wall-clock instant the arm was brought to by _arm_to_now
        self.events: deque = deque(maxlen=32)              # control endings, newest last
        self._log_counts: dict[str, list] = {}
        trace = os.environ.get("RCI_SIMULA_TRACE")
        self.trace: TickTrace | None = TickTrace(trace) if trace and not lockstep else None

    # --- endpoint ----------------------------------------------------------------------
    def listen(self, kind: str, **options) -> str:
        """Serve controllers at an endpoint of ``kind`` (``tcp``: host, port; ``pty``; ``zenoh``:
        address, priority; rci.simula.listeners); returns the address a controller opens."""
        self.listener = open_listener(kind, **options)
        if self.listener.line is not None:      # a point-to-point line: its one client is there already
            self.session = Client(self.listener.line)
        return self.listener.url

    # --- output --------------------------------------------------------------------------
    def log(self, text: str) -> None:
        print(f"simula: {text}", file=self.err, flush=True)

    def log_limited(self, kind: str, text: str) -> None:
        """At most LOG_BURST lines of one kind per second; the others are counted and summed up."""
        now = time.monotonic()
        entry = self._log_counts.setdefault(kind, [now, 0, 0])     # window start, shown, suppressed
        if now - entry[0] >= 1.0:
            if entry[2]:
                self.log(f"({entry[2]} more '{kind}' messages in the last {now - entry[0]:.1f} s not shown)")
            entry[:] = [now, 0, 0]
        if entry[1] < LOG_BURST:
            entry[1] += 1
            self.log(text)
        else:
            entry[2] += 1

    def _report(self) -> None:
        """-v: joint angles once per simulated second (A.7)."""
        while self.verbose and self.arm.t + 1e-9 >= self.next_report:
            q = " ".join(f"{x:9.3f}" for x in np.degrees(self.arm.q))
            print(f"t={self.next_report:8.1f} s  q(deg) = {q}", file=self.out, flush=True)
            self.next_report += 1.0

    # --- what the control channel shows ----------------------------------------------------
    def owner_info(self) -> dict | None:
        s = self.session
        if s is None or not s.welcomed:
            return None
        h = s.hello
        return {"pid": h.pid if h else 0, "program": h.client if h else "", "address": s.transport.address,
                "running": s.running, "faulted": s.faulted}

    def events_info(self) -> dict:
        """The control endings remembered and the latest HOWs (seq, wall time sent, q in rad)."""
        ticks = [[seq, t, [float(x) for x in q]] for seq, t, q in list(self.ticks)[-64:]]
        return {"events": list(self.events), "ticks": ticks, "stale_chg": self.stale,
                "duplicate_chg": self.duplicates, "now": time.monotonic(),
                "bus": self.listener.info() if self.listener is not None else None}

    # --- frames --------------------------------------------------------------------------
    def _send(self, ftype: int, seq: int, payload: bytes = b"", client: Client | None = None) -> None:
        c = client or self.session
        if c is None:
            return
        if not c.transport.write(protocol.encode_frame(ftype, seq, payload)):
            self._lost(c, "client stopped reading or went away")

    def _send_msg(self, ftype: int, payload: bytes = b"", client: Client | None = None) -> None:
        c = client or self.session
        if c is not None:
            c.msg_seq += 1              # before sending: a failed send drops the session
            self._send(ftype, c.msg_seq - 1, payload, c)

    def _error(self, code: int, text: str, client: Client | None = None) -> None:
        self.log_limited("refusal", text)
        self._send_msg(protocol.ERROR, protocol.ErrorMsg(code, text).encode(), client)

    def _how(self, seq: int) -> How:
        """Sample the arm now: the HOW for cycle ``seq``."""
        smp = self.arm.sample()
        if smp.status:
            self.log_limited("status", f"status {smp.status} ({codes.STATUS_TEXT.get(smp.status, '?')}) at cycle {seq}")
        how = How(pos=smp.pos, adcr=smp.adcr, status=smp.status, state=smp.state, exio=0,
                  inport1=smp.inport1, outport1=smp.outport1,
                  time_ns=int(round(self.arm.t * 1e9)), rate_hz=self._announced_rate(),
                  robot_overruns=self.overruns)
        self.ticks.append([seq, None, self.arm.q.copy()])
        return how

    def _announced_rate(self) -> int:
        """The rate the next HOW carries: the one it begins the period at (Hz)."""
        return self.rate if self._rate_change is None else self._rate_change.hz

    def _begin_period(self) -> None:
        """The HOW that ends the period in progress goes out now: a rate change commanded by the
        CHG of that period takes effect here, so that HOW carries the new rate and the next
        period runs at it (docs/protocol.md, "Timing: one cycle")."""
        change, self._rate_change = self._rate_change, None
        if change is not None:
            self.rate = change.hz

    def _sent(self) -> None:
        """The latest HOW has just been written: remember when (the arm's position at that instant is known)."""
        now = time.monotonic()
        self.last_tick_wall = now
        if self.ticks:
            self.ticks[-1][1] = now

    def _send_how(self) -> None:
        """Sample the arm and send HOW(seq), beginning the next period (at a new rate if one was commanded)."""
        payload = protocol.encode_how(self._how(self.seq))
        self._begin_period()
        self._send(protocol.HOW, self.seq, payload)
        self._sent()

    def _prepare_next(self) -> None:
        """Real-time mode, CHG of this cycle applied: advance the arm to the next tick now.

        The arm's motion from this tick to the next depends only on the commands in hand,
        so it is computed here, while the clock still has most of the period to run; the
        tick then sends the frame at once (re-encoded there only if ``robot_overruns``
        changed meanwhile). The state before the step is kept: a release arriving before
        the tick rewinds to it (``_arm_to_now``).
        """
        self._rewind = (self.arm.save_state(), self.seq)
        if not self.arm.step(1.0 / self.rate, stop=self._input_waiting):
            # a frame came in meanwhile (a release, perhaps): it must not wait for the rest of
            # the step (up to 2 ms at 100 Hz); the tick steps the arm instead, as when no CHG came
            self.arm.restore_state(self._rewind[0])
            self._rewind = None
            return
        seq = (self.seq + 1) & 0xFFFFFFFF
        how = self._how(seq)
        self._prepared = (how, protocol.encode_frame(protocol.HOW, seq, protocol.encode_how(how)))

    def _input_waiting(self) -> bool:
        """True if the owner has sent something not yet read (asked between the substeps of a step)."""
        s = self.session
        if s is None:
            return False
        try:
            return bool(select.select([s.transport], [], [], 0)[0])
        except (ValueError, OSError):
            return False

    # --- ending a control -------------------------------------------------------------------
    def _arm_to_now(self, seq: int | None = None) -> None:
        """Bring the arm to the instant a release takes effect, before it is applied.

        Real time: the wall-clock instant it arrives. A step already made for the period in
        progress (``_prepare_next``) is undone and the arm advanced only by the time that
        really passed since the last tick (at most a period). Lockstep: the instant of the
        HOW the release answers (``seq``); if simula has already stepped past it for that
        HOW's CHG, the step is undone (the controller's computation takes no simulated time,
        so a release right after CHG(n) comes at HOW(n)'s instant, like CHG(n) itself).
        """
        self._took_effect = time.monotonic()
        rewind, self._rewind = self._rewind, None
        if self.lockstep:
            if rewind is not None and seq is not None and rewind[1] == seq:
                self.arm.restore_state(rewind[0])
                self._forget_ticks_after(seq)
            return
        if rewind is not None:
            self.arm.restore_state(rewind[0])
            self._prepared = None
            self._forget_ticks_after(rewind[1])
        dt = min(max(time.monotonic() - self.last_tick_wall, 0.0), 1.0 / self.rate)
        if dt > 0.0:
            self.arm.step(dt)

    def _forget_ticks_after(self, seq: int) -> None:
        """Drop the remembered HOWs of cycles after ``seq`` (a rewound step: the arm never got there)."""
        while self.ticks and 0 < ((self.ticks[-1][0] - seq) & 0xFFFFFFFF) < 0x80000000:
            self.ticks.pop()

    def _end_control(self, cause: str, seq: int, *, power_off: bool = False, flags: str = "") -> None:
        """The control is over: hold every joint (power off if asked) and remember how it ended."""
        s = self.session
        if s is not None:
            s.running = False
        if power_off:
            self.arm.power = False
        self.arm.hold_all()
        self._prepared = None
        self._rewind = None
        self._rate_change = None
        wall, self._took_effect = self._took_effect or time.monotonic(), 0.0
        self.events.append({"cause": cause, "flags": flags, "seq": seq, "wall": wall,
                            "t": self.arm.t, "q": [float(x) for x in self.arm.q], "power": bool(self.arm.power),
                            "overruns": self.overruns})

    def _release(self, chg: Chg, seq: int) -> None:
        """The release flags of a CHG that is not the cycle's answer (stale, duplicate, or late).

        Obeyed whatever its seq (docs/protocol.md): power_off and stop always, end when a
        control is running, power_on only while the control it was sent in still runs.
        """
        s = self.session
        running = s is not None and s.running
        flags = Chg(nj=chg.nj)
        flags.power_off.com, flags.stop.com = chg.power_off.com, chg.stop.com
        flags.power_on.com = chg.power_on.com if running else 0
        flags.end.com = chg.end.com if running else 0
        names = ",".join(n for n in ("end", "stop", "power_on", "power_off") if getattr(flags, n).com)
        if not names:
            return
        if running and flags.end.com:
            self._arm_to_now(seq)
        self.arm.apply(flags, 1.0 / self.rate)
        if flags.end.com:
            self._end_control("release", seq, flags=names)

    def _robot_ends(self, cause: str, status: int, text: str) -> None:
        """The robot itself ends the owner's control (corrupt frame): hold, power off, ERROR."""
        s = self.session
        if s is None or not s.running:
            return
        self._arm_to_now()
        self._end_control(cause, self.seq, power_off=True)
        s.faulted = True
        self.log(f"{text}: arm held, power off")
        self._send_msg(protocol.ERROR, protocol.ErrorMsg(status, text[:255]).encode(), s)

    def _watchdog_fires(self) -> None:
        """No CHG for too long: hold, power off, a last HOW with status 3, no more HOWs."""
        s = self.session
        assert s is not None
        self.arm.hold_all()
        self.arm.power = False
        self.arm.flag(codes.ST_WATCHDOG, f"no CHG for {self.missed} cycles: arm stopped, power off")
        self.log(self.arm.status_text)
        self.seq = (self.seq + 1) & 0xFFFFFFFF
        self._end_control("watchdog", self.seq, power_off=True)
        s.faulted = True
        self._send_how()

    def _lost(self, c: Client, why: str) -> None:
        """A connection is gone (end of file, or it stopped reading)."""
        if c is self.session:
            self._drop(why)
        elif c in self.pending:
            self.pending.remove(c)
            c.transport.close()

    def _drop(self, why: str) -> None:
        """The owner's connection is gone: a running control ends (arm held, power off); wait for the next."""
        s = self.session
        if s is None:
            return
        if s.running:
            self._arm_to_now()
            self._end_control(f"link lost: {why}", self.seq, power_off=True)
            self.log(f"session ended during a control: {why}: arm held, power off")
        elif self.verbose:
            self.log(f"session ended: {why}")
        if self._is_line(s):
            self.session = Client(s.transport)
        else:
            s.transport.close()
            self.session = None

    # --- ownership ---------------------------------------------------------------------------
    def _takeover_refusal(self, owner: Client) -> str | None:
        """None if a takeover of ``owner`` is allowed, else why not."""
        if owner.running:
            return "its control is running (a takeover needs the robot's watchdog to have stopped it)"
        if not owner.faulted:
            return ("it is connected and its last control did not end on a robot-side fault; "
                    "end that program to free the robot")
        return None

    def _read_hello(self, c: Client, f: protocol.Frame) -> protocol.Hello | None:
        """The HELLO of ``f``, or None after an ERROR to ``c`` (unreadable, or for another robot)."""
        try:
            hello = protocol.Hello.decode(f.payload)
        except ProtocolError as exc:
            self._error(codes.ST_BAD_COMMAND, f"bad HELLO: {exc}", c)
            return None
        if hello.robot != self.robot:
            self._error(codes.ST_BAD_COMMAND, f"this simula is a {self.robot}, the program asks for {hello.robot!r}", c)
            return None
        return hello

    def _hello_from(self, c: Client, f: protocol.Frame) -> None:
        """A HELLO from a connection that does not own the arm."""
        hello = self._read_hello(c, f)
        if hello is None:
            return
        owner = self.session
        if owner is not None and owner.welcomed:
            why = self._takeover_refusal(owner) if hello.takeover else "takeover not asked"
            if why is not None:
                text = (f"robot busy: owned by {owner.describe()}"
                        + (f", control running at {self.rate} Hz" if owner.running else "")
                        + (f"; takeover refused: {why}" if hello.takeover else
                           "; one controller at a time (a crashed owner can be taken over once the robot's "
                           "watchdog has stopped it)"))
                self._error(codes.ST_BUSY, text, c)
                self._lost(c, "refused")
                return
            self.log(f"takeover: {c.describe() if c.hello else c.transport.address} replaces {owner.describe()}")
            owner.transport.close()
            self.session = None
        if c in self.pending:
            self.pending.remove(c)
        self.session = c
        self._welcome(c, hello)

    def _welcome(self, c: Client, hello: protocol.Hello) -> None:
        c.welcomed = True
        c.hello = hello
        c.faulted = False
        w = protocol.Welcome(self.robot, self.arm.n, N_ADC, self.rate, self.arm.state,
                             protocol.MODE_LOCKSTEP if self.lockstep else protocol.MODE_REALTIME, SERVER_NAME)
        self._send_msg(protocol.WELCOME, w.encode(), c)

    # --- frames from the owner --------------------------------------------------------------
    def _handle(self, c: Client, f: protocol.Frame) -> None:
        if c is not self.session or not c.welcomed:
            if f.type == protocol.HELLO:
                if c is self.session:            # the pty's client, not welcomed yet
                    self._hello_owner(c, f)
                else:
                    self._hello_from(c, f)
            elif f.type == protocol.BYE:
                self._send_msg(protocol.BYE, f.payload if len(f.payload) == 1 else b"\x00", c)
            else:
                self._error(codes.ST_BAD_COMMAND, f"{f.name} frame before HELLO: ignored", c)
            return
        if f.type == protocol.HELLO:
            self._hello_owner(c, f)
        elif f.type == protocol.START:
            self._start(c, f)
        elif f.type == protocol.CHG:
            self._chg(c, f)
        elif f.type == protocol.BYE:
            try:
                bye = protocol.Bye.decode(f.payload)
            except ProtocolError:
                bye = protocol.Bye(False)
            if c.running:
                # a controller releases before it says BYE: a control still running here lost
                # its release on the way, which may have asked for power off: switch it off
                self._arm_to_now()
                self._end_control("BYE during a control (its release was lost)", self.seq, power_off=True)
                self.log("BYE during a control: its release never came; arm held, power off")
            if bye.power_off:
                self.arm.power = False
                self.arm.hold_all()
            self._send_msg(protocol.BYE, bye.encode(), c)
            c.welcomed = False                   # no longer the owner
            if not self._is_line(c):
                self.session = None
                self.pending.append(c)
        else:
            self._error(codes.ST_BAD_COMMAND, f"unexpected {f.name} frame from the controller", c)

    def _hello_owner(self, c: Client, f: protocol.Frame) -> None:
        """HELLO from the owner itself (a program restarting on the same connection or line)."""
        if c.running:
            self._end_control("new HELLO from the owner", self.seq)
        hello = self._read_hello(c, f)
        if hello is None:
            c.welcomed = False
            return
        self._welcome(c, hello)

    def _start(self, c: Client, f: protocol.Frame) -> None:
        try:
            rate = check_rate_hz(protocol.Start.decode(f.payload).rate_hz, "START rate_hz")
        except (ProtocolError, ValueError) as exc:
            self._error(codes.ST_BAD_COMMAND, f"bad START: {exc}", c)
            return
        self.rate = rate
        self._rate_change = None
        self._prepared = None
        self._rewind = None
        c.running = True
        c.faulted = False
        self.overruns = 0
        self.missed = 0
        self.got_chg = False
        self.last_chg_wall = time.monotonic()
        self.seq = (self.seq + 1) & 0xFFFFFFFF
        self._send_how()
        self.next_tick = time.monotonic() + 1.0 / self.rate

    def _chg(self, c: Client, f: protocol.Frame) -> None:
        try:
            chg = protocol.decode_chg(f.payload)
        except ProtocolError as exc:
            self._bad_frame(c, exc)
            return
        if not (c.running and f.seq == self.seq and not self.got_chg):
            if c.running and f.seq == self.seq:
                self.duplicates += 1
            else:
                self.stale += 1
            self._release(chg, f.seq)
            return
        self.got_chg = True
        self.missed = 0
        self.last_chg_wall = time.monotonic()
        if self.trace is not None:
            self.trace.got_chg(self.last_chg_wall)
        # this CHG runs at the current rate, the period of the HOW it answers; a rate command
        # in it is read here, from the record itself, and begins with the next HOW
        try:
            change = chg.rate_change()
        except ValueError as exc:
            change = None
            self.arm.flag(codes.ST_BAD_COMMAND, str(exc))
        self.arm.apply(chg, 1.0 / self.rate)
        if self.arm.status:
            self.log_limited("status", self.arm.status_text)
        if chg.end.com:
            flags = ",".join(n for n in ("end", "stop", "power_on", "power_off") if getattr(chg, n).com)
            self._end_control("release", f.seq, flags=flags)
            return
        self._rate_change = change
        if self.lockstep:
            self._rewind = (self.arm.save_state(), self.seq)
            self.arm.step(1.0 / self.rate)
            self._report()
            self.seq = (self.seq + 1) & 0xFFFFFFFF
            self.got_chg = False
            self._send_how()
        else:
            t0 = time.monotonic()
            self._prepare_next()
            if self.trace is not None:
                self.trace.prepared(time.monotonic() - t0)

    def _bad_frame(self, c: Client, exc: ProtocolError) -> None:
        c.bad_frames += 1
        who = "controller" if c is self.session else f"connection {c.transport.address}"
        self.log_limited("bad frame", f"bad frame from the {who} dropped: {exc}")
        if isinstance(exc, VersionError) and c is not self.session:
            self._error(codes.ST_BAD_COMMAND, f"{exc}", c)
            return
        if c is self.session and c.running:
            self._robot_ends("corrupt frame from the controller", codes.ST_BAD_FRAME,
                             f"corrupt frame from the controller during a control ({exc})")

    def _on_readable(self, c: Client) -> None:
        data = c.transport.read()
        if data is None:
            self._lost(c, "connection closed")
            return
        if not data:
            return
        c.decoder.feed(data)
        while self._connected(c):
            try:
                f = c.decoder.next_frame()
            except ProtocolError as exc:
                self._bad_frame(c, exc)
                continue
            if f is None:
                break
            self._handle(c, f)

    def _is_line(self, c: Client) -> bool:
        """True for a point-to-point line's client (a pty): it outlives each program on the line."""
        return self.listener is not None and c.transport is self.listener.line

    def _connected(self, c: Client) -> bool:
        return c is self.session or c in self.pending

    # --- real-time clock --------------------------------------------------------------------
    def _poll_client(self) -> None:
        """Read whatever the owner has sent, without waiting."""
        s = self.session
        if s is None:
            return
        try:
            ready, _, _ = select.select([s.transport], [], [], 0)
        except (InterruptedError, ValueError, OSError):
            return
        if ready:
            self._on_readable(s)

    def _wait_for_tick(self) -> None:
        """The last SPIN_S before a tick: busy-wait for accuracy, still reading the link.

        A CHG arriving in this window is taken in (it is in time: the robot looks for it at
        the tick), and, once in, the next HOW is prepared while the clock runs out.
        """
        while True:
            now = time.monotonic()
            if now >= self.next_tick:
                return
            s = self.session
            if s is None or not s.running:
                return
            if not self.got_chg:
                self._poll_client()

    def _tick(self) -> None:
        """Real-time mode, one period elapsed: advance the arm and send the next HOW."""
        s = self.session
        if s is None or not s.running:
            self._prepared = None
            self.next_tick += 1.0 / self.rate
            return
        if not self.got_chg:
            self._poll_client()            # a CHG that came in at the last moment is in time
            s = self.session
            if s is None or not s.running:
                self._prepared = None
                return
        deadline = self.next_tick
        late = not self.got_chg
        if late:
            self.overruns += 1
            self.missed += 1
            if self.missed >= self.watchdog and self.missed / self.rate >= self.watchdog_time:
                self.arm.step(1.0 / self.rate)
                self.next_tick += 1.0 / self.rate
                self._watchdog_fires()
                return
        prepared, self._prepared = self._prepared, None
        self._rewind = None
        if prepared is None:                  # no CHG in time (or none yet): step the arm now
            self.arm.step(1.0 / self.rate)
            self.seq = (self.seq + 1) & 0xFFFFFFFF
            self.got_chg = False
            self._send_how()
            if late and self.arm.hold_current_mode():
                # no command for the period now starting: position targets stay (a place to
                # stop at), motor currents do not (they would keep accelerating the joint)
                self.log_limited("late", f"no CHG for cycle {(self.seq - 1) & 0xFFFFFFFF}: "
                                         f"current-mode joints held")
        else:
            how, frame = prepared             # made by _prepare_next, at the rate it announces
            self._begin_period()
            self.seq = (self.seq + 1) & 0xFFFFFFFF
            self.got_chg = False
            if how.robot_overruns != self.overruns:
                how.robot_overruns = self.overruns
                frame = protocol.encode_frame(protocol.HOW, self.seq, protocol.encode_how(how))
            if not s.transport.write(frame):
                self._drop("client stopped reading or went away")
            self._sent()
        if self.trace is not None:
            self.trace.tick(deadline, time.monotonic(), late)
        self.next_tick += 1.0 / self.rate          # the new rate's period from here on
        self._report()
        now = time.monotonic()
        if now - self.next_tick > 5.0 / self.rate:         # far behind (machine stalled): resync
            self.next_tick = now + 1.0 / self.rate

    def _lockstep_watchdog(self) -> None:
        """Lockstep: a control whose CHG has not come for ``lockstep_watchdog`` s of wall clock is ended."""
        s = self.session
        if (self.lockstep and s is not None and s.running and self.lockstep_watchdog > 0
                and time.monotonic() - self.last_chg_wall > self.lockstep_watchdog):
            self.missed = 1
            self._watchdog_fires()

    def _idle_step(self) -> None:
        """Real-time mode without a running control: the arm keeps living (finishes motions, cools)."""
        now = time.monotonic()
        dt = now - self.last_idle
        self.last_idle = now
        running = self.session is not None and self.session.running
        if self.lockstep or running or dt <= 0:
            return
        if self.arm.quiescent():
            self.arm.coast(dt)                     # nothing moves: skip the 1 kHz physics
        else:
            self.arm.step(min(dt, 0.5))
        self._report()

    # --- main loop -----------------------------------------------------------------------------
    def serve_forever(self, control: ControlChannel | None = None) -> None:
        """Run until :meth:`stop` (or a signal handler calling it)."""
        self.control = control
        if not self.lockstep:
            # collections of the young generation every 700 allocations (the default) came
            # every few hundred ticks and took up to 0.2 ms; most objects of a tick die young,
            # so a far higher threshold costs little per collection and makes them rare
            saved_gc = gc.get_threshold()
            gc.set_threshold(50_000, 50, 100)
        try:
            self._serve(control)
        finally:
            if not self.lockstep:
                gc.set_threshold(*saved_gc)

    def _accept(self) -> None:
        for conn in self.listener.accept():
            if len(self.pending) >= MAX_PENDING:
                self.log_limited("too many connections", f"connection from {conn.address} refused: "
                                                         f"{MAX_PENDING} connections already wait for a HELLO")
                conn.close()
                continue
            self.pending.append(Client(conn))

    def _expire_pending(self) -> None:
        if not self.pending:
            return
        now = time.monotonic()
        for c in [c for c in self.pending if now - c.connected > PENDING_TIMEOUT_S and c.hello is None]:
            self._lost(c, "silent")

    def _control_work(self, control: ControlChannel) -> None:
        """Run queued control-channel commands, never in the last moments before a tick."""
        now = time.monotonic()
        running = self.session is not None and self.session.running
        if not self.lockstep and running:
            if self.next_tick - now < 4 * SPIN_S:
                return
            budget = 1 if self.rate >= 500 else 2
        else:
            budget = 4
        control.service(self, budget)

    def _serve(self, control: ControlChannel | None) -> None:
        while not self.stopping:
            clients = ([self.session] if self.session is not None else []) + self.pending
            rfds: list = [c.transport for c in clients]
            if self.listener is not None and self.listener.fileno() is not None:
                rfds.append(self.listener)
            wfds: list = [c.transport for c in clients if c.transport.wants_write()]
            if control is not None:
                rfds.extend(control.fds())
                wfds.extend(control.write_fds())
            running = self.session is not None and self.session.running
            if not self.lockstep and running:
                timeout = max(0.0, self.next_tick - time.monotonic() - SPIN_S)
            else:
                timeout = 0.05 if not self.lockstep else 0.25
            if control is not None and control.pending():
                timeout = min(timeout, 0.001)
            try:
                ready, writable, _ = select.select(rfds, wfds, [], timeout)
            except InterruptedError:
                continue
            for w in writable:
                c = next((c for c in clients if c.transport is w), None)
                if c is not None:
                    if self._connected(c) and not c.transport.flush():
                        self._lost(c, "client stopped reading")
                elif control is not None:
                    control.on_writable(w)
            for r in ready:                   # the owner first: its end of file frees the robot
                if self.session is not None and r is self.session.transport:
                    self._on_readable(self.session)
            for r in ready:
                if r is self.listener:
                    self._accept()
                elif self.session is not None and r is self.session.transport:
                    continue
                else:
                    c = next((c for c in self.pending if c.transport is r), None)
                    if c is not None:
                        self._on_readable(c)
                    elif control is not None:
                        control.on_readable(r)
            if control is not None and control.pending():
                self._control_work(control)
            self._expire_pending()
            if self.listener is not None:    # what the endpoint refused (floods on the bus): one line each
                for line in self.listener.report():
                    self.log(line)
            if self.lockstep:
                self._lockstep_watchdog()
            else:
                running = self.session is not None and self.session.running
                if running and time.monotonic() >= self.next_tick - SPIN_S:
                    if self.trace is not None:
                        self.trace.cur_spin = time.monotonic()
                    self._wait_for_tick()
                    self._tick()
                    self.last_idle = time.monotonic()
                else:
                    self._idle_step()

    def stop(self) -> None:
        self.stopping = True

    def close(self) -> None:
        if self.trace is not None:
            self.trace.save()
        for c in self.pending:
            c.transport.close()
        if self.session is not None:
            self.session.transport.close()
        if self.listener is not None:
            self.listener.close()
        if self.control is not None:
            self.control.close()
