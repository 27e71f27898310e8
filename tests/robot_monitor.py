"""Reference robot-side monitor: the robot's half of docs/protocol.md around a pluggable arm.

This is the "simple communication monitor" of thesis 2.2.4 written from the protocol
page: it answers HELLO, runs cycles after START (real time: by its own clock; lockstep:
one period per CHG), executes CHG commands through an ``Arm`` and enforces the watchdog.
``EchoArm`` is the smallest useful arm: it parrots commands (POS jumps to the target, CUR
drifts the joint in proportion to the current), enough to test a controller end to end.
simula is the full simulator; a real arm's monitor would wrap its hardware in ``Arm``.

A ``fault`` hook can rewrite or drop each outgoing HOW frame (fault-injection tests).

It follows the robot-side safety rules of docs/protocol.md: the release flags of any CHG
are obeyed whatever its seq; a cycle without a CHG holds the joints that were in current
mode (``Arm.hold_current_mode``, where the arm has it); one controller at a time (over TCP
a connection arriving while one is served is answered ERROR ``ST_BUSY`` and closed).
"""
from __future__ import annotations

import os
import select
import socket
import threading
import time
from typing import Callable, Protocol

import numpy as np

from rci import codes, protocol
from rci.chg import CUR, POS, STOP, STOPCAL, Chg
from rci.exceptions import ProtocolError
from rci.how import How


class Arm(Protocol):
    """What the monitor needs from an arm (real or simulated)."""

    name: str
    nj: int
    nadc: int

    def sample(self, how: How) -> None: ...           # fill pos, adcr, state, status
    def apply(self, chg: Chg) -> None: ...            # execute one CHG's commands
    def step(self, dt: float) -> None: ...            # advance dt seconds
    def released(self, power_off: bool) -> None: ...  # control ended
    # optional: def hold_current_mode(self) -> None  - a cycle passed without a CHG


class EchoArm:
    """A kinematic arm that parrots commands (no dynamics); starts calibrated and powered."""

    def __init__(self, name: str = "puma260", nj: int = 6, nadc: int = 16, *,
                 pos0: np.ndarray | None = None, calibrated: bool = True, counts_per_dac_s: float = 10.0) -> None:
        self.name, self.nj, self.nadc = name, nj, nadc
        self.pos = np.zeros(nj) if pos0 is None else np.asarray(pos0, float).copy()
        self.target = self.pos.copy()
        self.current = np.zeros(nj)
        self.mode = np.zeros(nj, dtype=int)   # 0 hold, POS, CUR
        self.state = codes.TP_OK | (codes.CALIB_OK if calibrated else 0)
        self.status = 0
        self.k = counts_per_dac_s
        self.applied: list[Chg] = []
        self.lock = threading.Lock()

    def sample(self, how: How) -> None:
        with self.lock:
            how.pos[:] = np.rint(self.pos).astype(np.int64)
            how.adcr[:] = 0
            how.adcr[: self.nj] = np.clip(np.rint(self.current * 0.75), -2048, 2047).astype(np.int64)
            how.state = self.state
            how.status = self.status

    def apply(self, chg: Chg) -> None:
        with self.lock:
            self.applied.append(chg)
            if chg.power_off.com:
                self.state &= ~codes.POWER_ON
            if chg.stop.com:
                self.mode[:] = 0
                self.current[:] = 0
            if chg.power_on.com:
                self.state |= codes.POWER_ON
            for i, c in enumerate(chg.motion):
                if c.com == POS:
                    self.mode[i], self.target[i] = POS, c.value
                elif c.com == CUR:
                    self.mode[i], self.current[i] = CUR, c.value
                elif c.com in (STOP, STOPCAL):
                    self.mode[i], self.current[i] = 0, 0.0
                    if c.com == STOPCAL:
                        self.pos[i] = c.value

    def step(self, dt: float) -> None:
        with self.lock:
            for i in range(self.nj):
                if self.mode[i] == POS:
                    self.pos[i] = self.target[i]
                elif self.mode[i] == CUR:
                    self.pos[i] += self.k * self.current[i] * dt

    def released(self, power_off: bool) -> None:
        with self.lock:
            self.mode[:] = 0
            self.current[:] = 0
            if power_off:
                self.state &= ~codes.POWER_ON

    def hold_current_mode(self) -> None:
        with self.lock:
            cur = self.mode == CUR
            self.mode[cur] = 0
            self.current[cur] = 0


