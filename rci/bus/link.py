"""The robot link over Zenoh: the link address ``zenoh/KEY`` next to serial, pty and socket.

A robot (or ``simula --zenoh KEY``) serves its arm under the key expression
``rcci/KEY``; a controller reaches it through a Zenoh session, on one host or several
(peer to peer over TCP, or through a Zenoh router), with the same frames, the same
ownership rule and the same fault handling as over a socket (docs/protocol.md).

Key expressions (``KEY`` is the robot's name on the bus, e.g. ``lab/puma260``):

``rcci/KEY/hello``            queryable of the robot: a controller asks to connect, with
                              its connection id and X25519 public key; the robot answers
                              with its own (the connection's keys: rci.bus.frames)
``rcci/KEY/c/ID/down``        the controller's frames to the robot (HELLO, CHG, ...), sealed
``rcci/KEY/c/ID/up``          the robot's frames to that controller (WELCOME, HOW, ...), sealed
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

Every publication of a connection is encrypted and carries a MAC under a key agreed at its hello
(rci.bus.frames): one not made by that connection's end (a forgery, garbage, a truncated,
oversized or replayed frame, from any process on the bus) is dropped before the frame
decoder, counted, and reported once per flood; it ends no control and is blamed on no one.

Address: ``zenoh/KEY[?connect=ENDPOINT][&listen=ENDPOINT][&lease=MS][&config=FILE]``;
endpoints are Zenoh locators (``tcp/127.0.0.1:7447``, ``tls/host:7447``); ``config`` a
Zenoh configuration file (JSON5: TLS, authentication, access control; rci.bus.session).
Without ``connect`` (here or in the file) a controller connects to ``tcp/127.0.0.1:7447``,
where ``simula --zenoh KEY`` listens by default.
"""
from __future__ import annotations

import json
import logging
import re
import socket
import threading
import time
import uuid
from collections import deque
from dataclasses import dataclass
from urllib.parse import parse_qs

from .frames import Handshake, KeyAgreementError, Opener, Rejections, Sealer
from .guard import BoundedWorker, Episodes
from .session import (DEFAULT_ENDPOINT, ZenohLinkError, configured_endpoints, free_endpoint,  # noqa: F401 - API
                      load_config, open_session, per_session_limit, undeclare)

log = logging.getLogger(__name__)

PREFIX = "zenoh/"
HELLO_TIMEOUT_S = 5.0
HELLO_RETRY_S = 0.5       # a controller asks again after this long without an answer
HELLO_PAUSE_S = 0.05      # ... and pauses this long after a query that ended unanswered
HELLO_QUEUE = 16          # hellos waiting for the robot's hello worker; more are dropped
HELLO_RATE = 100.0        # hellos the robot answers a second at most (a key agreement each)
HELLO_PER_SESSION_HZ = 5.0   # hellos that reach the robot from one Zenoh session a second at most (the
                             # fairness rule: Zenoh drops the rest where they come in; a controller asks
                             # every HELLO_RETRY_S, 2 a second, so its asks always pass)
HELLO_LIMIT_ID = "rcci robot hello per session"     # its id in the Zenoh configuration (a file may redefine it)
MAX_OFFERS = 16           # connections answered that have not sent a frame yet
OFFER_TTL_S = 5.0         # ... forgotten after this long
REPORT_S = 0.25          # the robot looks at its counts of dropped publications this often
_ID_RE = re.compile(r"[0-9a-f]{1,32}")


