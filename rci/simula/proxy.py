"""A fault-injection proxy for the robot link: a loopback relay between a controller and simula.

    python -m rci.simula.proxy --upstream socket://127.0.0.1:7600 [--port 0]

stdout line 1 is the address a controller connects to (``socket://127.0.0.1:PORT``), line 2
``control socket://127.0.0.1:PORT``, a line-based command channel like simula's. The proxy
relays bytes both ways, one link frame at a time (it finds frame boundaries from the sync
bytes and the length field, so it can damage a frame and still know where the next one
starts), and applies the faults it is told to:

    fault <down|up> <flip|truncate|drop|dup|delay|cut> [type=HOW|CHG|any] [skip=N] [count=N|forever]
          [bit=K] [keep=N] [delay=S]
    clear                       remove every armed fault
    log                         the faults applied so far (direction, kind, frame type and seq, time)
    ping

``down`` is robot -> controller (HOW, session replies), ``up`` controller -> robot (CHG,
HELLO, START, BYE). A fault applies to ``count`` frames (default 1) of the given type after
skipping ``skip`` of them: ``flip`` inverts bit K of the frame (default: a payload bit, so
the CRC catches it), ``truncate`` passes only the first ``keep`` bytes (default half),
``drop`` loses the frame, ``dup`` sends it twice, ``delay`` holds it (and, as on a byte
stream, everything after it) for S seconds, ``cut`` closes both connections at once (a
dead link). Times in the log are ``time.monotonic()``, comparable with simula's events.

Used by the fault tests and ``python -m bench.faults``; ``ProxyProcess`` starts one.
"""
from __future__ import annotations

import argparse
import heapq
import json
import select
import socket
import sys
import time
from dataclasses import dataclass, field

from .. import protocol
from .process import ToolProcess

DIRECTIONS = ("down", "up")
KINDS = ("flip", "truncate", "drop", "dup", "delay", "cut")


@dataclass
class Fault:
    """One armed fault: which frames it hits and what it does to them."""

    direction: str
    kind: str
    ftype: int | None = None        # frame type, None: any
    skip: int = 0
    count: int = 1                  # -1: forever
    bit: int | None = None
    keep: int | None = None
    delay: float = 0.0
    id: int = 0

    @classmethod
    def parse(cls, words: list[str], fid: int) -> "Fault":
        if len(words) < 2 or words[0] not in DIRECTIONS or words[1] not in KINDS:
            raise ValueError(f"usage: fault <{'|'.join(DIRECTIONS)}> <{'|'.join(KINDS)}> [type=HOW|CHG|any] "
                             f"[skip=N] [count=N|forever] [bit=K] [keep=N] [delay=S]")
        f = cls(words[0], words[1], id=fid)
        names = {v: k for k, v in protocol.TYPE_NAMES.items()}
        for w in words[2:]:
            key, _, val = w.partition("=")
            if key == "type":
                f.ftype = None if val.lower() == "any" else names.get(val.upper())
                if val.lower() != "any" and f.ftype is None:
                    raise ValueError(f"type={val}: not a frame type ({', '.join(names)}, any)")
            elif key == "count":
                f.count = -1 if val == "forever" else int(val)
            elif key in ("skip", "bit", "keep"):
                setattr(f, key, int(val))
            elif key == "delay":
                f.delay = float(val)
            else:
                raise ValueError(f"unknown fault option {w!r}")
        if f.kind == "delay" and not f.delay > 0:
            raise ValueError("a delay fault needs delay=S with S > 0")
        return f

    def matches(self, direction: str, ftype: int) -> bool:
        return self.direction == direction and self.count != 0 and (self.ftype is None or self.ftype == ftype)


def split_frames(buf: bytearray) -> list[tuple[int | None, int, bytes]]:
    """Cut complete frames (type, seq, bytes) off the front of ``buf``; bytes that cannot
    start a frame come out as (None, 0, bytes) so they are relayed untouched."""
    out: list[tuple[int | None, int, bytes]] = []
    while buf:
        i = buf.find(protocol.SYNC)
        if i < 0:
            keep = 1 if buf[-1:] == protocol.SYNC[:1] else 0
            if len(buf) > keep:
                out.append((None, 0, bytes(buf[: len(buf) - keep])))
                del buf[: len(buf) - keep]
            return out
        if i:
            out.append((None, 0, bytes(buf[:i])))
            del buf[:i]
        if len(buf) < protocol.HEADER_LEN:
            return out
        ver, ftype, seq, length = protocol.HEADER.unpack_from(buf, 2)
        if length > protocol.MAX_PAYLOAD:
            out.append((None, 0, bytes(buf[:1])))
            del buf[:1]
            continue
        total = protocol.HEADER_LEN + length + protocol.TRAILER_LEN
        if len(buf) < total:
            return out
        out.append((ftype, seq, bytes(buf[:total])))
        del buf[:total]
    return out


