"""simula's robot side of the RCI link: sessions over TCP or a pty, real-time and lockstep cycles.

One client (control program) at a time drives the arm; the arm and its state outlive
every session, as A.7 asks ("remember its state from one program to the next"). The
protocol is docs/protocol.md (frames from ``rci.protocol``); the test control channel
is ``rci.simula.control``. Single-threaded: one ``select`` loop serves the link, the
control channel and the real-time clock, so a run is easy to reason about.
"""
from __future__ import annotations

import errno
import gc
import os
import select
import socket
import sys
import time
import tty
from dataclasses import dataclass, field

import numpy as np

from .. import codes, protocol
from ..chg import rate_hz as chg_rate_hz
from ..exceptions import ProtocolError
from ..how import How
from .arm import N_ADC, Arm
from .control import ControlChannel

SERVER_NAME = "simula 1"
WATCHDOG_CYCLES = 5        # real-time mode: missing CHGs in a row before the arm is stopped
SPIN_S = 0.0002            # real-time mode: busy-wait the last 200 us before a tick (jitter)


class TickTrace:
    """Real-time mode: per-tick wall-clock timestamps (time.monotonic, shared with the controller).

    Enabled by the environment variable ``RCI_SIMULA_TRACE=<file.npz>``; written when the
    server closes. One row per tick: ``deadline`` (the tick's scheduled time), ``sent`` (its
    HOW written), ``chg`` (the CHG answering that HOW read, 0 if none in time), ``late`` (1 if
    the tick found no CHG for the previous HOW), ``spin`` (when the busy-wait before the tick
    began: a late value means the select() wake-up was late), ``prep`` (seconds spent
    preparing the next HOW after the CHG came in). Compare with the controller's
    ``CycleTiming.arrival`` to split a late cycle between the two processes and the link.
    """

    def __init__(self, path: str, capacity: int = 1 << 18) -> None:
        self.path = path
        self.deadline = np.zeros(capacity)
        self.sent = np.zeros(capacity)
        self.chg = np.zeros(capacity)
        self.late = np.zeros(capacity, dtype=np.int8)
        self.spin = np.zeros(capacity)
        self.prep = np.zeros(capacity)
        self.cur_spin = 0.0
        self.n = 0
        self.capacity = capacity

    def tick(self, deadline: float, sent: float, late: bool) -> None:
        if self.n < self.capacity:
            self.deadline[self.n], self.sent[self.n], self.late[self.n] = deadline, sent, late
            self.spin[self.n] = self.cur_spin
            self.n += 1

    def got_chg(self, t: float) -> None:
        if 0 < self.n <= self.capacity:
            self.chg[self.n - 1] = t

    def prepared(self, seconds: float) -> None:
        if 0 < self.n <= self.capacity:
            self.prep[self.n - 1] = seconds

    def save(self) -> None:
        n = self.n
        np.savez(self.path, deadline=self.deadline[:n], sent=self.sent[:n], chg=self.chg[:n],
                 late=self.late[:n], spin=self.spin[:n], prep=self.prep[:n])


class Transport:
    """A byte pipe to one client: ``fileno``, ``read``, ``write``, ``close``."""

    def fileno(self) -> int:
        raise NotImplementedError

    def read(self) -> bytes:
        raise NotImplementedError

    def write(self, data: bytes) -> bool:
        raise NotImplementedError

    def close(self) -> None:
        pass


class SocketTransport(Transport):
    def __init__(self, sock: socket.socket) -> None:
        self.sock = sock
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        sock.settimeout(2.0)        # a client that stops reading must not freeze the robot

    def fileno(self) -> int:
        return self.sock.fileno()

    def read(self) -> bytes:
        try:
            return self.sock.recv(65536)
        except (ConnectionError, socket.timeout, OSError):
            return b""

    def write(self, data: bytes) -> bool:
        try:
            self.sock.sendall(data)
            return True
        except (OSError, socket.timeout):
            return False

    def close(self) -> None:
        try:
            self.sock.close()
        except OSError:
            pass


