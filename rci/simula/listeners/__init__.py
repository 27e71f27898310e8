"""simula's endpoints: where controllers reach the robot, one module per kind, the robot-side
mirror of ``rci.transports`` (a kind of link is one file on each side).

| kind | module | address a controller opens (line 1 of simula's output) |
|---|---|---|
| ``tcp`` (default; ``--host``, ``--port``) | ``tcp.py`` | ``socket://host:port`` |
| ``pty`` (``--pty``) | ``pty.py`` | the pseudo-terminal's device path, ``/dev/pts/N`` |
| ``zenoh`` (``--zenoh KEY``) | ``zenoh.py`` | ``zenoh/KEY?connect=...`` (docs/zenoh.md) |

A :class:`Listener` hands the server new connections (:class:`ClientTransport`: byte pipes
that never block the robot); the server (rci.simula.server) decides who owns the arm. To add
one, write a module here with ``NAME`` (what the server is asked for), ``SCHEME`` (the
prefix of the address it prints, the ``SCHEME`` of the matching ``rci.transports`` module)
and ``open_listener(**options) -> Listener``; :func:`open_listener` finds it by name.
"""
from __future__ import annotations

from functools import cache
from typing import Protocol

from ...plugins import declared, module


class ClientTransport:
    """A byte pipe to one client: ``fileno``, ``read``, ``write``, ``flush``, ``close``; never blocks.

    The Zenoh bus's connections (rci.bus.link.Connection) have the same shape."""

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


class Listener(Protocol):
    """Where controllers connect. Either it accepts connections (``fileno`` is a descriptor
    readable when :meth:`accept` has some), or it is one point-to-point line (``line``: its
    one connection, there from the start and outliving each program that opens it)."""

    url: str                            # the address a controller opens
    line: ClientTransport | None        # a point-to-point line's one connection, else None

    def fileno(self) -> int | None:
        """Readable when :meth:`accept` has new connections; None if it never has any."""

    def accept(self) -> list[ClientTransport]:
        """The connections that have come in (possibly none); never blocks."""

    def report(self) -> list[str]:
        """Log lines about what the endpoint refused or dropped since the last call."""

    def info(self) -> dict | None:
        """What the control channel's ``events`` shows of the endpoint (None: nothing)."""

    def close(self) -> None:
        """Stop listening; idempotent. Connections already handed out are closed by the server."""


class UnknownListener(ValueError):
    """A listener kind that no module of this package serves."""


@cache
def kinds() -> dict[str, str]:
    """Listener name -> module name, for every module of this package that declares NAME."""
    return declared(__name__, __path__, "NAME")


def open_listener(name: str, **options) -> Listener:
    """The listener of kind ``name`` (``tcp``, ``pty``, ``zenoh``: module docstring), open;
    OSError (from the endpoint) if it cannot be, UnknownListener for an unknown kind."""
    module_name = kinds().get(name)
    if module_name is None:
        raise UnknownListener(f"no simula listener {name!r} (known: {', '.join(sorted(kinds()))})")
    return module(__name__, module_name).open_listener(**options)