@dataclass
class _Pair:
    """One controller connection and its connection to the robot."""

    down_sock: socket.socket                  # to the controller
    up_sock: socket.socket                    # to the robot
    bufs: dict = field(default_factory=lambda: {"down": bytearray(), "up": bytearray()})
    queues: dict = field(default_factory=lambda: {"down": [], "up": []})   # heaps of (release time, n, bytes)
    held_until: dict = field(default_factory=lambda: {"down": 0.0, "up": 0.0})
    out: dict = field(default_factory=lambda: {"down": bytearray(), "up": bytearray()})

    def dest(self, direction: str) -> socket.socket:
        return self.down_sock if direction == "down" else self.up_sock


class Proxy:
    """The relay and its faults, served from one select loop."""

    def __init__(self, upstream: str, host: str = "127.0.0.1", port: int = 0) -> None:
        if not upstream.startswith("socket://"):
            raise ValueError(f"--upstream {upstream!r}: a socket://host:port address")
        h, p = upstream.removeprefix("socket://").rsplit(":", 1)
        self.upstream = (h, int(p))
        self.listener = socket.create_server((host, port))
        self.control = socket.create_server(("127.0.0.1", 0))
        self.pairs: list[_Pair] = []
        self.ctl_clients: dict[socket.socket, bytearray] = {}
        self.faults: list[Fault] = []
        self.log: list[dict] = []
        self.frames = {"down": 0, "up": 0}
        self._next_id = 1
        self._n = 0
        self.stopping = False

    @property
    def url(self) -> str:
        return "socket://%s:%d" % self.listener.getsockname()[:2]

    @property
    def control_url(self) -> str:
        return "socket://%s:%d" % self.control.getsockname()[:2]

    # --- faults ---------------------------------------------------------------------------
    def _apply(self, pair: _Pair, direction: str, ftype: int | None, seq: int, data: bytes) -> None:
        now = time.monotonic()
        sends = [data]
        delay = 0.0
        if ftype is not None:
            self.frames[direction] += 1
            for f in self.faults:
                if not f.matches(direction, ftype):
                    continue
                if f.skip > 0:
                    f.skip -= 1
                    continue
                if f.count > 0:
                    f.count -= 1
                self.log.append({"id": f.id, "dir": direction, "kind": f.kind, "type": protocol.TYPE_NAMES.get(ftype),
                                 "seq": seq, "wall": now})
                if f.kind == "cut":
                    self._close_pair(pair)
                    return
                if f.kind == "drop":
                    sends = []
                elif f.kind == "dup":
                    sends = sends * 2
                elif f.kind == "flip":
                    bit = f.bit if f.bit is not None else 8 * (protocol.HEADER_LEN + max(0, len(data) - 16) // 2) + 3
                    b = bytearray(sends[0])
                    b[(bit // 8) % len(b)] ^= 1 << (bit % 8)
                    sends = [bytes(b)] + sends[1:]
                elif f.kind == "truncate":
                    keep = f.keep if f.keep is not None else len(data) // 2
                    sends = [s[:keep] for s in sends]
                elif f.kind == "delay":
                    delay = max(delay, f.delay)
                break                                     # one fault per frame
        release = max(now + delay, pair.held_until[direction])
        pair.held_until[direction] = release if delay else pair.held_until[direction]
        for s in sends:
            self._n += 1
            heapq.heappush(pair.queues[direction], (release, self._n, s))

    def _pump(self, pair: _Pair) -> None:
        now = time.monotonic()
        for direction in DIRECTIONS:
            q = pair.queues[direction]
            while q and q[0][0] <= now:
                pair.out[direction] += heapq.heappop(q)[2]
            if pair.out[direction]:
                try:
                    n = pair.dest(direction).send(pair.out[direction])
                except (BlockingIOError, InterruptedError):
                    n = 0
                except OSError:
                    self._close_pair(pair)
                    return
                del pair.out[direction][:n]

    def _close_pair(self, pair: _Pair) -> None:
        if pair in self.pairs:
            self.pairs.remove(pair)
        for s in (pair.down_sock, pair.up_sock):
            try:
                s.close()
            except OSError:
                pass

    # --- control channel ------------------------------------------------------------------
    def execute(self, line: str) -> dict:
        words = line.split()
        if not words:
            return {"ok": False, "error": "empty command"}
        cmd = words[0].lower()
        try:
            if cmd == "ping":
                return {"ok": True, "pairs": len(self.pairs), "frames": dict(self.frames)}
            if cmd == "fault":
                f = Fault.parse(words[1:], self._next_id)
                self._next_id += 1
                self.faults.append(f)
                return {"ok": True, "id": f.id}
            if cmd == "clear":
                self.faults.clear()
                return {"ok": True}
            if cmd == "log":
                return {"ok": True, "log": self.log, "frames": dict(self.frames), "now": time.monotonic()}
        except ValueError as exc:
            return {"ok": False, "error": str(exc)}
        return {"ok": False, "error": f"unknown command {cmd!r} (fault, clear, log, ping)"}

    def _control_readable(self, sock: socket.socket) -> None:
        try:
            data = sock.recv(4096)
        except OSError:
            data = b""
        if not data:
            self.ctl_clients.pop(sock, None)
            sock.close()
            return
        buf = self.ctl_clients[sock]
        buf += data
        while b"\n" in buf:
            i = buf.index(b"\n")
            line = bytes(buf[:i]).decode("utf-8", "replace")
            del buf[: i + 1]
            try:
                sock.sendall((json.dumps(self.execute(line)) + "\n").encode())
            except OSError:
                self.ctl_clients.pop(sock, None)
                return

    # --- loop -----------------------------------------------------------------------------
    def serve_forever(self) -> None:
        while not self.stopping:
            rfds: list = [self.listener, self.control, *self.ctl_clients]
            for p in self.pairs:
                rfds += [p.down_sock, p.up_sock]
            wait = 0.05
            now = time.monotonic()
            for p in self.pairs:
                for d in DIRECTIONS:
                    if p.queues[d]:
                        wait = min(wait, max(0.0, p.queues[d][0][0] - now))
                    if p.out[d]:
                        wait = min(wait, 0.001)
            ready, _, _ = select.select(rfds, [], [], wait)
            for r in ready:
                if r is self.listener:
                    self._accept()
                elif r is self.control:
                    conn, _ = self.control.accept()
                    self.ctl_clients[conn] = bytearray()
                elif r in self.ctl_clients:
                    self._control_readable(r)
                else:
                    self._relay_readable(r)
            for p in list(self.pairs):
                self._pump(p)

    def _accept(self) -> None:
        down, _ = self.listener.accept()
        try:
            up = socket.create_connection(self.upstream, timeout=2.0)
        except OSError:
            down.close()
            return
        for s in (down, up):
            s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            s.setblocking(False)
        self.pairs.append(_Pair(down, up))

    def _relay_readable(self, sock: socket.socket) -> None:
        pair = next((p for p in self.pairs if sock in (p.down_sock, p.up_sock)), None)
        if pair is None:
            return
        direction = "up" if sock is pair.down_sock else "down"    # bytes from the controller go up
        try:
            data = sock.recv(65536)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            data = b""
        if not data:
            self._close_pair(pair)               # either end closed: close the other (a dead link)
            return
        buf = pair.bufs[direction]
        buf += data
        for ftype, seq, chunk in split_frames(buf):
            if pair not in self.pairs:
                return
            self._apply(pair, direction, ftype, seq, chunk)


class ProxyProcess(ToolProcess):
    """A running ``python -m rci.simula.proxy --upstream URL --port 0``."""

    def __init__(self, upstream: str, start_timeout: float = 30.0) -> None:
        super().__init__([sys.executable, "-m", "rci.simula.proxy", "--upstream", upstream, "--port", "0"],
                         start_timeout)

    def fault(self, spec: str) -> int:
        """Arm a fault (``"up drop type=CHG"``); returns its id."""
        reply = self.command(f"fault {spec}")
        if not reply["ok"]:
            raise ValueError(reply["error"])
        return reply["id"]

    def applied(self) -> list[dict]:
        """The faults applied so far, oldest first."""
        return self.command("log")["log"]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m rci.simula.proxy", description=__doc__.splitlines()[0])
    ap.add_argument("--upstream", required=True, help="the robot's link address, socket://host:port")
    ap.add_argument("--host", default="127.0.0.1")
    ap.add_argument("--port", type=int, default=0)
    ap.add_argument("--priority", type=int, default=75,
                    help="SCHED_FIFO priority (0: leave the scheduler alone); between simula's 70 and the "
                         "control task's 80, so the relay adds no scheduling delay of its own; falls back quietly")
    a = ap.parse_args(argv)
    if a.priority > 0:
        from ..realtime import RealtimeStatus, set_fifo
        set_fifo(a.priority, RealtimeStatus())
    try:
        proxy = Proxy(a.upstream, a.host, a.port)
    except (OSError, ValueError) as exc:
        print(f"proxy: {exc}", file=sys.stderr)
        return 2
    print(proxy.url, flush=True)
    print(f"control {proxy.control_url}", flush=True)
    import signal
    signal.signal(signal.SIGTERM, lambda *_: setattr(proxy, "stopping", True))
    try:
        proxy.serve_forever()
    except KeyboardInterrupt:
        pass
    return 0


if __name__ == "__main__":
    sys.exit(main())
