"""The Zenoh bus: the robot link ``zenoh/KEY``, shared data and channels between processes, and their security.

``rci.bus.session`` opens every Zenoh session of the project (the user's configuration
file: TLS, authentication, access control); ``rci.bus.link`` is the robot link over the
bus; ``rci.bus.frames`` authenticates its frames (a key agreed per connection, a message
authentication code on each); ``rci.bus.guard`` bounds the work a flood can cause;
``rci.bus.cell`` is shared data and channels between processes (``Bus``);
``rci.bus.keys`` makes a cell's certificate authority, keys and configuration files
(docs/zenoh.md, docs/security.md).
"""
from .cell import Bus, BusChannel, BusShared, decode, encode

__all__ = ["Bus", "BusChannel", "BusShared", "decode", "encode"]
