"""simula's side of one controller's connection: a byte pipe that never blocks the robot.

``ClientTransport`` (``fileno``, ``read``, ``write``, ``flush``, ``close``) with a TCP
connection (``SocketTransport``, a bounded queue of unsent bytes) and a pseudo-terminal
(``PtyTransport``); the Zenoh bus's connections (rci.bus.link.Connection) have the same
shape. rci.simula.server serves controllers through them.
"""
from __future__ import annotations

import errno
import os
import socket
import tty

MAX_UNSENT = 1 << 16       # bytes queued to a controller that does not read before it counts as gone


class ClientTransport:
    """A byte pipe to one client: ``fileno``, ``read``, ``write``, ``flush``, ``close``; never blocks."""

    address = ""

    def fileno(self) -> int:
        raise NotImplementedError

    def read(self) -> bytes | None:
        """What is there (b"" if nothing), or None at end of file."""
        raise NotImplementedError

    def write(self, data: bytes) -> bool:
        """Queue and send what the peer accepts; False if the peer is gone or does not read."""
        raise NotImplementedError

    def wants_write(self) -> bool:
        return False

    def flush(self) -> bool:
        return True

    def close(self) -> None:
        pass


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


class PtyTransport(ClientTransport):
    """The master side of a pseudo-terminal; the controller opens the slave path with pyserial.

    One line, one controller: rci opens a device path with an exclusive lock, so a second
    program cannot open it while the first has it (docs/protocol.md, "Ownership").
    """

    def __init__(self) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)              # no echo, no line discipline: a byte pipe
        os.set_blocking(self.master, False)
        self.path = os.ttyname(self.slave)  # the slave stays open so a closing client gives no EIO
        self.address = self.path

    def fileno(self) -> int:
        return self.master

    def read(self) -> bytes | None:
        try:
            return os.read(self.master, 65536)
        except (BlockingIOError, OSError):
            return b""                      # a pty has no end of file: a new program may open it

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
