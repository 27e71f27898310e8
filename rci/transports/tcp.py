"""``socket://host:port``: TCP, as simula (and a robot with a network interface) serves it.

Non-blocking once connected: the link waits on the socket with ``select``; one small frame
per cycle each way, so Nagle's algorithm is off (it would hold a CHG back until the
previous one is acknowledged, costing a cycle at high rates).
"""
from __future__ import annotations

import select
import socket
from urllib.parse import urlsplit

from ..exceptions import DeviceError, LinkClosed

SCHEME = "socket://"


class TcpTransport:
    """A connected TCP socket (rci.transports.Transport)."""

    def __init__(self, sock: socket.socket, description: str, write_timeout: float) -> None:
        self.sock = sock
        self.description = description
        self.write_timeout = write_timeout
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        sock.setblocking(False)
        self._open = True

    def fileno(self) -> int | None:
        return self.sock.fileno() if self._open else None

    def read(self, n: int, timeout: float = 0.0) -> bytes:
        try:
            data = self.sock.recv(n)
        except (BlockingIOError, InterruptedError):
            return b""
        except OSError as e:
            raise LinkClosed(f"{self.description}: {e}") from None
        if not data:
            raise LinkClosed(f"{self.description}: socket disconnected")
        return data

    def write(self, data: bytes) -> None:
        view = memoryview(data)
        while view:
            try:
                n = self.sock.send(view)
            except (BlockingIOError, InterruptedError):
                n = 0
            except OSError as e:
                raise LinkClosed(f"{self.description}: write failed: {e}") from None
            view = view[n:]
            if view:        # the socket's buffer is full: wait for room, not forever
                _, ready, _ = select.select([], [self.sock], [], self.write_timeout)
                if not ready:
                    raise LinkClosed(f"{self.description}: write failed: the robot has not read for "
                                     f"{self.write_timeout} s")

    def close(self) -> None:
        if not self._open:
            return
        self._open = False
        try:
            self.sock.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass
        self.sock.close()

    @property
    def is_open(self) -> bool:
        return self._open


def open_transport(url: str, *, timeout: float = 5.0, priority: int = 0) -> TcpTransport:  # noqa: ARG001
    parts = urlsplit(url)
    try:
        host, port = parts.hostname, parts.port
    except ValueError as e:
        raise DeviceError(f"cannot open robot link {url!r}: {e}") from None
    if not host or port is None:
        raise DeviceError(f"cannot open robot link {url!r}: expected socket://HOST:PORT")
    try:
        sock = socket.create_connection((host, port), timeout=timeout)
    except OSError as e:
        raise DeviceError(f"cannot open robot link {url!r}: {e}") from None
    return TcpTransport(sock, url, timeout)