class _Stream:
    """Bytes over a file descriptor (socket or pty master), non-blocking, with select."""

    def __init__(self, fd: int, closer: Callable[[], None]) -> None:
        self.fd = fd
        self._close = closer
        os.set_blocking(fd, False)

    def read(self, wait: float) -> bytes | None:
        """Bytes available within ``wait`` s; b'' if none; None at end of file."""
        r, _, _ = select.select([self.fd], [], [], max(wait, 0.0))
        if not r:
            return b""
        try:
            data = os.read(self.fd, 65536)
        except BlockingIOError:
            return b""
        except OSError:
            return None
        return data if data else None

    def write(self, data: bytes) -> None:
        view = memoryview(data)
        while view:
            try:
                n = os.write(self.fd, view)
                view = view[n:]
            except BlockingIOError:
                select.select([], [self.fd], [], 0.05)

    def close(self) -> None:
        self._close()


class Monitor:
    """Serves one arm over one byte stream at a time (see docs/protocol.md)."""

    def __init__(self, arm: Arm, *, lockstep: bool = False, watchdog: int = 5, rate_hz: int = 36) -> None:
        self.arm = arm
        self.lockstep = lockstep
        self.watchdog = watchdog
        self.rate_hz = rate_hz
        self.seq = 0
        self.robot_overruns = 0
        self.fault: Callable[[int, bytes], bytes | None] | None = None
        self.stop_event = threading.Event()
        self.cycles = 0
        self.how = How(pos=np.zeros(arm.nj, dtype=np.int64), adcr=np.zeros(arm.nadc, dtype=np.int64))
        self._t0 = time.monotonic_ns()
        self._msg_seq = 0
        self._listener: socket.socket | None = None
        self._owner = ""
        self._newcomers: list[tuple[socket.socket, float]] = []   # accepted, refused once their HELLO came

    # --- transport entry points ---------------------------------------------------
    def serve_fd(self, fd: int, closer: Callable[[], None] | None = None) -> None:
        """Serve a connected fd (a socket's or a pty master's) until EOF or ``stop_event``."""
        stream = _Stream(fd, closer or (lambda: os.close(fd)))
        try:
            self._session(stream)
        except OSError:
            pass            # the controller went away mid-write: wait for the next one
        finally:
            stream.close()

    def serve_tcp(self, host: str = "127.0.0.1", port: int = 0, ready: Callable[[int], None] | None = None) -> None:
        """Listen on host:port (0 = any free port; ``ready(port)`` is called) and serve connections in turn."""
        srv = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        srv.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        srv.bind((host, port))
        srv.listen(4)
        srv.settimeout(0.05)
        self._listener = srv
        if ready is not None:
            ready(srv.getsockname()[1])
        try:
            while not self.stop_event.is_set():
                try:
                    conn, _ = srv.accept()
                except socket.timeout:
                    continue
                conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                self._owner = "%s:%d" % conn.getpeername()[:2]
                self.serve_fd(conn.fileno(), conn.close)
                for late, _ in self._newcomers:      # arrived while it was served: refused all the same
                    self._refuse(late)
                self._newcomers = []
        finally:
            srv.close()

    # --- the protocol -----------------------------------------------------------
    def _send(self, stream: _Stream, ftype: int, seq: int, payload: bytes) -> None:
        data = protocol.encode_frame(ftype, seq, payload)
        if ftype == protocol.HOW and self.fault is not None:
            data = self.fault(seq, data)
            if data is None:
                return
        stream.write(data)

    def _msg(self) -> int:
        self._msg_seq += 1
        return self._msg_seq

    def _session(self, stream: _Stream) -> None:
        dec = protocol.FrameDecoder()
        running = False
        period = 1.0 / self.rate_hz
        next_t = 0.0
        answered = True
        missing = 0
        change = None          # a rate command: its CHG runs at the old rate, the next HOW carries the new
        while not self.stop_event.is_set():
            self._refuse_newcomers()
            if running and not self.lockstep:
                wait = next_t - time.monotonic()
            else:
                wait = 0.05
            frame = None
            try:
                frame = dec.next_frame()
            except ProtocolError:
                continue
            if frame is None:
                data = stream.read(max(wait, 0.0))
                if data is None:
                    return
                if data:
                    dec.feed(data)
                    continue
            if frame is None:
                if running and not self.lockstep and time.monotonic() >= next_t:
                    # a cycle boundary: account for the previous CHG, then start a new cycle
                    if not answered:
                        self.robot_overruns += 1
                        missing += 1
                        hold = getattr(self.arm, "hold_current_mode", None)
                        if hold is not None:
                            hold()             # no command for this period: no motor current either
                        if missing >= self.watchdog:
                            self.arm.released(False)
                            running = False
                            self._send_how(stream, watchdog=True)
                            continue
                    self.arm.step(period)
                    if change is not None:
                        self.rate_hz, period, change = change.hz, change.period, None
                    next_t += period
                    self._send_how(stream)
                    answered = False
                continue
            t = frame.type
            if t == protocol.HELLO:
                try:
                    hello = protocol.Hello.decode(frame.payload)
                except ProtocolError as e:
                    self._send(stream, protocol.ERROR, self._msg(), protocol.ErrorMsg(codes.ST_BAD_COMMAND, str(e)).encode())
                    continue
                if hello.robot != self.arm.name:
                    self._send(stream, protocol.ERROR, self._msg(),
                               protocol.ErrorMsg(codes.ST_BAD_COMMAND, f"this is {self.arm.name!r}, not {hello.robot!r}").encode())
                    continue
                running = False
                self.arm.sample(self.how)
                w = protocol.Welcome(self.arm.name, self.arm.nj, self.arm.nadc, self.rate_hz, self.how.state,
                                     protocol.MODE_LOCKSTEP if self.lockstep else protocol.MODE_REALTIME, "tests/robot_monitor.py")
                self._send(stream, protocol.WELCOME, self._msg(), w.encode())
            elif t == protocol.START:
                st = protocol.Start.decode(frame.payload)
                self.rate_hz = st.rate_hz
                period = 1.0 / st.rate_hz
                running, answered, missing, change = True, False, 0, None
                next_t = time.monotonic() + period
                self._send_how(stream)
            elif t == protocol.CHG:
                chg = protocol.decode_chg(frame.payload)
                current = frame.seq == self.seq and running and not answered
                if current:
                    answered, missing = True, 0
                    self._apply(chg)
                    change = chg.rate_change()
                elif chg.end.com or chg.stop.com or chg.power_off.com:
                    safety = Chg(nj=chg.nj)
                    safety.end.com, safety.stop.com, safety.power_off.com = chg.end.com, chg.stop.com, chg.power_off.com
                    self._apply(safety)
                else:
                    self.robot_overruns += 1
                if chg.end.com:
                    running = False
                    self.arm.released(bool(chg.power_off.com))
                    continue
                if current and self.lockstep and running:
                    self.arm.step(period)
                    if change is not None:
                        self.rate_hz, period, change = change.hz, change.period, None
                    self._send_how(stream)
                    answered = False
            elif t == protocol.BYE:
                bye = protocol.Bye.decode(frame.payload)
                running = False
                self.arm.released(bye.power_off)
                self._send(stream, protocol.BYE, self._msg(), frame.payload)

    def _refuse_newcomers(self) -> None:
        """One controller at a time: a connection arriving while one is served gets ERROR(ST_BUSY).

        The refusal answers the newcomer's HELLO (as simula's does): sent before it, it could
        reach a controller that still discards stale input before greeting. Never blocks the
        served control: a newcomer is looked at again each cycle until its HELLO is there.
        """
        srv = self._listener
        if srv is None:
            return
        try:
            ready, _, _ = select.select([srv], [], [], 0)
            if ready:
                conn, _ = srv.accept()
                self._newcomers.append((conn, time.monotonic()))
        except OSError:
            pass
        if not self._newcomers:
            return
        socks = [c for c, _ in self._newcomers]
        try:
            readable, _, _ = select.select(socks, [], [], 0)
        except OSError:
            readable = socks
        now = time.monotonic()
        waiting = []
        for conn, since in self._newcomers:
            if conn in readable or now - since > 2.0:
                self._refuse(conn)
            else:
                waiting.append((conn, since))
        self._newcomers = waiting

    def _refuse(self, conn: socket.socket) -> None:
        try:
            msg = protocol.ErrorMsg(codes.ST_BUSY, f"robot busy: owned by the controller at {self._owner}; "
                                                   f"one controller at a time")
            conn.sendall(protocol.encode_frame(protocol.ERROR, 0, msg.encode()))
            # read what the newcomer sent (its HELLO) before closing: a socket closed with
            # unread data resets the connection, and the reset can overtake the refusal
            conn.shutdown(socket.SHUT_WR)
            conn.settimeout(0.2)
            while conn.recv(4096):
                pass
        except OSError:
            pass
        conn.close()

    def _apply(self, chg: Chg) -> None:
        self.arm.apply(chg)

    def _send_how(self, stream: _Stream, watchdog: bool = False) -> None:
        """Sample the arm and send HOW with the next sequence number."""
        self.seq = (self.seq + 1) & 0xFFFFFFFF
        self.cycles += 1
        h = self.how
        self.arm.sample(h)
        if watchdog:
            h.status = codes.ST_WATCHDOG
        h.time_ns = time.monotonic_ns() - self._t0
        h.rate_hz = self.rate_hz
        h.robot_overruns = self.robot_overruns
        self._send(stream, protocol.HOW, self.seq, protocol.encode_how(h))
