"""The robot link over Zenoh: the link address ``zenoh/KEY`` next to serial, pty and socket.

A robot (or ``simula --zenoh KEY``) serves its arm under the key expression
``rcci/KEY``; a controller reaches it through a Zenoh session, on one host or several
(peer to peer over TCP, or through a Zenoh router), with the same frames, the same
ownership rule and the same fault handling as over a socket (docs/protocol.md).

Key expressions (``KEY`` is the robot's name on the bus, e.g. ``lab/puma260``):

``rcci/KEY/hello``            queryable of the robot: a controller asks to connect, with
                              its connection id as payload; the robot answers ``ok``
``rcci/KEY/c/ID/down``        the controller's frames to the robot (HELLO, CHG, ...)
``rcci/KEY/c/ID/up``          the robot's frames to that controller (WELCOME, HOW, ...)
``rcci/KEY/c/ID``             liveliness token of the controller ``ID``
``rcci/KEY/robot``            liveliness token of the robot

A connection is a byte stream like a socket: on each side a local socket pair carries
what the subscriber receives to the reader's ``select()``, so the link's framing, its
waits and its wake-up work unchanged. The subscriber's callback runs on the Zenoh thread
that received the frame (``_on_zenoh_thread``), and Zenoh's threads run at the reader's
real-time priority + 1 on the CPUs of the thread that opened the session: pin the
controller (and all of simula's threads, ``taskset -a``) to one CPU for 1 kHz
(docs/zenoh.md, "Speed").

When a side's liveliness token disappears (the process died, its host or network went
away: Zenoh notices within its lease, a few seconds by default, ``lease`` in the address
below sets it) the other side reads end of file: the controller's control ends with a
link fault, the robot holds the arm as for a dropped socket. A controller that stops
sending while alive is caught by the robot's watchdog, as on every link.

Address: ``zenoh/KEY[?connect=ENDPOINT][&listen=ENDPOINT][&lease=MS]``; endpoints are
Zenoh locators (``tcp/127.0.0.1:7447``). Without ``connect`` a controller connects to
``tcp/127.0.0.1:7447``, where ``simula --zenoh KEY`` listens by default.
"""
from __future__ import annotations

import os
import socket
import threading
import uuid
from collections import deque
from dataclasses import dataclass
from urllib.parse import parse_qs

PREFIX = "zenoh/"
DEFAULT_ENDPOINT = "tcp/127.0.0.1:7447"
HELLO_TIMEOUT_S = 5.0


def free_endpoint(host: str = "127.0.0.1") -> str:
    """A Zenoh TCP locator on a port of ``host`` that is free now (``tcp/HOST:PORT``), for a
    session that listens: the OS picks the port, which is released for Zenoh to bind."""
    with socket.socket() as sock:
        sock.bind((host, 0))
        return f"tcp/{host}:{sock.getsockname()[1]}"


class ZenohLinkError(OSError):
    """The Zenoh link cannot be set up or has failed (says which key and why)."""


@dataclass(frozen=True)
class ZenohAddress:
    """A parsed ``zenoh/KEY?...`` link address."""

    key: str
    connect: tuple[str, ...] = ()
    listen: tuple[str, ...] = ()
    lease_ms: int | None = None

    @staticmethod
    def parse(url: str) -> "ZenohAddress":
        if not url.startswith(PREFIX):
            raise ZenohLinkError(f"{url!r}: not a Zenoh link address (zenoh/KEY[?connect=ENDPOINT])")
        key, _, query = url[len(PREFIX):].partition("?")
        key = key.strip("/")
        if not key or any(c in key for c in "*$#? "):
            raise ZenohLinkError(f"{url!r}: the key must be a plain key expression such as lab/puma260")
        opts = parse_qs(query, keep_blank_values=False)
        unknown = set(opts) - {"connect", "listen", "lease"}
        if unknown:
            raise ZenohLinkError(f"{url!r}: unknown option(s) {', '.join(sorted(unknown))} "
                                 "(connect, listen, lease)")
        lease = opts.get("lease", [None])[0]
        try:
            lease_ms = None if lease is None else int(lease)
        except ValueError:
            raise ZenohLinkError(f"{url!r}: lease must be an integer number of milliseconds") from None
        return ZenohAddress(key, tuple(opts.get("connect", ())), tuple(opts.get("listen", ())), lease_ms)

    def url(self) -> str:
        q = [f"connect={e}" for e in self.connect] + [f"listen={e}" for e in self.listen]
        q += [f"lease={self.lease_ms}"] if self.lease_ms is not None else []
        return PREFIX + self.key + ("?" + "&".join(q) if q else "")

    def keyexpr(self, *parts: str) -> str:
        return "/".join(("rcci", self.key) + parts)


