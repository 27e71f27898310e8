"""``pty``: simula serves a pseudo-terminal, one line for one controller at a time (``/dev/pts/N``).

The robot side of ``rci.transports.serial_line`` (pyserial opens the slave path, as it would
a real serial line). The line is there before any program opens it and stays after each
one ends: it is the listener's ``line``, never accepted. One line, one controller: rci
opens a device path with an exclusive lock, so a second program cannot open it while the
first has it (docs/protocol.md, "Ownership").
"""
from __future__ import annotations

import errno
import os
import tty

from . import ClientTransport

NAME = "pty"
SCHEME = "/dev/"            # a device path: its twin, rci.transports.serial_line, is the fallback there


class PtyTransport(ClientTransport):
    """The master side of a pseudo-terminal; the controller opens the slave path with pyserial."""

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


class PtyListener:
    """One pseudo-terminal (rci.simula.listeners.Listener): nothing to accept, one ``line``."""

    def __init__(self) -> None:
        self.line = PtyTransport()
        self.url = self.line.path

    def fileno(self) -> int | None:
        return None

    def accept(self) -> list[ClientTransport]:
        return []

    def report(self) -> list[str]:
        return []

    def info(self) -> dict | None:
        return None

    def close(self) -> None:
        self.line.close()


def open_listener() -> PtyListener:
    """A new pseudo-terminal; its slave path is ``url``."""
    return PtyListener()
