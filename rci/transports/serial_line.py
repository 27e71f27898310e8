"""A serial line or a pseudo-terminal (a device path), or pyserial's ``loop://`` for tests.

A device path is opened with an exclusive lock: one controller per line (docs/protocol.md,
"Ownership"); a second program gets DeviceError at once instead of sharing, and stealing,
the first one's frames.
"""
from __future__ import annotations

import re

import serial

from ..exceptions import DeviceError, LinkClosed

BAUDRATE = 115200


class SerialTransport:
    """A pyserial port (rci.transports.Transport); non-blocking reads where it has a descriptor."""

    def __init__(self, port: serial.SerialBase, description: str) -> None:
        self.port = port
        self.description = description
        port.timeout = 0
        try:
            self._fd: int | None = port.fileno()
        except (AttributeError, NotImplementedError, OSError, serial.SerialException):
            self._fd = None

    def fileno(self) -> int | None:
        return self._fd

    def read(self, n: int, timeout: float = 0.0) -> bytes:
        try:
            if self._fd is not None:
                return self.port.read(n)
            self.port.timeout = max(timeout, 0.0)
            return self.port.read(max(1, min(n, self.port.in_waiting)))
        except (serial.SerialException, OSError) as e:
            raise LinkClosed(f"{self.description}: {e}") from None

    def write(self, data: bytes) -> None:
        try:
            n = self.port.write(data)
            if self._fd is None:
                self.port.flush()
        except (serial.SerialException, OSError) as e:
            raise LinkClosed(f"{self.description}: write failed: {e}") from None
        if n is not None and n != len(data):
            raise LinkClosed(f"{self.description}: short write ({n} of {len(data)} bytes)")

    def close(self) -> None:
        try:
            self.port.close()
        except (serial.SerialException, OSError):
            pass

    @property
    def is_open(self) -> bool:
        return bool(self.port.is_open)


def open_transport(url: str, *, timeout: float = 5.0, priority: int = 0) -> SerialTransport:  # noqa: ARG001
    device = "://" not in url
    try:
        port = serial.serial_for_url(url, baudrate=BAUDRATE, timeout=timeout, write_timeout=timeout,
                                     **({"exclusive": True} if device else {}))
    except (serial.SerialException, OSError, ValueError) as e:
        hint = " (another program has this line open: one controller per line)" \
            if device and "exclusively lock" in str(e) else _address_hint(url)
        raise DeviceError(f"cannot open robot link {url!r}: {e}{hint}") from None
    return SerialTransport(port, url)


_HOST_PORT = re.compile(r"^(?:[a-z]+://)?(\[[0-9a-fA-F:]+\]|[\w.-]+):(\d+)/?$")


def _address_hint(url: str) -> str:
    """For a network address given without ``socket://`` (``127.0.0.1:7600``, ``tcp://host:7600``),
    which pyserial took for a device path or an unknown scheme: the address that was meant."""
    m = _HOST_PORT.match(url)
    if m is None or url.startswith("socket://") or url.startswith("/"):
        return ""
    return (f" (a network address needs the socket:// scheme: did you mean "
            f"'socket://{m.group(1)}:{m.group(2)}'? docs/protocol.md)")
