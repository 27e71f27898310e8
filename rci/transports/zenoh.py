"""``zenoh/KEY?connect=...``: the robot link over the Zenoh bus (docs/zenoh.md).

The controller's end of a connection (rci.bus.link.ControllerPort): frames go out as
publications, what the robot publishes is read from a local socket pair the link can
``select`` on.
"""
from __future__ import annotations

from ..exceptions import DeviceError, LinkClosed
from ..bus.link import PREFIX, ControllerPort, ZenohLinkError

SCHEME = PREFIX


class ZenohTransport:
    """rci.transports.Transport over a ControllerPort."""

    def __init__(self, port: ControllerPort) -> None:
        self.port = port
        self.description = port.portstr

    def fileno(self) -> int | None:
        return self.port.fileno()

    def read(self, n: int, timeout: float = 0.0) -> bytes:   # noqa: ARG002 (it has a descriptor)
        try:
            return self.port.read(n)
        except ZenohLinkError as e:
            raise LinkClosed(str(e)) from None

    def write(self, data: bytes) -> None:
        try:
            self.port.write(data)
        except ZenohLinkError as e:
            raise LinkClosed(str(e)) from None

    def close(self) -> None:
        self.port.close()

    @property
    def is_open(self) -> bool:
        return self.port.is_open


def open_transport(url: str, *, timeout: float = 5.0, priority: int = 0) -> ZenohTransport:
    try:
        return ZenohTransport(ControllerPort(url, timeout=timeout, priority=priority))
    except ZenohLinkError as e:
        raise DeviceError(f"cannot open robot link {url!r}: {e}") from None