def _threads() -> set[int]:
    try:
        return {int(t) for t in os.listdir("/proc/self/task")}
    except OSError:
        return set()


def undeclare(*objs) -> None:
    """Undeclare Zenoh publishers, subscribers, queryables and tokens, skipping None; a close
    path: one that fails (its session already closed) does not stop the others."""
    for obj in objs:
        if obj is None:
            continue
        try:
            obj.undeclare()
        except Exception:
            pass


def _realtime_threads(tids: set[int], priority: int) -> bool:
    """Run ``tids`` (Zenoh's runtime threads) under SCHED_FIFO ``priority`` where the OS
    allows: a frame crosses them on its way to and from the control thread, and a
    real-time control thread or simula's spin before a tick would otherwise keep them off
    the CPU for whole periods. False (nothing changed) without the privilege."""
    if priority <= 0 or not hasattr(os, "sched_setscheduler"):
        return False
    done = False
    for tid in tids:
        try:
            os.sched_setscheduler(tid, os.SCHED_FIFO, os.sched_param(priority))
            done = True
        except OSError:
            return done
    return done


def open_session(connect: tuple[str, ...] = (), listen: tuple[str, ...] = (), lease_ms: int | None = None,
                 priority: int = 0, router: bool = False, client: bool = False):
    """A Zenoh peer session with these endpoints (multicast scouting off: explicit endpoints,
    so a test on loopback meets no stranger's session); its threads real-time at
    ``priority`` if > 0 and allowed. ``router``: the session also routes between the
    sessions connected to it (the process the others connect to, in a workcell); ``client``:
    a client of such a router (everything goes through it)."""
    try:
        import zenoh
    except ImportError:
        raise ZenohLinkError("the Zenoh link needs the eclipse-zenoh package (pip install eclipse-zenoh)") from None
    conf = zenoh.Config()
    conf.insert_json5("mode", '"router"' if router else ('"client"' if client else '"peer"'))
    conf.insert_json5("scouting/multicast/enabled", "false")
    if connect:
        conf.insert_json5("connect/endpoints", "[" + ",".join(f'"{e}"' for e in connect) + "]")
    if listen:
        conf.insert_json5("listen/endpoints", "[" + ",".join(f'"{e}"' for e in listen) + "]")
    # the low-latency transport (no batching, no QoS lanes): about 30 % less round trip for the
    # link's small frames (measured: Python ping-pong between two processes on loopback, p50
    # 256 -> 181 us); every session of the link uses it, so peers agree
    conf.insert_json5("transport/unicast/lowlatency", "true")
    conf.insert_json5("transport/unicast/qos/enabled", "false")
    if lease_ms is not None:
        conf.insert_json5("transport/link/tx/lease", str(int(lease_ms)))
        conf.insert_json5("transport/link/tx/keep_alive", "4")
    before = _threads()
    try:
        session = zenoh.open(conf)
    except Exception as exc:    # zenoh raises its own ZError
        raise ZenohLinkError(f"cannot open a Zenoh session (connect {list(connect)}, listen {list(listen)}): "
                             f"{exc}") from None
    _realtime_threads(_threads() - before, priority)
    return session


class _Pipe:
    """A local socket pair: Zenoh callbacks write into ``inlet``; the reader selects on ``outlet``.

    The callbacks run on Zenoh's own threads (``_on_zenoh_thread``), which must never wait
    for a reader: ``inlet`` does not block, and a reader that leaves the pair full has
    stopped reading; the pipe then ends (``overflowed``), as simula counts a TCP client
    that does not read as gone. The pair holds ``BUFFER`` bytes of socket buffer, where the
    OS allows (net.core.wmem_max): about 10,000 frames, 10 s at 1 kHz (the default buffer
    held 278 frames of 100 bytes)."""

    BUFFER = 4 << 20

    def __init__(self) -> None:
        self.outlet, self.inlet = socket.socketpair()
        self.outlet.setblocking(False)
        self.inlet.setblocking(False)
        try:
            self.inlet.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, self.BUFFER)
        except OSError:
            pass
        self.lock = threading.Lock()
        self.closed = False
        self.overflowed = False

    def push(self, data: bytes) -> None:
        with self.lock:
            if self.closed or self.overflowed:
                return
            try:
                self.inlet.sendall(data)
            except BlockingIOError:
                self.overflowed = True
                self._shut()
            except OSError:
                pass

    def _shut(self) -> None:
        try:
            self.inlet.shutdown(socket.SHUT_WR)
        except OSError:
            pass

    def end(self) -> None:
        """End of file for the reader (the other side is gone)."""
        with self.lock:
            if not self.closed:
                self._shut()

    def read(self, n: int = 65536) -> bytes | None:
        """What is there (b"" if nothing), None at end of file."""
        try:
            data = self.outlet.recv(n)
        except (BlockingIOError, InterruptedError):
            return b""
        except OSError:
            return None
        return data or None

    def close(self) -> None:
        with self.lock:
            self.closed = True
        for s in (self.inlet, self.outlet):
            try:
                s.close()
            except OSError:
                pass