@dataclass(frozen=True)
class ZenohAddress:
    """A parsed ``zenoh/KEY?...`` link address."""

    key: str
    connect: tuple[str, ...] = ()
    listen: tuple[str, ...] = ()
    lease_ms: int | None = None
    config: str | None = None       # the Zenoh configuration file (rci.bus.session)

    @staticmethod
    def parse(url: str) -> "ZenohAddress":
        if not url.startswith(PREFIX):
            raise ZenohLinkError(f"{url!r}: not a Zenoh link address (zenoh/KEY[?connect=ENDPOINT])")
        key, _, query = url[len(PREFIX):].partition("?")
        key = key.strip("/")
        if not key or any(c in key for c in "*$#? "):
            raise ZenohLinkError(f"{url!r}: the key must be a plain key expression such as lab/puma260")
        opts = parse_qs(query, keep_blank_values=False)
        unknown = set(opts) - {"connect", "listen", "lease", "config"}
        if unknown:
            raise ZenohLinkError(f"{url!r}: unknown option(s) {', '.join(sorted(unknown))} "
                                 "(connect, listen, lease, config)")
        lease = opts.get("lease", [None])[0]
        try:
            lease_ms = None if lease is None else int(lease)
        except ValueError:
            raise ZenohLinkError(f"{url!r}: lease must be an integer number of milliseconds") from None
        config = opts.get("config", [None])[-1]
        return ZenohAddress(key, tuple(opts.get("connect", ())), tuple(opts.get("listen", ())), lease_ms, config)

    def url(self) -> str:
        q = [f"connect={e}" for e in self.connect] + [f"listen={e}" for e in self.listen]
        q += [f"lease={self.lease_ms}"] if self.lease_ms is not None else []
        q += [f"config={self.config}"] if self.config is not None else []
        return PREFIX + self.key + ("?" + "&".join(q) if q else "")

    def keyexpr(self, *parts: str) -> str:
        return "/".join(("rcci", self.key) + parts)


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


def _new_id() -> str:
    return uuid.uuid4().hex[:12]


def _hello_request(cid: str, public: bytes) -> bytes:
    return json.dumps({"id": cid, "key": public.hex()}).encode()


def _parse_hello(payload: bytes) -> tuple[str, bytes]:
    """(connection id, controller's public key) from a hello query; ValueError if unusable."""
    if len(payload) > 256:
        raise ValueError("hello too long")
    msg = json.loads(payload)
    cid, key = str(msg["id"]), bytes.fromhex(str(msg["key"]))
    if not _ID_RE.fullmatch(cid):
        raise ValueError("bad connection id")
    return cid, key


