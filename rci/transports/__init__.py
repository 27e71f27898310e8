"""Byte transports under the robot link's framing (rci.link), one module per kind, chosen
by the link address the way pyserial's URL handlers are.

| address | module |
|---|---|
| ``socket://host:port`` (simula, a robot's network interface) | ``tcp.py`` |
| ``zenoh/KEY?connect=...`` (the Zenoh bus, docs/zenoh.md) | ``zenoh.py`` |
| anything else: a device path (``/dev/ttyUSB0``, a pty ``/dev/pts/5``), ``loop://`` | ``serial_line.py`` (pyserial) |

A transport moves bytes and nothing else (:class:`Transport`); the link above it frames
them. To add one (a field bus, a shared-memory ring), write a module here with ``SCHEME``
(the address prefix it serves) and ``open_transport(url, timeout, priority) ->
Transport``; :func:`open_transport` finds it.
"""
from __future__ import annotations

from functools import cache
from typing import Protocol, runtime_checkable

from ..plugins import declared, module


@runtime_checkable
class Transport(Protocol):
    """A byte stream to the robot. ``read`` never blocks when ``fileno()`` is a descriptor
    (the link waits on it with ``select``); without one it waits up to ``timeout`` itself."""

    description: str          # for messages: the address and what it is

    def fileno(self) -> int | None:
        """A descriptor that is readable when bytes (or end of file) are waiting, or None."""

    def read(self, n: int, timeout: float = 0.0) -> bytes:
        """Up to ``n`` bytes that are there (b"" if none); raises LinkClosed at end of file."""

    def write(self, data: bytes) -> None:
        """Write all of ``data``; raises LinkClosed if the other end is gone or stuck."""

    def close(self) -> None:
        """Close; idempotent."""

    @property
    def is_open(self) -> bool:
        """False once closed."""


FALLBACK = "serial_line"


@cache
def _kinds() -> dict[str, str]:
    """Address prefix -> module name, for every module of this package that declares SCHEME."""
    return declared(__name__, __path__, "SCHEME")


def open_transport(url: str, *, timeout: float = 5.0, priority: int = 0) -> Transport:
    """The transport for ``url`` (module docstring), opened; DeviceError if it cannot be."""
    name = next((m for prefix, m in _kinds().items() if url.startswith(prefix)), FALLBACK)
    return module(__name__, name).open_transport(url, timeout=timeout, priority=priority)