def _on_zenoh_thread(fn):
    """``fn`` as a Zenoh callback run by the Zenoh thread that received the sample.

    zenoh-python's default (``indirect``) hands every sample to a Python thread of its own:
    an ordinary (SCHED_OTHER) thread with the CPU affinity of the thread that declared the
    subscriber. A frame then waited for that thread to get a CPU behind every other
    process, and next to real-time threads pinned to the same CPU it waited for whole
    periods: at 1 kHz on a loaded machine the robot's watchdog (100 cycles without a CHG)
    ended the control within a second, and at 50 Hz unpinned within seconds (measured
    2026-11-26, docs/zenoh.md "Speed"). Run directly, the callback is one hop shorter and
    runs at the priority of Zenoh's threads (``open_session``); it only copies the payload
    into a socket pair (or marks end of file), so it holds the interpreter lock for
    microseconds and never waits on anything but that lock."""
    import zenoh

    return zenoh.handlers.Callback(fn, indirect=False)


def _put(publisher, data: bytes) -> None:
    publisher.put(data)


def _declare_publisher(session, key: str):
    import zenoh

    # BLOCK: a frame is never dropped by Zenoh (a lost HOW or CHG would end the control as a
    # sequence gap); a put waits only while the transmit queue is full
    return session.declare_publisher(key, congestion_control=zenoh.CongestionControl.BLOCK,
                                      priority=zenoh.Priority.REAL_TIME, express=True)


class ControllerPort:
    """The controller's end of a Zenoh link, shaped like the pyserial port ``rci.link.Link``
    drives (``fileno``, ``read``, ``write``, ``close``): frames go out as publications on
    ``.../down``; what arrives on ``.../up`` is read from a local socket pair."""

    def __init__(self, url: str, timeout: float = HELLO_TIMEOUT_S, priority: int = 0) -> None:
        self.address = ZenohAddress.parse(url)
        self.portstr = url
        self.timeout = 0.0
        self.is_open = False
        a = self.address
        self.id = uuid.uuid4().hex[:12]
        self.session = open_session(a.connect or (DEFAULT_ENDPOINT,), a.listen, a.lease_ms, priority)
        self.pipe = _Pipe()
        try:
            self.sub = self.session.declare_subscriber(
                a.keyexpr("c", self.id, "up"), _on_zenoh_thread(lambda s: self.pipe.push(s.payload.to_bytes())))
            self.pub = _declare_publisher(self.session, a.keyexpr("c", self.id, "down"))
            self.token = self.session.liveliness().declare_token(a.keyexpr("c", self.id))
            self.watch = self.session.liveliness().declare_subscriber(a.keyexpr("robot"),
                                                                     _on_zenoh_thread(self._robot_liveliness))
            self._hello(timeout)
        except BaseException:
            self.close()
            raise
        self.is_open = True

    def _robot_liveliness(self, sample) -> None:
        import zenoh

        if sample.kind == zenoh.SampleKind.DELETE:
            self.pipe.end()

    def _hello(self, timeout: float) -> None:
        a = self.address
        for reply in self.session.get(a.keyexpr("hello"), payload=self.id.encode(), timeout=timeout):
            if reply.ok is not None and reply.ok.payload.to_bytes() == b"ok":
                return
            if reply.err is not None:
                raise ZenohLinkError(f"{self.portstr}: the robot refused: {reply.err.payload.to_bytes()!r}")
        raise ZenohLinkError(f"{self.portstr}: no robot answers on rcci/{a.key} within {timeout} s "
                             f"(is `simula --zenoh {a.key}` running, and reachable at "
                             f"{', '.join(a.connect or (DEFAULT_ENDPOINT,))}?)")

    # --- what rci.link.Link uses --------------------------------------------------
    def fileno(self) -> int:
        return self.pipe.outlet.fileno()

    @property
    def in_waiting(self) -> int:
        return 0

    def read(self, n: int = 4096) -> bytes:
        data = self.pipe.read(n)
        if data is None:
            if self.pipe.overflowed:
                raise ZenohLinkError(f"{self.portstr}: frames from the robot were not read "
                                     "(the local buffer filled up); link ended")
            raise ZenohLinkError(f"{self.portstr}: the robot left the Zenoh bus")
        return data

    def write(self, data: bytes) -> int:
        if not self.is_open:
            raise ZenohLinkError(f"{self.portstr}: link closed")
        try:
            _put(self.pub, bytes(data))
        except Exception as exc:
            raise ZenohLinkError(f"{self.portstr}: publication failed: {exc}") from None
        return len(data)

    def flush(self) -> None:
        pass

    def close(self) -> None:
        self.is_open = False
        undeclare(*(self.__dict__.pop(name, None) for name in ("watch", "token", "pub", "sub")))
        session = self.__dict__.pop("session", None)
        if session is not None:
            try:
                session.close()
            except Exception:
                pass
        self.pipe.close()