class ControllerPort:
    """The controller's end of a Zenoh link, shaped like the pyserial port ``rci.link.Link``
    drives (``fileno``, ``read``, ``write``, ``close``): frames go out sealed (rci.bus.frames)
    as publications on ``.../down``; what arrives on ``.../up`` is checked and read from a
    local socket pair. ``rejected``: what arrived that was not the robot's (by reason)."""

    def __init__(self, url: str, timeout: float = HELLO_TIMEOUT_S, priority: int = 0) -> None:
        self.address = ZenohAddress.parse(url)
        self.portstr = url
        self.timeout = 0.0
        self.is_open = False
        a = self.address
        self.id = _new_id()
        self._handshake = Handshake()
        self._opener: Opener | None = None
        self._sealer: Sealer | None = None
        self.early = 0                  # publications on .../up before the key was agreed (dropped)
        self.session = open_session(a.connect, a.listen, a.lease_ms, priority, config=a.config,
                                    default_connect=(DEFAULT_ENDPOINT,))
        self.pipe = _Pipe()
        try:
            self.sub = self.session.declare_subscriber(a.keyexpr("c", self.id, "up"), _on_zenoh_thread(self._on_up))
            self.pub = _declare_publisher(self.session, a.keyexpr("c", self.id, "down"))
            self.token = self.session.liveliness().declare_token(a.keyexpr("c", self.id))
            self.watch = self.session.liveliness().declare_subscriber(a.keyexpr("robot"),
                                                                     _on_zenoh_thread(self._robot_liveliness))
            self._hello(timeout)
        except BaseException:
            self.close()
            raise
        self.episodes = Episodes(f"{url}: publications on the link not from the robot", lambda: self.rejected.total,
                                 self.rejected.describe)
        self.is_open = True

    @property
    def rejected(self) -> Rejections:
        return self._opener.rejected if self._opener is not None else Rejections()

    def _on_up(self, sample) -> None:
        opener = self._opener
        if opener is None:
            self.early += 1
            return
        frame = opener.open(sample.payload.to_bytes())
        if frame is not None:
            self.pipe.push(frame)

    def _robot_liveliness(self, sample) -> None:
        import zenoh

        if sample.kind == zenoh.SampleKind.DELETE:
            self.pipe.end()

    def _hello(self, timeout: float) -> None:
        """Ask the robot for a connection, again every HELLO_RETRY_S until ``timeout`` (a
        robot busy with a flood of hellos drops some: an unanswered one is asked again)."""
        a = self.address
        deadline = time.monotonic() + timeout
        request = _hello_request(self.id, self._handshake.public)
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                break
            for reply in self.session.get(a.keyexpr("hello"), payload=request, timeout=min(left, HELLO_RETRY_S)):
                if reply.err is not None:
                    raise ZenohLinkError(f"{self.portstr}: the robot refused: {reply.err.payload.to_bytes()!r}")
                if reply.ok is not None:
                    self._agree(reply.ok.payload.to_bytes())
                    return
            # no answer: nobody serves the key yet (the query ends at once) or the robot dropped
            # it; ask again a little later, not in a busy loop
            time.sleep(max(0.0, min(HELLO_PAUSE_S, deadline - time.monotonic())))
        raise ZenohLinkError(f"{self.portstr}: no robot answers on rcci/{a.key} within {timeout} s "
                             f"(is `simula --zenoh {a.key}` running, and reachable at "
                             f"{', '.join(self._endpoints())}"
                             f"{' with the configuration ' + repr(a.config) if a.config else ''}?)")

    def _endpoints(self) -> tuple[str, ...]:
        a = self.address
        return a.connect or configured_endpoints(load_config(a.config), "connect") or (DEFAULT_ENDPOINT,)

    def _agree(self, answer: bytes) -> None:
        try:
            robot_public = bytes.fromhex(json.loads(answer)["key"])
            down, up = self._handshake.keys(robot_public, self._handshake.public, robot_public,
                                            self.address.keyexpr("c", self.id))
        except (ValueError, KeyError, TypeError) as exc:
            raise ZenohLinkError(f"{self.portstr}: the robot's answer to hello cannot be used ({exc})") from None
        self._sealer, self._opener = Sealer(down), Opener(up)

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
        line = self.episodes.poll()
        if line is not None:
            log.warning("%s", line)
        return data

    def write(self, data: bytes) -> int:
        if not self.is_open:
            raise ZenohLinkError(f"{self.portstr}: link closed")
        try:
            _put(self.pub, self._sealer.seal(bytes(data)))
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
    """The robot's end: answers ``rcci/KEY/hello`` (on a bounded worker thread, at most
    ``HELLO_RATE`` a second) and makes one :class:`Connection` per controller, which the
    server picks up with :meth:`accept` once its first authenticated frame has come in
    (a hello that is never followed by a frame costs a slot for ``OFFER_TTL_S`` at most).

    Everything a peer can send is bounded here: Zenoh lets at most ``HELLO_PER_SESSION_HZ``
    hellos a second in from each session connected to the robot (the fairness rule: a flood
    from one session leaves every other session's hellos their way in), a hello is queued (at
    most ``HELLO_QUEUE``, the rest dropped and counted), a publication on a connection's
    ``down`` key is checked (rci.bus.frames) and dropped unless it is that connection's;
    ``report()`` says once per flood how many were dropped and why."""

    def __init__(self, address: ZenohAddress, priority: int = 0) -> None:
        self.address = address
        hello_limit = per_session_limit(HELLO_LIMIT_ID, address.keyexpr("hello"), HELLO_PER_SESSION_HZ)
        self.session = open_session(address.connect, address.listen, address.lease_ms, priority,
                                    config=address.config, default_listen=(DEFAULT_ENDPOINT,), limits=(hello_limit,))
        self._wake = _Pipe()
        self._new: deque[Connection] = deque()
        self._live: dict[str, Connection] = {}
        self._lock = threading.Lock()
        self._next_report = 0.0
        self.stray = 0                # publications on .../c/ID/down for no connection
        self.refused = Rejections()   # hellos refused, by reason
        self.closed_rejections = Rejections()    # what connections now closed rejected
        a = address
        self._hellos = BoundedWorker(f"hello-{a.key}", self._answer_hello, HELLO_QUEUE, HELLO_RATE, HELLO_QUEUE)
        self.episodes = [
            Episodes(f"rcci/{a.key}: frames not from their connection's controller", self._rejected_total,
                     self._rejected_describe),
            Episodes(f"rcci/{a.key}: hello queries dropped (more than {HELLO_QUEUE} waiting, {HELLO_RATE:.0f}/s "
                     "answered)", lambda: self._hellos.dropped, lambda: f"{self._hellos.offered} asked"),
            Episodes(f"rcci/{a.key}: hello queries refused", lambda: self.refused.total, self.refused.describe),
        ]
        self.token = self.session.liveliness().declare_token(a.keyexpr("robot"))
        self.watch = self.session.liveliness().declare_subscriber(a.keyexpr("c", "*"),
                                                                 _on_zenoh_thread(self._controller_liveliness))
        self.down = self.session.declare_subscriber(a.keyexpr("c", "*", "down"), _on_zenoh_thread(self._on_down))
        self.hello = self.session.declare_queryable(a.keyexpr("hello"), self._hellos.offer)

    def url(self) -> str:
        """The address a controller on this host uses (with a configuration file of its own
        identity added as ``&config=``: the robot's is not for controllers)."""
        listen = self.address.listen or configured_endpoints(load_config(self.address.config), "listen") \
            or (DEFAULT_ENDPOINT,)
        return ZenohAddress(self.address.key, connect=(listen[0],), lease_ms=self.address.lease_ms).url()

    # --- on Zenoh's threads: bounded work ------------------------------------------------------
    def _on_down(self, sample) -> None:
        cid = str(sample.key_expr).rsplit("/", 2)[-2]
        conn = self._live.get(cid)
        if conn is None:
            self.stray += 1
            return
        if conn.received(sample.payload.to_bytes()) and not conn.announced:
            with self._lock:              # once, whichever Zenoh thread delivers the first frame
                first, conn.announced = not conn.announced, True
                if first:
                    self._new.append(conn)
            if first:
                self._wake.push(b"n")

    def _controller_liveliness(self, sample) -> None:
        import zenoh

        if sample.kind != zenoh.SampleKind.DELETE:
            return
        cid = str(sample.key_expr).rsplit("/", 1)[-1]
        conn = self._live.get(cid)
        if conn is not None:
            conn.pipe.end()

    # --- on the hello worker's thread -------------------------------------------------------------
    def _answer_hello(self, query) -> None:
        try:
            cid, controller_public = _parse_hello(query.payload.to_bytes() if query.payload is not None else b"")
        except (ValueError, KeyError, TypeError):
            self.refused.add("unreadable hello")
            query.reply_err(b"bad hello (a JSON object with id and key)")
            return
        if cid in self._live:
            self.refused.add("connection id in use")
            query.reply_err(b"connection id in use")
            return
        handshake = Handshake()
        try:
            down, up = handshake.keys(controller_public, controller_public, handshake.public,
                                      self.address.keyexpr("c", cid))
        except KeyAgreementError:
            self.refused.add("unusable public key")
            query.reply_err(b"unusable public key")
            return
        self._expire_offers()
        self._live[cid] = Connection(self, cid, Opener(down), Sealer(up))
        query.reply(query.key_expr, json.dumps({"key": handshake.public.hex()}).encode())

    def _expire_offers(self) -> None:
        """Forget connections whose hello was answered but that sent no frame: the oldest
        beyond MAX_OFFERS, and any older than OFFER_TTL_S."""
        now = time.monotonic()
        offers = [c for c in list(self._live.values()) if not c.announced]
        stale = [c for c in offers if now - c.created > OFFER_TTL_S]
        stale += offers[:max(0, len(offers) - MAX_OFFERS + 1)]
        for c in stale:
            c.close()

    # --- the server's side -----------------------------------------------------------------------------
    def fileno(self) -> int:
        return self._wake.outlet.fileno()

    def accept(self) -> list["Connection"]:
        """Connections whose first authenticated frame arrived since the last call."""
        while self._wake.read(4096):
            pass
        with self._lock:
            out = list(self._new)
            self._new.clear()
        return out

    def forget(self, conn: "Connection") -> None:
        if self._live.get(conn.id) is conn:
            self._live.pop(conn.id, None)
            for why, n in conn.opener.rejected.counts.items():
                self.closed_rejections.counts[why] = self.closed_rejections.counts.get(why, 0) + n

    def _rejected_total(self) -> int:
        return (self.stray + self.closed_rejections.total
                + sum(c.opener.rejected.total for c in list(self._live.values())))

    def _rejected_describe(self) -> str:
        r = Rejections(dict(self.closed_rejections.counts))
        for c in list(self._live.values()):
            for why, n in c.opener.rejected.counts.items():
                r.counts[why] = r.counts.get(why, 0) + n
        if self.stray:
            r.counts["for no connection"] = self.stray
        return r.describe()

    def info(self) -> dict:
        """What the endpoint dropped, by kind, and the lines it reported (the control channel's ``events``)."""
        return {"rejected": self._rejected_total(), "rejected_why": self._rejected_describe(),
                "hello_asked": self._hellos.offered, "hello_dropped": self._hellos.dropped,
                "hello_refused": self.refused.total, "connections": len(self._live),
                "reports": [line for e in self.episodes for line in e.lines]}

    def report(self) -> list[str]:
        """Lines that say, once per flood, what was dropped and why (the server logs them);
        looks at most every REPORT_S."""
        now = time.monotonic()
        if now < self._next_report:
            return []
        self._next_report = now + REPORT_S
        return [line for e in self.episodes if (line := e.poll(now)) is not None]

    def close(self) -> None:
        undeclare(self.hello, self.down, self.watch, self.token)
        self._hellos.close()
        with self._lock:
            conns = list(self._live.values()) + list(self._new)
            self._new.clear()
        for c in conns:
            c.close()
        try:
            self.session.close()
        except Exception:
            pass
        self._wake.close()


