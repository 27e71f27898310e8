"""Shared data and channels between processes and hosts, on the Zenoh bus (thesis 2.4.2.2).

``rci.multi`` gives the control tasks of one process shared data (mode t1) and channels
(t2, t3). When the tasks run in different processes, or on different hosts (one arm's
control task per processor, thesis 2.4.3), :class:`Bus` gives them the same two things
with the same Python API, carried by Zenoh:

    from rci.bus import Bus
    with Bus("lab", tasks=("microbo",), connect=("tcp/10.0.0.1:7447",)) as bus:   # the tasks of this process
        bus.shared["puma_q"] = q                                  # t1: the latest value, everywhere
        seen = bus.shared.get("puma_q")
        reports = bus.channel("microbo", "planning", capacity=8)  # t3 (drop_oldest) or t2/t3 (block)
        reports.send({"waist": 0.1})                              # in the microbo's process
        reports.receive(timeout=1.0)                              # in the planning process

Key expressions (``CELL`` is the workcell's name):

``rcci/CELL/shared/NAME``               every write of shared value NAME (the latest wins)
``rcci/CELL/channel/SENDER/RECEIVER``   the channel's messages, in order
``rcci/CELL/channel/SENDER/RECEIVER/ack``  the receiver's count of messages taken (flow control)

Semantics, as in one process: a shared value is written and read whole; a process that
joins late asks the others for the current values (a Zenoh query) before it reads. A
channel's queue lives at its receiver: ``drop_oldest`` loses the oldest there (counted in
``dropped`` on the receiving side); ``block`` holds the sender until the receiver has taken
enough (the receiver's acknowledgements are the credit: no message is lost, t2);
``error`` raises ``ChannelFull`` in the sender when the receiver's queue is full as far
as the sender knows. A control task never waits (``ChannelFull`` instead), as in
``rci.multi``. Messages and values are numbers, strings, None, booleans, lists, tuples,
dicts with string keys and numpy arrays (encoded as JSON: nothing is unpickled from the
network).
"""
from __future__ import annotations

import base64
import collections
import json
import threading
from typing import Any, Callable

import numpy as np

from ..workcell_data import OVERFLOW, ChannelFull, MultiError
from .session import ZenohLinkError, configured_endpoints, load_config, open_session, undeclare


# --- the codec -------------------------------------------------------------------------
def encode(value: Any) -> bytes:
    """A value as JSON bytes (numpy arrays and tuples kept as such)."""
    return json.dumps(_to_json(value), separators=(",", ":")).encode()


def decode(data: bytes) -> Any:
    return _from_json(json.loads(data))


def _to_json(v: Any) -> Any:
    if v is None or isinstance(v, (bool, int, float, str)):
        return v
    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, np.ndarray):
        a = np.ascontiguousarray(v)
        return {"__nd__": [a.dtype.str, list(a.shape), base64.b64encode(a.tobytes()).decode()]}
    if isinstance(v, tuple):
        return {"__tuple__": [_to_json(x) for x in v]}
    if isinstance(v, list):
        return [_to_json(x) for x in v]
    if isinstance(v, dict):
        if not all(isinstance(k, str) for k in v):
            raise MultiError("bus: dict keys must be strings to cross processes")
        if "__nd__" in v or "__tuple__" in v:
            raise MultiError("bus: '__nd__' and '__tuple__' are reserved dict keys")
        return {k: _to_json(x) for k, x in v.items()}
    raise MultiError(f"bus: a {type(v).__name__} cannot cross processes (numbers, strings, lists, "
                     "tuples, dicts with string keys, numpy arrays)")


def _from_json(v: Any) -> Any:
    if isinstance(v, list):
        return [_from_json(x) for x in v]
    if isinstance(v, dict):
        if "__nd__" in v and len(v) == 1:
            dtype, shape, data = v["__nd__"]
            return np.frombuffer(base64.b64decode(data), dtype=np.dtype(dtype)).reshape(shape).copy()
        if "__tuple__" in v and len(v) == 1:
            return tuple(_from_json(x) for x in v["__tuple__"])
        return {k: _from_json(x) for k, x in v.items()}
    return v