class RobotEndpoint:
    """The robot's end: answers ``rcci/KEY/hello`` and makes one :class:`Connection` per
    controller, which the server picks up with :meth:`accept` when :meth:`fileno` is readable."""

    def __init__(self, address: ZenohAddress, priority: int = 0) -> None:
        self.address = address
        self.session = open_session(address.connect, address.listen or (DEFAULT_ENDPOINT,), address.lease_ms,
                                    priority)
        self._wake = _Pipe()
        self._new: deque[Connection] = deque()
        self._live: dict[str, Connection] = {}
        self._lock = threading.Lock()
        a = address
        self.token = self.session.liveliness().declare_token(a.keyexpr("robot"))
        self.watch = self.session.liveliness().declare_subscriber(a.keyexpr("c", "*"),
                                                                 _on_zenoh_thread(self._controller_liveliness))
        self.hello = self.session.declare_queryable(a.keyexpr("hello"), self._on_hello)

    def url(self) -> str:
        """The address a controller on this host uses."""
        listen = self.address.listen or (DEFAULT_ENDPOINT,)
        return ZenohAddress(self.address.key, connect=(listen[0],), lease_ms=self.address.lease_ms).url()

    def _on_hello(self, query) -> None:
        cid = query.payload.to_bytes().decode(errors="replace") if query.payload is not None else ""
        if not cid or "/" in cid or "*" in cid:
            query.reply_err(b"bad connection id")
            return
        conn = Connection(self, cid)
        with self._lock:
            self._live[cid] = conn
            self._new.append(conn)
        self._wake.push(b"n")
        query.reply(query.key_expr, b"ok")

    def _controller_liveliness(self, sample) -> None:
        import zenoh

        if sample.kind != zenoh.SampleKind.DELETE:
            return
        cid = str(sample.key_expr).rsplit("/", 1)[-1]
        with self._lock:
            conn = self._live.pop(cid, None)
        if conn is not None:
            conn.pipe.end()

    def fileno(self) -> int:
        return self._wake.outlet.fileno()

    def accept(self) -> list["Connection"]:
        """Connections that arrived since the last call."""
        while self._wake.read(4096):
            pass
        with self._lock:
            out = list(self._new)
            self._new.clear()
        return out

    def forget(self, conn: "Connection") -> None:
        with self._lock:
            if self._live.get(conn.id) is conn:
                del self._live[conn.id]

    def close(self) -> None:
        with self._lock:
            conns = list(self._live.values()) + list(self._new)
            self._live.clear()
            self._new.clear()
        for c in conns:
            c.close()
        undeclare(self.hello, self.watch, self.token)
        try:
            self.session.close()
        except Exception:
            pass
        self._wake.close()


class Connection:
    """One controller's byte stream at the robot (non-blocking reads, publications out)."""

    def __init__(self, endpoint: RobotEndpoint, cid: str) -> None:
        a = endpoint.address
        self.endpoint = endpoint
        self.id = cid
        self.address = f"zenoh connection {cid}"
        self.pipe = _Pipe()
        self.sub = endpoint.session.declare_subscriber(
            a.keyexpr("c", cid, "down"), _on_zenoh_thread(lambda s: self.pipe.push(s.payload.to_bytes())))
        self.pub = _declare_publisher(endpoint.session, a.keyexpr("c", cid, "up"))

    def fileno(self) -> int:
        return self.pipe.outlet.fileno()

    def read(self) -> bytes | None:
        return self.pipe.read()

    def write(self, data: bytes) -> bool:
        try:
            _put(self.pub, bytes(data))
            return True
        except Exception:
            return False

    def wants_write(self) -> bool:
        return False        # publications queue in Zenoh, not here

    def flush(self) -> bool:
        return True

    def close(self) -> None:
        self.endpoint.forget(self)
        undeclare(self.sub, self.pub)
        self.pipe.close()
