"""simula's control channel: a line-based text side door for tests and demonstrations.

Not part of the RCI protocol (a real arm has no such door). One command per line, one
JSON reply per line (``{"ok": true, ...}`` or ``{"ok": false, "error": "..."}``)::

    state                            the arm's state (angles, modes, calibration, currents, owner)
    events                           the last control endings (cause, time, arm position) and ticks
    ping                             liveness check

and, only when simula was started with ``--test-channel`` (the test channel plays the
world around the arm, e.g. pushes a joint while the zero-gravity program runs)::

    torque <joint 1..n> <N*m or N>   apply an external joint torque (the world pushes)
    torque clear                     remove all external torques
    load pulley:joint=J,mass=M,radius=R[,sign=S] | load none

Listens on loopback only, on the port given with ``--control-port`` (0: any free port,
printed on simula's second stdout line).

The channel shares simula's only loop with the robot link, so it never blocks and its
work is bounded: sockets are non-blocking, each loop pass runs at most ``BUDGET``
commands (the rest wait for the next pass), a client's queued replies are sent as its
socket accepts them, and a client that sends an over-long line, queues too many
commands or stops reading its replies is disconnected.
"""
from __future__ import annotations

import json
import socket
from collections import deque
from typing import Any, Protocol

import numpy as np

from .params import parse_load

MAX_LINE = 4096          # bytes in one command line
MAX_QUEUED = 64          # commands waiting per client
MAX_REPLY_BYTES = 1 << 18  # replies waiting per client (a client that stops reading)
BUDGET = 4               # commands run per pass of simula's loop, over all clients
TEST_COMMANDS = ("torque", "load")


class ServedRobot(Protocol):
    """What the channel reads of simula's server (``rci.simula.server.Server``, which imports
    this module: a protocol here, not an import back)."""

    arm: Any                   # the SimulatedArm
    seq: int                   # the latest HOW's cycle number
    session: Any               # the owner's Client, or None

    def owner_info(self) -> dict | None: ...

    def events_info(self) -> dict: ...


def execute(line: str, server: "ServedRobot", *, test_commands: bool = False) -> dict:
    """Run one control command against the server's arm; returns the reply object."""
    arm = server.arm
    words = line.split()
    if not words:
        return {"ok": False, "error": "empty command"}
    cmd, args = words[0].lower(), words[1:]
    if cmd in TEST_COMMANDS and not test_commands:
        return {"ok": False, "error": f"{cmd!r} acts on the arm: a test command, refused unless simula was "
                                      f"started with --test-channel"}
    try:
        if cmd == "ping":
            return {"ok": True, "t": arm.t}
        if cmd == "state":
            return {"ok": True, "state": arm.snapshot(), "cycle": server.seq,
                    "running": bool(server.session and server.session.running), "owner": server.owner_info()}
        if cmd == "events":
            return {"ok": True, **server.events_info()}
        if cmd == "torque":
            if args == ["clear"]:
                arm.ext[:] = 0.0
                return {"ok": True, "external_torque": arm.ext.tolist()}
            if len(args) != 2:
                return {"ok": False, "error": "usage: torque <joint 1..n> <value> | torque clear"}
            joint, value = int(args[0]), float(args[1])
            if not 1 <= joint <= arm.n:
                return {"ok": False, "error": f"joint {joint} is not 1..{arm.n}"}
            if not np.isfinite(value):
                return {"ok": False, "error": f"torque {args[1]!r} is not finite"}
            arm.set_external_torque(joint - 1, value)
            return {"ok": True, "external_torque": arm.ext.tolist()}
        if cmd == "load":
            arm.load = parse_load(" ".join(args), arm.n)
            return {"ok": True, "load": None if arm.load is None else vars(arm.load)}
    except ValueError as exc:
        return {"ok": False, "error": str(exc)}
    return {"ok": False, "error": f"unknown command {cmd!r} (state, events, ping; with --test-channel: torque, load)"}


class _Peer:
    """One connected control client: its partial input, queued commands and unsent replies."""

    def __init__(self, sock: socket.socket) -> None:
        self.sock = sock
        self.inbuf = bytearray()
        self.lines: deque[str] = deque()
        self.out = bytearray()


class ControlChannel:
    """TCP listener plus its connected clients, served from the server's select loop.

    ``test_commands``: allow the commands that act on the arm (``torque``, ``load``).
    """

    def __init__(self, host: str = "127.0.0.1", port: int = 0, *, test_commands: bool = False) -> None:
        self.listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.listener.bind((host, port))
        self.listener.listen(4)
        self.listener.setblocking(False)
        self.test_commands = test_commands
        self.clients: dict[socket.socket, _Peer] = {}

    @property
    def url(self) -> str:
        host, port = self.listener.getsockname()[:2]
        return f"socket://{host}:{port}"

    def fds(self) -> list:
        """Sockets to watch for reading."""
        return [self.listener, *self.clients]

    def write_fds(self) -> list:
        """Sockets with replies waiting to be sent."""
        return [s for s, p in self.clients.items() if p.out]

    def pending(self) -> bool:
        """True if commands are waiting to run."""
        return any(p.lines for p in self.clients.values())

    def on_readable(self, sock, server: "ServedRobot | None" = None) -> None:  # noqa: ARG002 (server: older callers)
        """Take in what a socket has (accept, or queue complete lines); runs nothing."""
        if sock is self.listener:
            try:
                conn, _ = self.listener.accept()
            except (BlockingIOError, OSError):
                return
            conn.setblocking(False)
            self.clients[conn] = _Peer(conn)
            return
        peer = self.clients.get(sock)
        if peer is None:
            return
        try:
            data = sock.recv(MAX_LINE)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            data = b""
        if not data:
            self._close(sock)
            return
        peer.inbuf += data
        while True:
            i = peer.inbuf.find(b"\n")
            if i < 0:
                break
            raw = bytes(peer.inbuf[:i])
            del peer.inbuf[: i + 1]
            peer.lines.append(raw.decode("utf-8", "replace").strip())
        if len(peer.inbuf) > MAX_LINE or len(peer.lines) > MAX_QUEUED:
            self._close(sock)            # a line without end, or a flood: not a test client

    def on_writable(self, sock) -> None:
        peer = self.clients.get(sock)
        if peer is not None:
            self._flush(peer)

    def service(self, server: "ServedRobot", budget: int = BUDGET) -> int:
        """Run up to ``budget`` queued commands, one per client in turn; returns how many ran."""
        ran = 0
        while ran < budget:
            progressed = False
            for peer in list(self.clients.values()):
                if ran >= budget:
                    break
                if not peer.lines:
                    continue
                reply = execute(peer.lines.popleft(), server, test_commands=self.test_commands)
                peer.out += (json.dumps(reply) + "\n").encode()
                ran += 1
                progressed = True
                self._flush(peer)
            if not progressed:
                break
        return ran

    def _flush(self, peer: _Peer) -> None:
        if peer.out:
            try:
                n = peer.sock.send(peer.out)
            except (BlockingIOError, InterruptedError):
                n = 0
            except OSError:
                self._close(peer.sock)
                return
            del peer.out[:n]
        if len(peer.out) > MAX_REPLY_BYTES:
            self._close(peer.sock)       # it does not read its replies

    def _close(self, sock) -> None:
        self.clients.pop(sock, None)
        try:
            sock.close()
        except OSError:
            pass

    def close(self) -> None:
        for c in list(self.clients):
            self._close(c)
        self.listener.close()