# --- shared data (t1) --------------------------------------------------------------------
class BusShared:
    """``rci.multi.Shared`` across processes: ``put``/``get``/``[]``/``in``; names are strings."""

    def __init__(self, bus: "Bus") -> None:
        self._bus = bus
        self._values: dict[str, Any] = {}
        self._own: dict[str, bytes] = {}          # this process's writes, answered to late joiners
        self._lock = threading.Lock()
        self._publishers: dict[str, Any] = {}
        s, cell = bus.session, bus.cell
        self._sub = s.declare_subscriber(f"rcci/{cell}/shared/*", self._on_sample)
        self._queryable = s.declare_queryable(f"rcci/{cell}/shared/*", self._on_query)
        for reply in s.get(f"rcci/{cell}/shared/*", timeout=bus.join_timeout):
            if reply.ok is not None:
                self._on_sample(reply.ok)

    def _on_sample(self, sample) -> None:
        name = str(sample.key_expr).rsplit("/", 1)[-1]
        try:
            value = decode(sample.payload.to_bytes())
        except (ValueError, KeyError, TypeError):
            return                                   # not ours: ignored
        with self._lock:
            self._values[name] = value

    def _on_query(self, query) -> None:
        with self._lock:
            own = dict(self._own)
        for name, data in own.items():
            query.reply(f"rcci/{self._bus.cell}/shared/{name}", data)

    def put(self, name: str, value: Any) -> None:
        if not isinstance(name, str) or not name or any(c in name for c in "/*$#? "):
            raise MultiError(f"bus shared data: the name must be a plain string, not {name!r}")
        data = encode(value)
        with self._lock:
            self._values[name] = decode(data)        # a copy, as in one process
            self._own[name] = data
            pub = self._publishers.get(name)
        if pub is None:
            pub = self._bus.session.declare_publisher(f"rcci/{self._bus.cell}/shared/{name}")
            with self._lock:
                self._publishers[name] = pub
        pub.put(data)

    def get(self, name: str, default: Any = None) -> Any:
        with self._lock:
            v = self._values.get(name, default)
        return _from_json(_to_json(v)) if v is not default else v

    def __getitem__(self, name: str) -> Any:
        with self._lock:
            if name not in self._values:
                raise KeyError(f"shared data on the bus has no {name!r} (yet): names are {sorted(self._values)}")
        return self.get(name)

    def __setitem__(self, name: str, value: Any) -> None:
        self.put(name, value)

    def __contains__(self, name: str) -> bool:
        with self._lock:
            return name in self._values

    def commit(self) -> None:
        """Nothing to do: every write is published at once (no lockstep barrier across processes)."""

    def close(self) -> None:
        undeclare(self._sub, self._queryable, *self._publishers.values())


# --- channels (t2, t3) -------------------------------------------------------------------
class BusChannel:
    """``rci.multi.Channel`` across processes. Open it with the same arguments in the
    sender's and the receiver's process (:meth:`Bus.channel`); each end does its half: the
    receiving process (the receiver is one of its tasks) keeps the queue, the sending one
    counts the receiver's acknowledgements."""

    def __init__(self, bus: "Bus", sender: str, receiver: str, capacity: int = 16, overflow: str = "drop_oldest",
                 is_control_thread: Callable[[], bool] = lambda: False) -> None:
        if overflow not in OVERFLOW:
            raise MultiError(f"channel {sender}->{receiver}: overflow must be one of {OVERFLOW}, not {overflow!r}")
        if int(capacity) < 1:
            raise MultiError(f"channel {sender}->{receiver}: capacity must be >= 1, not {capacity!r}")
        for who in (sender, receiver):
            if not who or any(c in who for c in "/*$#? "):
                raise MultiError(f"channel {sender}->{receiver}: task names must be plain strings")
        self.sender, self.receiver = sender, receiver
        self.capacity, self.overflow = int(capacity), overflow
        self.dropped = 0            # receiving end: messages lost to drop_oldest
        self.sent = 0               # sending end: messages sent
        self.taken = 0              # receiving end: messages received
        self._acked = 0             # sending end: the receiver's count of messages taken
        self._items: collections.deque = collections.deque()
        self._cond = threading.Condition()
        self._in_control = is_control_thread
        key = f"rcci/{bus.cell}/channel/{sender}/{receiver}"
        s = bus.session
        import zenoh

        block = zenoh.CongestionControl.BLOCK
        self.receiving = receiver in bus.tasks
        self.sending = sender in bus.tasks
        self._declared = []
        if self.sending:
            self._pub = s.declare_publisher(key, congestion_control=block)
            self._declared += [self._pub, s.declare_subscriber(key + "/ack", self._on_ack)]
        if self.receiving:
            self._ack_pub = s.declare_publisher(key + "/ack", congestion_control=block)
            self._declared += [self._ack_pub, s.declare_subscriber(key, self._on_message)]

    def __repr__(self) -> str:
        return f"BusChannel({self.sender!r} -> {self.receiver!r}, {len(self)}/{self.capacity}, {self.overflow})"

    def __len__(self) -> int:
        """Messages waiting at this end (the receiving end's queue)."""
        return len(self._items)

    def _on_message(self, sample) -> None:
        try:
            msg = decode(sample.payload.to_bytes())
        except (ValueError, KeyError, TypeError):
            return
        with self._cond:
            if len(self._items) >= self.capacity and self.overflow == "drop_oldest":
                self._items.popleft()
                self.dropped += 1
            self._items.append(msg)
            self._cond.notify_all()

    def _on_ack(self, sample) -> None:
        try:
            n = int(sample.payload.to_bytes())
        except ValueError:
            return
        with self._cond:
            self._acked = max(self._acked, n)
            self._cond.notify_all()

    def send(self, message: Any, timeout: float | None = None) -> None:
        """Publish ``message``; with ``block``/``error``, only while the receiver has room."""
        if message is None:
            raise MultiError(f"channel {self.sender}->{self.receiver}: None cannot be sent "
                             "(receive() returns None for 'no message')")
        if not self.sending:
            raise MultiError(f"channel {self.sender}->{self.receiver}: {self.sender!r} is not a task of this "
                             f"process (Bus(tasks=...)): it cannot send on this channel here")
        data = encode(message)
        with self._cond:
            full = lambda: self.sent - self._acked >= self.capacity    # noqa: E731
            if self.overflow != "drop_oldest" and full():
                if self.overflow == "error" or self._in_control():
                    why = "" if self.overflow == "error" else " (a control task never waits)"
                    raise ChannelFull(f"channel {self.sender}->{self.receiver} is full "
                                      f"({self.capacity} messages not yet taken){why}")
                if not self._cond.wait_for(lambda: not full(), timeout):
                    raise ChannelFull(f"channel {self.sender}->{self.receiver}: still full after {timeout} s")
            self.sent += 1
        self._pub.put(data)

    def receive(self, timeout: float = 0.0) -> Any:
        """The oldest message, or None (after waiting ``timeout`` s, planning level only)."""
        if timeout and self._in_control():
            raise MultiError(f"channel {self.sender}->{self.receiver}: a control task must not wait in receive()")
        if not self.receiving:
            raise MultiError(f"channel {self.sender}->{self.receiver}: {self.receiver!r} is not a task of this "
                             f"process (Bus(tasks=...)): its messages are received in its own process")
        with self._cond:
            if not self._items and timeout:
                self._cond.wait_for(lambda: bool(self._items), timeout)
            if not self._items:
                return None
            msg = self._items.popleft()
            self.taken += 1
            taken = self.taken
        self._ack_pub.put(str(taken).encode())
        return msg

    def commit(self) -> None:
        """Nothing to do across processes (no lockstep barrier)."""

    def close(self) -> None:
        undeclare(*self._declared)


