"""simula's control channel: a line-based text side door for tests and demonstrations.

Not part of the RCI protocol (a real arm has no such door): it lets a test play the
world around the arm, e.g. push a joint while the zero-gravity program runs. One
command per line, one JSON reply per line (``{"ok": true, ...}`` or ``{"ok": false,
"error": "..."}``)::

    torque <joint 1..n> <N*m or N>   apply an external joint torque (the world pushes)
    torque clear                     remove all external torques
    load pulley:joint=J,mass=M,radius=R[,sign=S] | load none
    state                            the arm's state (angles, modes, calibration, currents)
    ping                             liveness check

Listens on loopback only, on the port given with ``--control-port`` (0: any free port,
printed on simula's second stdout line).
"""
from __future__ import annotations

import json
import socket
from typing import TYPE_CHECKING

import numpy as np

from .params import parse_load

if TYPE_CHECKING:  # pragma: no cover
    from .server import Server

MAX_LINE = 4096


def execute(line: str, server: "Server") -> dict:
    """Run one control command against the server's arm; returns the reply object."""
    arm = server.arm
    words = line.split()
    if not words:
        return {"ok": False, "error": "empty command"}
    cmd, args = words[0].lower(), words[1:]
    try:
        if cmd == "ping":
            return {"ok": True, "t": arm.t}
        if cmd == "state":
            return {"ok": True, "state": arm.snapshot(), "cycle": server.seq,
                    "running": bool(server.session and server.session.running)}
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
    return {"ok": False, "error": f"unknown command {cmd!r} (torque, load, state, ping)"}


class ControlChannel:
    """TCP listener plus its connected clients, served from the server's select loop."""

    def __init__(self, host: str = "127.0.0.1", port: int = 0) -> None:
        self.listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.listener.bind((host, port))
        self.listener.listen(4)
        self.clients: dict[socket.socket, bytearray] = {}

    @property
    def url(self) -> str:
        host, port = self.listener.getsockname()[:2]
        return f"socket://{host}:{port}"

    def fds(self) -> list:
        return [self.listener, *self.clients]

    def on_readable(self, sock, server: "Server") -> None:
        if sock is self.listener:
            conn, _ = self.listener.accept()
            self.clients[conn] = bytearray()
            return
        if sock not in self.clients:
            return
        try:
            data = sock.recv(4096)
        except OSError:
            data = b""
        if not data:
            self._close(sock)
            return
        buf = self.clients[sock]
        buf += data
        while b"\n" in buf:
            raw, _, rest = bytes(buf).partition(b"\n")
            buf[:] = rest
            reply = execute(raw.decode("utf-8", "replace").strip(), server)
            try:
                sock.sendall((json.dumps(reply) + "\n").encode())
            except OSError:
                self._close(sock)
                return
        if len(buf) > MAX_LINE:
            self._close(sock)

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