class Connection:
    """One controller's byte stream at the robot (non-blocking reads, sealed publications out)."""

    def __init__(self, endpoint: RobotEndpoint, cid: str, opener: Opener, sealer: Sealer) -> None:
        a = endpoint.address
        self.endpoint = endpoint
        self.id = cid
        self.address = f"zenoh connection {cid}"
        self.opener, self.sealer = opener, sealer
        self.created = time.monotonic()
        self.announced = False          # its first authenticated frame came: handed to the server
        self.pipe = _Pipe()
        self.pub = _declare_publisher(endpoint.session, a.keyexpr("c", cid, "up"))

    def received(self, sealed: bytes) -> bool:
        """On a Zenoh thread: a publication on this connection's ``down`` key; True if it was
        the controller's (its frame bytes go to the reader), False if dropped."""
        frame = self.opener.open(sealed)
        if frame is None:
            return False
        self.pipe.push(frame)
        return True

    def fileno(self) -> int:
        return self.pipe.outlet.fileno()

    def read(self) -> bytes | None:
        return self.pipe.read()

    def write(self, data: bytes) -> bool:
        try:
            _put(self.pub, self.sealer.seal(bytes(data)))
            return True
        except Exception:
            return False

    def wants_write(self) -> bool:
        return False        # publications queue in Zenoh, not here

    def flush(self) -> bool:
        return True

    def close(self) -> None:
        self.endpoint.forget(self)
        undeclare(self.pub)
        self.pipe.close()