# --- the bus ----------------------------------------------------------------------------
class Bus:
    """This process's place on the Zenoh bus for the workcell ``cell``; ``tasks`` are the
    names of the tasks that run in this process (arms' control tasks, ``"planning"``). A
    bus that only listens (the process the others connect to) routes between the others
    (a Zenoh router), unless ``router`` says otherwise. ``priority`` > 0: Zenoh's threads
    run under SCHED_FIFO at that priority where the OS allows (what crosses the bus then
    keeps moving on a loaded machine; arm processes use it for their event flags).
    ``config``: a Zenoh configuration file (TLS, authentication, access control, endpoints;
    default ``$RCI_ZENOH_CONFIG``: rci.bus.session); ``connect`` / ``listen`` replace its
    endpoints."""

    def __init__(self, cell: str, tasks: tuple[str, ...] | list[str], connect: tuple[str, ...] = (),
                 listen: tuple[str, ...] = (), join_timeout: float = 0.5, lease_ms: int | None = None,
                 router: bool | None = None, priority: int = 0, config: str | None = None) -> None:
        if not cell or any(c in cell for c in "*$#? "):
            raise MultiError(f"bus: the workcell's name must be a plain key expression, not {cell!r}")
        if isinstance(tasks, str) or not tasks:
            raise MultiError("bus: tasks must name the tasks of this process, e.g. ('puma',) or ('planning',)")
        self.cell = cell.strip("/")
        self.tasks = frozenset(tasks)
        self.priority = int(priority)    # SCHED_FIFO asked for Zenoh's threads (and the heartbeats of rccl.bus.planning)
        self.join_timeout = join_timeout
        try:
            if not connect and not listen:       # the endpoints of the user's configuration file
                conf = load_config(config)
                connect, listen = configured_endpoints(conf, "connect"), configured_endpoints(conf, "listen")
            # the process the others connect to (it listens and connects nowhere) routes between
            # them: two arm processes connected to the planning process reach each other through it
            hub = bool(listen) and not connect if router is None else router
            # a process that only connects is the hub's client: everything it says goes through
            # the hub. As a peer it would be told of the other peers and, believing them
            # reachable directly, the hub would stop forwarding between them (seen: an arm
            # process unreachable through the hub while its TCP link stayed up)
            spoke = bool(connect) and not listen and not hub
            self.session = open_session(tuple(connect), tuple(listen), lease_ms, priority, router=hub, client=spoke,
                                        config=config)
        except ZenohLinkError as exc:
            raise MultiError(f"bus {cell!r}: {exc}") from None
        self.shared = BusShared(self)
        self._channels: dict[tuple[str, str], BusChannel] = {}

    def channel(self, sender: str, receiver: str, capacity: int = 16, overflow: str = "drop_oldest",
                is_control_thread: Callable[[], bool] = lambda: False) -> BusChannel:
        """The channel ``sender`` -> ``receiver`` (the same object for the same pair)."""
        key = (sender, receiver)
        if key not in self._channels:
            self._channels[key] = BusChannel(self, sender, receiver, capacity, overflow, is_control_thread)
        return self._channels[key]

    def close(self) -> None:
        for ch in self._channels.values():
            ch.close()
        self.shared.close()
        try:
            self.session.close()
        except Exception:
            pass

    def __enter__(self) -> "Bus":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
