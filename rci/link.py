"""The robot link: frames (rci.protocol) over a byte transport (rci.transports).

``open_link(url)`` picks the transport by the address, as pyserial's URL handlers do: a
device path such as ``/dev/ttyUSB0`` or a pty slave ``/dev/pts/5``, ``socket://127.0.0.1:7600``
for simula, ``zenoh/KEY`` for the Zenoh bus, ``loop://`` for unit tests. ``Link.recv`` waits
with select() on the transport's descriptor (and on a wake-up pipe another thread can
write to), so the control task never spins. A new kind of link is a new module in
rci/transports/, nothing here.
"""
from __future__ import annotations

import os
import select
import time

from .exceptions import LinkClosed
from .protocol import Frame, FrameDecoder, encode_frame
from .transports import Transport, open_transport


class Link:
    """A framed, bidirectional link to the robot (or simula) over a transport (rci.transports)."""

    def __init__(self, transport: Transport, url: str = "") -> None:
        self.transport = transport
        self.url = url or transport.description
        self.decoder = FrameDecoder()
        self._fd = transport.fileno()
        self.bytes_in = 0
        self.bytes_out = 0
        # a pipe that another thread writes to, to end a recv() wait early (release)
        self._wake_r, self._wake_w = os.pipe()
        os.set_blocking(self._wake_r, False)
        os.set_blocking(self._wake_w, False)
        self._woken = False

    def wake(self) -> None:
        """Make a recv() in progress (in another thread) return None now."""
        try:
            os.write(self._wake_w, b"w")
        except (BlockingIOError, OSError):
            pass

    def _consume_wake(self) -> None:
        try:
            while os.read(self._wake_r, 64):
                pass
        except (BlockingIOError, OSError):
            pass

    # --- sending -------------------------------------------------------------------
    def send(self, ftype: int, seq: int, payload: bytes = b"") -> None:
        """Encode and write one frame; LinkClosed if the transport is gone."""
        data = encode_frame(ftype, seq, payload)
        self.transport.write(data)
        self.bytes_out += len(data)

    def send_raw(self, data: bytes) -> None:
        """Write raw bytes (fault injection in tests, or a monitor forwarding bytes)."""
        self.transport.write(data)

    # --- receiving -----------------------------------------------------------------
    def _read_available(self, wait: float) -> bytes:
        """Wait up to ``wait`` s for input, then read what is there (may be b'')."""
        if self._fd is None:
            return self.transport.read(4096, wait)
        if wait > 0:
            try:
                ready, _, _ = select.select([self._fd, self._wake_r], [], [], wait)
            except InterruptedError:
                return b""
            if self._wake_r in ready:
                self._consume_wake()
                self._woken = True
                return b""
            if not ready:
                return b""
        return self.transport.read(4096)

    def recv(self, timeout: float) -> Frame | None:
        """The next good frame, or None after ``timeout`` s.

        Raises a ProtocolError for a bad frame (after dropping it) and LinkClosed when the
        other end has gone (EOF, socket reset, pty master closed).
        """
        deadline = time.monotonic() + timeout
        self._woken = False
        while True:
            frame = self.decoder.next_frame()
            if frame is not None:
                return frame
            left = deadline - time.monotonic()
            if left <= 0 or self._woken:
                return None
            try:
                data = self._read_available(left)
            except OSError as e:
                raise LinkClosed(f"{self.url}: {e}") from None
            if data:
                self.bytes_in += len(data)
                self.decoder.feed(data)

    def pending_input(self) -> bool:
        """True if a complete or partial frame, or unread bytes, are waiting."""
        if self.decoder.buf:
            return True
        if self._fd is not None:
            ready, _, _ = select.select([self._fd], [], [], 0)
            return bool(ready)
        data = self.transport.read(4096, 0.0)      # no descriptor to ask: read what is there
        if data:
            self.bytes_in += len(data)
            self.decoder.feed(data)
        return bool(self.decoder.buf)

    def drain(self) -> int:
        """Discard all input now waiting (and any pending wake-up); returns the bytes dropped."""
        n = len(self.decoder.buf)
        self.decoder.reset()
        self._consume_wake()
        while True:
            try:
                data = self._read_available(0.0)
            except OSError as e:
                raise LinkClosed(f"{self.url}: {e}") from None
            if not data:
                return n
            n += len(data)

    def close(self) -> None:
        self.transport.close()
        self._close_wake()

    def _close_wake(self) -> None:
        for fd in (self._wake_r, self._wake_w):
            try:
                os.close(fd)
            except OSError:
                pass
        self._wake_r = self._wake_w = -1

    @property
    def is_open(self) -> bool:
        return self.transport.is_open


def open_link(url: str, *, connect_timeout: float = 5.0, priority: int = 0) -> Link:
    """Open the robot link named by ``url`` (module docstring; rci/transports/).

    A device path (serial line or pty) is opened with an exclusive lock: one controller per
    line (docs/protocol.md, "Ownership"). Over TCP and Zenoh the robot itself refuses a
    second controller (BUSY). ``priority`` > 0 runs a transport's own threads (Zenoh has
    some) under SCHED_FIFO where allowed. Raises DeviceError (thesis R_BAD_OPEN) naming the
    URL if the link cannot be opened.
    """
    return Link(open_transport(url, timeout=connect_timeout, priority=priority), url)
