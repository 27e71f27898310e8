"""``tcp``: simula listens on a TCP port; each controller is one connection (``socket://host:port``).

The robot side of ``rci.transports.tcp``. A connection is non-blocking with a bounded queue
of unsent bytes: a controller that stops reading must not freeze the robot, and one whose
queue overflows counts as gone.
"""
from __future__ import annotations

import socket

from . import ClientTransport

NAME = "tcp"
SCHEME = "socket://"
MAX_UNSENT = 1 << 16       # bytes queued to a controller that does not read before it counts as gone
BACKLOG = 8                # connections the kernel queues before simula accepts them


class SocketTransport(ClientTransport):
    """A non-blocking TCP connection with a bounded queue of unsent bytes."""

    def __init__(self, sock: socket.socket, address: str = "") -> None:
        self.sock = sock
        self.address = address
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        sock.setblocking(False)     # a client that stops reading must not freeze the robot
        self.out = bytearray()

    def fileno(self) -> int:
        return self.sock.fileno()

    def read(self) -> bytes | None:
        try:
            data = self.sock.recv(65536)
        except (BlockingIOError, InterruptedError):
            return b""
        except OSError:
            return None
        return data or None

    def write(self, data: bytes) -> bool:
        if self.out:
            self.out += data
            return self.flush()
        try:
            n = self.sock.send(data)
        except (BlockingIOError, InterruptedError):
            n = 0
        except OSError:
            return False
        if n < len(data):
            self.out += data[n:]
        return len(self.out) <= MAX_UNSENT

    def wants_write(self) -> bool:
        return bool(self.out)

    def flush(self) -> bool:
        if self.out:
            try:
                n = self.sock.send(self.out)
            except (BlockingIOError, InterruptedError):
                n = 0
            except OSError:
                return False
            del self.out[:n]
        return len(self.out) <= MAX_UNSENT

    def close(self) -> None:
        try:
            self.sock.close()
        except OSError:
            pass


class TcpListener:
    """A listening TCP socket (rci.simula.listeners.Listener)."""

    line = None

    def __init__(self, host: str, port: int) -> None:
        s = socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET, socket.SOCK_STREAM)
        try:
            s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            s.bind((host, port))
            s.listen(BACKLOG)
            s.setblocking(False)
        except OSError:
            s.close()
            raise
        self.sock = s
        self.url = f"{SCHEME}{host}:{s.getsockname()[1]}"

    def fileno(self) -> int | None:
        return self.sock.fileno()

    def accept(self) -> list[ClientTransport]:
        try:
            conn, addr = self.sock.accept()
        except (BlockingIOError, InterruptedError, OSError):
            return []
        address = f"{addr[0]}:{addr[1]}" if isinstance(addr, tuple) else str(addr)
        return [SocketTransport(conn, address)]

    def report(self) -> list[str]:
        return []

    def info(self) -> dict | None:
        return None

    def close(self) -> None:
        self.sock.close()


def open_listener(*, host: str = "127.0.0.1", port: int = 0) -> TcpListener:
    """Listen on ``host:port`` (port 0: a free one, named in ``url``); OSError if the bind fails."""
    return TcpListener(host, port)