class PtyTransport(Transport):
    """The master side of a pseudo-terminal; the controller opens the slave path with pyserial."""

    def __init__(self) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)              # no echo, no line discipline: a byte pipe
        os.set_blocking(self.master, False)
        self.path = os.ttyname(self.slave)  # the slave stays open so a closing client gives no EIO

    def fileno(self) -> int:
        return self.master

    def read(self) -> bytes:
        try:
            return os.read(self.master, 65536)
        except BlockingIOError:
            return b""
        except OSError:
            return b""

    def write(self, data: bytes) -> bool:
        try:
            os.write(self.master, data)
            return True
        except BlockingIOError:
            return True             # nobody reading: the frame is dropped, like a serial line
        except OSError as exc:
            return exc.errno in (errno.EIO, errno.EAGAIN)

    def close(self) -> None:
        for fd in (self.master, self.slave):
            try:
                os.close(fd)
            except OSError:
                pass


@dataclass
class Client:
    """Protocol state of the connected controller."""

    transport: Transport
    decoder: protocol.FrameDecoder = field(default_factory=protocol.FrameDecoder)
    welcomed: bool = False
    running: bool = False
    msg_seq: int = 0
    bad_frames: int = 0


class Server:
    """Serves one arm to successive clients; call :meth:`serve_forever`."""

    def __init__(self, arm: Arm, robot: str, *, lockstep: bool = False, verbose: bool = False,
                 rate_hz: int = 36, watchdog: int = WATCHDOG_CYCLES, watchdog_time: float = 0.1,
                 out=None, err=None) -> None:
        self.arm = arm
        self.robot = robot
        self.lockstep = lockstep
        self.verbose = verbose
        self.rate = rate_hz
        self.watchdog = watchdog
        self.watchdog_time = watchdog_time
        self.out = out or sys.stdout
        self.err = err or sys.stderr
        self.listener: socket.socket | None = None
        self.pty: PtyTransport | None = None
        self.session: Client | None = None
        self.control: ControlChannel | None = None
        self.seq = 0                  # HOW cycle counter, never restarts (docs/protocol.md)
        self.overruns = 0
        self.missed = 0
        self.got_chg = True
        self.next_tick = 0.0
        self.next_report = 1.0
        self.last_idle = time.monotonic()
        self.stopping = False
        self._pending_rate = rate_hz
        # real-time mode: the next HOW frame, computed as soon as the CHG that decides it is
        # in, so a tick only writes bytes (the arm step and the encoding, ~75 us at 1 kHz,
        # used to sit between the tick and the HOW and added their variation to the jitter)
        self._prepared: tuple[How, bytes] | None = None
        trace = os.environ.get("RCI_SIMULA_TRACE")
        self.trace: TickTrace | None = TickTrace(trace) if trace and not lockstep else None

    # --- endpoints ----------------------------------------------------------------------
    def listen_tcp(self, host: str, port: int) -> str:
        """Listen for controllers; returns the ``socket://host:port`` URL."""
        s = socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET, socket.SOCK_STREAM)
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        s.bind((host, port))
        s.listen(4)
        self.listener = s
        return f"socket://{host}:{s.getsockname()[1]}"

    def open_pty(self) -> str:
        """Serve a pseudo-terminal; returns the device path a controller opens."""
        self.pty = PtyTransport()
        self.session = Client(self.pty)
        return self.pty.path

    # --- output --------------------------------------------------------------------------
    def log(self, text: str) -> None:
        print(f"simula: {text}", file=self.err, flush=True)

    def _report(self) -> None:
        """-v: joint angles once per simulated second (A.7)."""
        while self.verbose and self.arm.t + 1e-9 >= self.next_report:
            q = " ".join(f"{x:9.3f}" for x in np.degrees(self.arm.q))
            print(f"t={self.next_report:8.1f} s  q(deg) = {q}", file=self.out, flush=True)
            self.next_report += 1.0

    # --- frames --------------------------------------------------------------------------
    def _send(self, ftype: int, seq: int, payload: bytes = b"") -> None:
        s = self.session
        if s is None:
            return
        if not s.transport.write(protocol.encode_frame(ftype, seq, payload)):
            self._drop("client stopped reading or went away")

    def _send_msg(self, ftype: int, payload: bytes = b"") -> None:
        s = self.session
        if s is not None:
            s.msg_seq += 1              # before sending: a failed send drops the session
            self._send(ftype, s.msg_seq - 1, payload)

    def _error(self, code: int, text: str) -> None:
        self.log(text)
        self._send_msg(protocol.ERROR, protocol.ErrorMsg(code, text).encode())

    def _how(self, seq: int) -> How:
        """Sample the arm now: the HOW for cycle ``seq``."""
        smp = self.arm.sample()
        if smp.status:
            self.log(f"status {smp.status} ({codes.STATUS_TEXT.get(smp.status, '?')}) at cycle {seq}")
        how = How(pos=smp.pos, adcr=smp.adcr, status=smp.status, state=smp.state, exio=0,
                  inport1=smp.inport1, outport1=smp.outport1,
                  time_ns=int(round(self.arm.t * 1e9)), rate_hz=self.rate,
                  robot_overruns=self.overruns)
        return how

    def _send_how(self) -> None:
        self._send(protocol.HOW, self.seq, protocol.encode_how(self._how(self.seq)))

    def _prepare_next(self) -> None:
        """Real-time mode, CHG of this cycle applied: advance the arm to the next tick now.

        The arm's motion from this tick to the next depends only on the commands in hand,
        so it is computed here, while the clock still has most of the period to run; the
        tick then sends the frame at once (re-encoded there only if a stale or duplicate CHG
        has changed ``robot_overruns`` meanwhile).
        """
        self.arm.step(1.0 / self.rate)
        self.rate = self._pending_rate
        seq = (self.seq + 1) & 0xFFFFFFFF
        how = self._how(seq)
        self._prepared = (how, protocol.encode_frame(protocol.HOW, seq, protocol.encode_how(how)))

    def _drop(self, why: str) -> None:
        """The client is gone: hold the arm and wait for the next one (pty: keep the device)."""
        s = self.session
        if s is None:
            return
        if s.running:
            self.arm.hold_all()
        if self.verbose or s.running:
            self.log(f"session ended: {why}")
        if isinstance(s.transport, PtyTransport):
            self.session = Client(s.transport)
        else:
            s.transport.close()
            self.session = None

    def _handle(self, f: protocol.Frame) -> None:
        s = self.session
        assert s is not None
        if f.type == protocol.HELLO:
            try:
                hello = protocol.Hello.decode(f.payload)
            except ProtocolError as exc:
                self._error(codes.ST_BAD_COMMAND, f"bad HELLO: {exc}")
                return
            if s.running:
                self.arm.hold_all()
                s.running = False
            if hello.robot != self.robot:
                self._error(codes.ST_BAD_COMMAND, f"this simula is a {self.robot}, the program asks for {hello.robot!r}")
                return
            s.welcomed = True
            w = protocol.Welcome(self.robot, self.arm.n, N_ADC, self.rate, self.arm.state,
                                 protocol.MODE_LOCKSTEP if self.lockstep else protocol.MODE_REALTIME, SERVER_NAME)
            self._send_msg(protocol.WELCOME, w.encode())
        elif f.type == protocol.START:
            if not s.welcomed:
                self._error(codes.ST_BAD_COMMAND, "START before HELLO")
                return
            try:
                rate = chg_rate_hz(protocol.Start.decode(f.payload).rate_hz)
            except (ProtocolError, ValueError) as exc:
                self._error(codes.ST_BAD_COMMAND, f"bad START: {exc}")
                return
            self.rate = self._pending_rate = rate
            self._prepared = None
            s.running = True
            self.overruns = 0
            self.missed = 0
            self.got_chg = False
            self.seq = (self.seq + 1) & 0xFFFFFFFF
            self._send_how()
            self.next_tick = time.monotonic() + 1.0 / self.rate
        elif f.type == protocol.CHG:
            if not s.running:
                return                      # a CHG in flight after END: ignore
            if f.seq != self.seq or self.got_chg:
                self.overruns += 1          # stale or duplicate reply
                return
            try:
                chg = protocol.decode_chg(f.payload)
            except ProtocolError as exc:
                self.overruns += 1
                self.log(f"bad CHG {f.seq}: {exc}")
                return
            self.got_chg = True
            self.missed = 0
            if self.trace is not None:
                self.trace.got_chg(time.monotonic())
            events = self.arm.apply(chg, 1.0 / self.rate)
            if self.arm.status:
                self.log(self.arm.status_text)
            new_rate = self.rate
            for ev in events:
                if ev.startswith("rate:"):
                    try:
                        new_rate = chg_rate_hz(int(ev[5:]))
                    except ValueError as exc:
                        self.arm.flag(codes.ST_BAD_COMMAND, str(exc))
            if "end" in events:
                s.running = False
                self.arm.hold_all()
                return
            if self.lockstep:
                self.arm.step(1.0 / self.rate)
                self.rate = new_rate
                self._report()
                self.seq = (self.seq + 1) & 0xFFFFFFFF
                self.got_chg = False
                self._send_how()
            else:
                self._pending_rate = new_rate
                t0 = time.monotonic()
                self._prepare_next()
                if self.trace is not None:
                    self.trace.prepared(time.monotonic() - t0)
        elif f.type == protocol.BYE:
            try:
                bye = protocol.Bye.decode(f.payload)
            except ProtocolError:
                bye = protocol.Bye(False)
            if s.running:
                self.arm.hold_all()
                s.running = False
            if bye.power_off:
                self.arm.power = False
                self.arm.hold_all()
            self._send_msg(protocol.BYE, bye.encode())
            s.welcomed = False
        else:
            self._error(codes.ST_BAD_COMMAND, f"unexpected {f.name} frame from the controller")

    def _on_readable(self) -> None:
        s = self.session
        assert s is not None
        data = s.transport.read()
        if not data:
            if not isinstance(s.transport, PtyTransport):
                self._drop("connection closed")
            return
        s.decoder.feed(data)
        while self.session is s:
            try:
                f = s.decoder.next_frame()
            except ProtocolError as exc:
                s.bad_frames += 1
                self.log(f"bad frame dropped: {exc}")
                continue
            if f is None:
                break
            self._handle(f)

    # --- real-time clock --------------------------------------------------------------------
    def _poll_client(self) -> None:
        """Read whatever the controller has sent, without waiting."""
        s = self.session
        if s is None:
            return
        try:
            ready, _, _ = select.select([s.transport], [], [], 0)
        except (InterruptedError, ValueError, OSError):
            return
        if ready:
            self._on_readable()

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
                self.arm.hold_all()
                self.arm.flag(codes.ST_WATCHDOG, f"no CHG for {self.missed} cycles: arm stopped")
                self.log(self.arm.status_text)
                self.arm.step(1.0 / self.rate)
                self.next_tick += 1.0 / self.rate
                self.seq = (self.seq + 1) & 0xFFFFFFFF
                self._send_how()
                s.running = False
                return
        prepared, self._prepared = self._prepared, None
        if prepared is None:                  # no CHG in time (or none yet): step the arm now
            self.arm.step(1.0 / self.rate)
            self.rate = self._pending_rate
            self.seq = (self.seq + 1) & 0xFFFFFFFF
            self.got_chg = False
            self._send_how()
        else:
            how, frame = prepared
            self.seq = (self.seq + 1) & 0xFFFFFFFF
            self.got_chg = False
            if how.robot_overruns != self.overruns:
                how.robot_overruns = self.overruns
                frame = protocol.encode_frame(protocol.HOW, self.seq, protocol.encode_how(how))
            if not s.transport.write(frame):
                self._drop("client stopped reading or went away")
        if self.trace is not None:
            self.trace.tick(deadline, time.monotonic(), late)
        self.next_tick += 1.0 / self.rate          # the new rate's period from here on
        self._report()
        now = time.monotonic()
        if now - self.next_tick > 5.0 / self.rate:         # far behind (machine stalled): resync
            self.next_tick = now + 1.0 / self.rate

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

    def _serve(self, control: ControlChannel | None) -> None:
        while not self.stopping:
            fds: list = []
            if self.listener is not None:
                fds.append(self.listener)
            if self.session is not None:
                fds.append(self.session.transport)
            if control is not None:
                fds.extend(control.fds())
            running = self.session is not None and self.session.running
            if not self.lockstep and running:
                timeout = max(0.0, self.next_tick - time.monotonic() - SPIN_S)
            else:
                timeout = 0.05 if not self.lockstep else 0.5
            try:
                ready, _, _ = select.select(fds, [], [], timeout)
            except InterruptedError:
                continue
            for r in ready:
                if r is self.listener:
                    conn, _ = self.listener.accept()
                    if self.session is not None:
                        self._drop("a new controller connected")
                    self.session = Client(SocketTransport(conn))
                elif self.session is not None and r is self.session.transport:
                    self._on_readable()
                elif control is not None:
                    control.on_readable(r, self)
            if not self.lockstep:
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
        if self.session is not None:
            self.session.transport.close()
        if self.pty is not None:
            self.pty.close()
        if self.listener is not None:
            self.listener.close()
        if self.control is not None:
            self.control.close()
