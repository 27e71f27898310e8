"""``zenoh``: simula serves the arm on the Zenoh bus under ``rcci/KEY`` (``zenoh/KEY?connect=...``).

The robot side of ``rci.transports.zenoh``: a thin face over ``rci.bus.link.RobotEndpoint``,
which keeps the endpoint's security where it is (docs/security.md): sealed frames, the
bounded hello worker, the limit on offered connections, and a connection handed out only
once its first authenticated frame has come in.
"""
from __future__ import annotations

import sys

from . import ClientTransport
from ...bus.link import PREFIX, RobotEndpoint, ZenohAddress

NAME = "zenoh"
SCHEME = PREFIX
SWITCH_INTERVAL_S = 5e-5   # how often the serving loop hands the GIL to Zenoh's threads


class ZenohListener:
    """rci.simula.listeners.Listener over a RobotEndpoint."""

    line = None

    def __init__(self, endpoint: RobotEndpoint) -> None:
        self.endpoint = endpoint
        self.url = endpoint.url()

    def fileno(self) -> int | None:
        return self.endpoint.fileno()

    def accept(self) -> list[ClientTransport]:
        return list(self.endpoint.accept())

    def report(self) -> list[str]:
        """Floods on the bus: one line each, with its count."""
        return list(self.endpoint.report())

    def info(self) -> dict | None:
        return self.endpoint.info()

    def close(self) -> None:
        self.endpoint.close()


def open_listener(*, address: ZenohAddress, priority: int = 0) -> ZenohListener:
    """Serve controllers at ``address``; ``priority``: SCHED_FIFO of Zenoh's threads (0: none)."""
    # Zenoh hands every frame to Python on its own threads, which need the GIL the serving
    # loop holds while it computes or spins before a tick: hand it over often (the default
    # 5 ms switch interval would delay a CHG by up to 5 ms)
    sys.setswitchinterval(SWITCH_INTERVAL_S)
    return ZenohListener(RobotEndpoint(address, priority))
