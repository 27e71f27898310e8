"""The robot link: frames over a pyserial byte stream (device path / pty, socket://, loop://).

``open_link(url)`` accepts anything ``serial.serial_for_url`` does: a device path such as
``/dev/ttyUSB0`` or a pty slave ``/dev/pts/5``, ``socket://127.0.0.1:7600`` for simula, and
``loop://`` for unit tests. The port is put in non-blocking mode once; ``Link.recv`` waits
with select() on the port's file descriptor, so the control task never spins.

For ``socket://`` the link reads and writes the (non-blocking) socket pyserial opened
directly: pyserial's socket ``read`` makes two select() calls around each recv() and its
``write`` one more, which at 1 kHz were three extra system calls (and GIL hand-offs) on
the control task's critical path every cycle.
"""
from __future__ import annotations

import os
import select
import time

import serial

from .exceptions import DeviceError, LinkClosed
from .protocol import Frame, FrameDecoder, encode_frame


class Link:
    """A framed, bidirectional link to the robot (or simula) over a pyserial port."""

    def __init__(self, port: serial.SerialBase, url: str = "") -> None:
        self.port = port
        self.url = url or getattr(port, "portstr", "") or ""
        self.decoder = FrameDecoder()
        self.port.timeout = 0            # non-blocking reads: we wait in select()
        sock = getattr(port, "_socket", None)
        self._sock = sock
        if sock is not None:
            # one small frame per cycle each way: Nagle's algorithm would hold a CHG back
            # until the previous one is acknowledged, costing a cycle at high rates
            import socket as _socket
            try:
                sock.setsockopt(_socket.IPPROTO_TCP, _socket.TCP_NODELAY, 1)
            except OSError:
                pass
        try:
            self._fd: int | None = port.fileno()
        except (AttributeError, NotImplementedError, OSError, serial.SerialException):
            self._fd = None
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
        """Encode and write one frame; LinkClosed if the port is gone."""
        data = encode_frame(ftype, seq, payload)
        sock = self._sock
        if sock is not None:
            try:
                n = sock.send(data)
            except (BlockingIOError, InterruptedError):
                n = 0
            except OSError as e:
                raise LinkClosed(f"{self.url}: write failed: {e}") from None
            if n < len(data):               # socket buffer full: let pyserial wait (write timeout)
                try:
                    self.port.write(data[n:])
                except (serial.SerialException, OSError) as e:
                    raise LinkClosed(f"{self.url}: write failed: {e}") from None
            self.bytes_out += len(data)
            return
        try:
            n = self.port.write(data)
            self.port.flush() if self._fd is None else None
        except (serial.SerialException, OSError) as e:
            raise LinkClosed(f"{self.url}: write failed: {e}") from None
        if n is not None and n != len(data):
            raise LinkClosed(f"{self.url}: short write ({n} of {len(data)} bytes)")
        self.bytes_out += len(data)

    def send_raw(self, data: bytes) -> None:
        """Write raw bytes (fault injection in tests, or a monitor forwarding bytes)."""
        try:
            self.port.write(data)
        except (serial.SerialException, OSError) as e:
            raise LinkClosed(f"{self.url}: write failed: {e}") from None

    # --- receiving -----------------------------------------------------------------
    def _read_available(self, wait: float) -> bytes:
        """Wait up to ``wait`` s for input, then read what is there (may be b'')."""
        if self._fd is not None:
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
            sock = self._sock
            if sock is not None:
                try:
                    data = sock.recv(4096)
                except (BlockingIOError, InterruptedError):
                    return b""
                if not data:
                    raise LinkClosed(f"{self.url}: socket disconnected")
                return data
            data = self.port.read(4096)
        else:
            self.port.timeout = max(wait, 0.0)
            data = self.port.read(max(1, self.port.in_waiting))
        return data

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
            except (serial.SerialException, OSError) as e:
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
        return bool(self.port.in_waiting)

    def drain(self) -> int:
        """Discard all input now waiting (and any pending wake-up); returns the bytes dropped."""
        n = len(self.decoder.buf)
        self.decoder.reset()
        self._consume_wake()
        while True:
            try:
                data = self._read_available(0.0)
            except (serial.SerialException, OSError) as e:
                raise LinkClosed(f"{self.url}: {e}") from None
            if not data:
                return n
            n += len(data)

    def close(self) -> None:
        sock = getattr(self.port, "_socket", None)
        if sock is not None:
            # pyserial's socket:// close() sleeps 0.3 s "for quick reconnects"; a controller
            # closing its link has no use for that, so shut the socket down directly.
            try:
                sock.shutdown(2)
            except OSError:
                pass
            sock.close()
            self.port._socket = None
            self._sock = None
            self.port.is_open = False
            return self._close_wake()
        try:
            self.port.close()
        except (serial.SerialException, OSError):
            pass
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
        return bool(self.port.is_open)


def open_link(url: str, *, baudrate: int = 115200, connect_timeout: float = 5.0, priority: int = 0) -> Link:
    """Open the robot link named by ``url`` (device path, ``socket://host:port`` or ``loop://``).

    A device path (serial line or pty) is opened with an exclusive lock: one controller per
    line (docs/protocol.md, "Ownership"); a second program gets DeviceError at once instead
    of sharing, and stealing, the first one's frames. Over TCP the robot itself refuses a
    second controller (BUSY). ``zenoh/KEY`` is the Zenoh bus (rci.zenoh_bus); ``priority`` > 0
    runs its threads under SCHED_FIFO (where allowed). Raises DeviceError (thesis R_BAD_OPEN) naming the URL if the
    link cannot be opened.
    """
    if url.startswith("zenoh/"):
        from .zenoh_bus import ControllerPort, ZenohLinkError
        try:
            return Link(ControllerPort(url, timeout=connect_timeout, priority=priority), url)
        except ZenohLinkError as e:
            raise DeviceError(f"cannot open robot link {url!r}: {e}") from None
    device = "://" not in url
    try:
        port = serial.serial_for_url(url, baudrate=baudrate, timeout=connect_timeout,
                                     write_timeout=connect_timeout, **({"exclusive": True} if device else {}))
    except (serial.SerialException, OSError, ValueError) as e:
        hint = " (another program has this line open: one controller per line)" \
            if device and "exclusively lock" in str(e) else ""
        raise DeviceError(f"cannot open robot link {url!r}: {e}{hint}") from None
    return Link(port, url)
