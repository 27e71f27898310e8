"""The RCI link protocol: framing, frame types and payload codecs for HOW, CHG and session frames.

See docs/protocol.md for the byte-level description. All multi-byte integers are
little-endian. A frame is::

    A5 5A | ver u8 | type u8 | seq u32 | len u16 | hcrc u16 | payload[len] | crc u16

``hcrc`` is CRC-16/CCITT-FALSE over ver..len (8 bytes), so a damaged length is caught
before the decoder waits for a payload that will never come; ``crc`` is the same CRC over
ver..payload (everything after the sync bytes, hcrc included). The decoder skips
garbage up to the next sync pair and raises a named ``ProtocolError`` for every bad frame
it drops, then carries on with the bytes after it.
"""
from __future__ import annotations

import binascii
import struct
from dataclasses import dataclass, field

import numpy as np

from . import chg as chgmod
from .chg import Chg, Cmd, UNVALUED, VALUED
from .exceptions import (ChecksumError, FrameLengthError, ProtocolError, SequenceGap,
                         UnknownFrameType, VersionError)
from .how import How

SYNC = b"\xA5\x5A"
VERSION = 2          # 2: HELLO carries the controller's pid and a takeover flag (ownership, docs/protocol.md)
HEADER = struct.Struct("<BBIH")     # ver, type, seq, len (after the sync bytes)
HEADER_LEN = 2 + HEADER.size + 2    # sync + fields + hcrc = 12
TRAILER_LEN = 2
MAX_PAYLOAD = 1024
MAX_NJ = 16
MAX_ADC = 64

# frame types
HELLO = 0x01     # controller -> robot: open a session
WELCOME = 0x02   # robot -> controller: session accepted, robot description
START = 0x03     # controller -> robot: start control cycles at a rate
HOW = 0x10       # robot -> controller: state at the start of cycle seq
CHG = 0x11       # controller -> robot: commands answering HOW(seq)
ERROR = 0x20     # either way: a refusal or fault, with a code and text
BYE = 0x30       # controller -> robot: close the session; robot echoes it
TYPE_NAMES = {HELLO: "HELLO", WELCOME: "WELCOME", START: "START", HOW: "HOW", CHG: "CHG",
              ERROR: "ERROR", BYE: "BYE"}

# WELCOME.mode
MODE_REALTIME = 0
MODE_LOCKSTEP = 1


def crc16(data: bytes, crc: int = 0xFFFF) -> int:
    """CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection, no final xor)."""
    return binascii.crc_hqx(data, crc)


@dataclass(frozen=True)
class Frame:
    """One decoded frame: type, sequence number and raw payload."""

    type: int
    seq: int
    payload: bytes

    @property
    def name(self) -> str:
        return TYPE_NAMES.get(self.type, f"0x{self.type:02x}")


def encode_frame(ftype: int, seq: int, payload: bytes = b"") -> bytes:
    """Build the bytes of one frame."""
    if len(payload) > MAX_PAYLOAD:
        raise FrameLengthError(f"payload of {len(payload)} bytes exceeds {MAX_PAYLOAD}")
    head = HEADER.pack(VERSION, ftype, seq & 0xFFFFFFFF, len(payload))
    head += struct.pack("<H", crc16(head))
    body = head + payload
    return SYNC + body + struct.pack("<H", crc16(body))


class FrameDecoder:
    """Incremental decoder: ``feed`` bytes, then call ``next_frame`` until it returns None.

    A bad frame raises a ``ProtocolError`` subclass after its bytes were dropped, so the
    caller may simply call ``next_frame`` again to resynchronise. ``skipped`` counts
    bytes discarded while hunting for a sync pair.
    """

    def __init__(self, max_payload: int = MAX_PAYLOAD) -> None:
        self.buf = bytearray()
        self.max_payload = max_payload
        self.skipped = 0

    def feed(self, data: bytes) -> None:
        self.buf += data

    def reset(self) -> None:
        """Drop any partial input."""
        self.buf.clear()

    def next_frame(self) -> Frame | None:
        buf = self.buf
        while True:
            i = buf.find(SYNC)
            if i < 0:
                # keep a trailing A5 that may be the first half of a sync pair
                keep = 1 if buf[-1:] == SYNC[:1] else 0
                self.skipped += len(buf) - keep
                del buf[: len(buf) - keep]
                return None
            if i:
                self.skipped += i
                del buf[:i]
            if len(buf) < HEADER_LEN:
                return None
            head = bytes(buf[2:2 + HEADER.size])
            (hcrc,) = struct.unpack_from("<H", buf, 2 + HEADER.size)
            if crc16(head) != hcrc:
                del buf[:1]
                raise ChecksumError("bad header checksum; resynchronising")
            ver, ftype, seq, length = HEADER.unpack(head)
            if length > self.max_payload:
                del buf[:1]
                raise FrameLengthError(f"frame length {length} exceeds {self.max_payload}")
            total = HEADER_LEN + length + TRAILER_LEN
            if len(buf) < total:
                return None
            (crc,) = struct.unpack_from("<H", buf, total - TRAILER_LEN)
            if crc16(bytes(buf[2:total - TRAILER_LEN])) != crc:
                del buf[:1]
                raise ChecksumError(f"bad checksum on {TYPE_NAMES.get(ftype, hex(ftype))} frame seq {seq}")
            payload = bytes(buf[HEADER_LEN:HEADER_LEN + length])
            del buf[:total]
            if ver != VERSION:
                raise VersionError(ver, f"{TYPE_NAMES.get(ftype, hex(ftype))} frame of protocol version {ver}: "
                                        f"not supported (this side speaks {VERSION})")
            if ftype not in TYPE_NAMES:
                raise UnknownFrameType(f"unknown frame type 0x{ftype:02x} (seq {seq})")
            return Frame(ftype, seq, payload)


class SequenceChecker:
    """Checks that sequence numbers of a stream go up by one (modulo 2**32)."""

    def __init__(self) -> None:
        self.last: int | None = None

    def reset(self) -> None:
        self.last = None

    def check(self, seq: int) -> None:
        if self.last is not None:
            expected = (self.last + 1) & 0xFFFFFFFF
            if seq != expected:
                self.last = seq
                raise SequenceGap(expected, seq)
        self.last = seq


# --- strings -----------------------------------------------------------------------------
def _pack_str(s: str) -> bytes:
    raw = s.encode("utf-8")
    if len(raw) > 255:
        raise ValueError(f"string too long for a frame: {s[:40]!r}...")
    return bytes([len(raw)]) + raw


def _unpack_str(data: bytes, off: int, what: str) -> tuple[str, int]:
    if off >= len(data):
        raise FrameLengthError(f"{what}: payload ends before string length")
    n = data[off]
    end = off + 1 + n
    if end > len(data):
        raise FrameLengthError(f"{what}: string of {n} bytes runs past payload end")
    try:
        return data[off + 1:end].decode("utf-8"), end
    except UnicodeDecodeError as e:
        raise ProtocolError(f"{what}: string is not UTF-8: {e}") from None


# --- session payloads --------------------------------------------------------------------
HELLO_TAKEOVER = 0x01   # HELLO.flags: take the robot over from an owner whose control the robot stopped


@dataclass(frozen=True)
class Hello:
    """HELLO: the controller asks for a robot by name at a sample rate (Hz).

    ``pid`` is the controller's process id and ``client`` a free text naming the program;
    the robot quotes both when it refuses another controller (BUSY). ``takeover`` asks to
    replace an owner whose control the robot's watchdog has stopped.
    """

    robot: str
    rate_hz: int = 36
    client: str = "rci"
    pid: int = 0
    takeover: bool = False
    _S = struct.Struct("<BHIB")       # version, rate_hz, pid, flags

    def encode(self) -> bytes:
        flags = HELLO_TAKEOVER if self.takeover else 0
        return (self._S.pack(VERSION, self.rate_hz, self.pid & 0xFFFFFFFF, flags)
                + _pack_str(self.robot) + _pack_str(self.client))

    @classmethod
    def decode(cls, data: bytes) -> "Hello":
        if len(data) < 1:
            raise FrameLengthError("HELLO payload is empty")
        if data[0] != VERSION:
            raise VersionError(data[0], f"HELLO asks for protocol version {data[0]}, this side speaks {VERSION}")
        if len(data) < cls._S.size:
            raise FrameLengthError(f"HELLO payload of {len(data)} bytes is too short")
        ver, rate, pid, flags = cls._S.unpack_from(data)
        robot, off = _unpack_str(data, cls._S.size, "HELLO robot")
        client, off = _unpack_str(data, off, "HELLO client")
        if off != len(data):
            raise FrameLengthError(f"HELLO has {len(data) - off} trailing bytes")
        return cls(robot, rate, client, pid, bool(flags & HELLO_TAKEOVER))


@dataclass(frozen=True)
class Welcome:
    """WELCOME: the robot accepts; says what it is (joints, ADC channels, rate, state, mode)."""

    robot: str
    nj: int
    nadc: int
    rate_hz: int
    state: int
    mode: int = MODE_REALTIME
    server: str = ""
    _S = struct.Struct("<BBHHB")

    def encode(self) -> bytes:
        return (self._S.pack(self.nj, self.nadc, self.rate_hz, self.state, self.mode)
                + _pack_str(self.robot) + _pack_str(self.server))

    @classmethod
    def decode(cls, data: bytes) -> "Welcome":
        if len(data) < cls._S.size:
            raise FrameLengthError(f"WELCOME payload of {len(data)} bytes is too short")
        nj, nadc, rate, state, mode = cls._S.unpack_from(data)
        if not (1 <= nj <= MAX_NJ) or not (nj <= nadc <= MAX_ADC):
            raise ProtocolError(f"WELCOME: impossible nj={nj} nadc={nadc}")
        robot, off = _unpack_str(data, cls._S.size, "WELCOME robot")
        server, off = _unpack_str(data, off, "WELCOME server")
        return cls(robot, nj, nadc, rate, state, mode, server)


@dataclass(frozen=True)
class Start:
    """START: begin control cycles at ``rate_hz``."""

    rate_hz: int
    _S = struct.Struct("<H")

    def encode(self) -> bytes:
        return self._S.pack(self.rate_hz)

    @classmethod
    def decode(cls, data: bytes) -> "Start":
        if len(data) != cls._S.size:
            raise FrameLengthError(f"START payload must be {cls._S.size} bytes, got {len(data)}")
        return cls(*cls._S.unpack(data))


@dataclass(frozen=True)
class ErrorMsg:
    """ERROR: a code (robot status word or A.5.1 number) and a text."""

    code: int
    text: str
    _S = struct.Struct("<I")

    def encode(self) -> bytes:
        return self._S.pack(self.code & 0xFFFFFFFF) + _pack_str(self.text[:255])

    @classmethod
    def decode(cls, data: bytes) -> "ErrorMsg":
        if len(data) < cls._S.size:
            raise FrameLengthError("ERROR payload too short")
        (code,) = cls._S.unpack_from(data)
        text, _ = _unpack_str(data, cls._S.size, "ERROR text")
        return cls(code, text)


@dataclass(frozen=True)
class Bye:
    """BYE: close the session; ``power_off`` asks the robot to switch arm power off."""

    power_off: bool = False

    def encode(self) -> bytes:
        return bytes([1 if self.power_off else 0])

    @classmethod
    def decode(cls, data: bytes) -> "Bye":
        if len(data) != 1:
            raise FrameLengthError(f"BYE payload must be 1 byte, got {len(data)}")
        return cls(bool(data[0]))


# --- HOW ---------------------------------------------------------------------------------
_HOW_HEAD = struct.Struct("<QHIHHHHBB")   # time_ns rate overruns wc status state exio nj nadc
_HOW_MID = struct.Struct("<HH3B")          # inport1 outport1 pendant[3]


def how_size(nj: int, nadc: int) -> int:
    """Payload bytes of a HOW frame for ``nj`` joints and ``nadc`` ADC channels."""
    return _HOW_HEAD.size + 4 * nj + _HOW_MID.size + 2 * nadc


I32_MIN, I32_MAX = -2**31, 2**31 - 1


def encode_how(how: How) -> bytes:
    """HOW payload from a How record (pos as int32 counts, adcr as int16).

    ValueError naming the joint for a count outside the int32 range (a robot must saturate
    and report it, never let it wrap).
    """
    nj, nadc = len(how.pos), len(how.adcr)
    pos = np.asarray(how.pos)
    if pos.size and (pos.min() < I32_MIN or pos.max() > I32_MAX):
        j = int(np.argmax((pos < I32_MIN) | (pos > I32_MAX)))
        raise ValueError(f"how.pos[{j}] = {int(pos[j])} does not fit in the link's 32-bit encoder field")
    return b"".join((
        _HOW_HEAD.pack(how.time_ns, how.rate_hz, how.robot_overruns & 0xFFFFFFFF, how.wc & 0xFFFF,
                       how.status & 0xFFFF, how.state & 0xFFFF, how.exio & 0xFFFF, nj, nadc),
        pos.astype("<i4").tobytes(),
        _HOW_MID.pack(how.inport1 & 0xFFFF, how.outport1 & 0xFFFF, *(int(b) & 0xFF for b in how.pendant)),
        np.asarray(how.adcr, dtype="<i2").tobytes(),
    ))


def decode_how(data: bytes, seq: int, into: How | None = None) -> How:
    """A How from a HOW payload; fills ``into`` in place when given."""
    if len(data) < _HOW_HEAD.size:
        raise FrameLengthError(f"HOW payload of {len(data)} bytes is shorter than its header")
    t, rate, over, wc, status, state, exio, nj, nadc = _HOW_HEAD.unpack_from(data)
    if not (1 <= nj <= MAX_NJ) or nadc > MAX_ADC:
        raise FrameLengthError(f"HOW claims nj={nj}, nadc={nadc}")
    if len(data) != how_size(nj, nadc):
        raise FrameLengthError(f"HOW payload is {len(data)} bytes, expected {how_size(nj, nadc)} for nj={nj} nadc={nadc}")
    off = _HOW_HEAD.size
    pos = np.frombuffer(data, dtype="<i4", count=nj, offset=off).astype(np.int64)
    off += 4 * nj
    inport1, outport1, p0, p1, p2 = _HOW_MID.unpack_from(data, off)
    off += _HOW_MID.size
    adcr = np.frombuffer(data, dtype="<i2", count=nadc, offset=off).astype(np.int64)
    h = into if into is not None else How(pos=pos, adcr=adcr)
    if into is not None:
        if h.pos.shape == pos.shape:
            h.pos[:] = pos
        else:
            h.pos = pos
        if h.adcr.shape == adcr.shape:
            h.adcr[:] = adcr
        else:
            h.adcr = adcr
    h.pendant[:] = (p0, p1, p2)
    h.time_ns, h.rate_hz, h.robot_overruns, h.wc = t, rate, over, wc
    h.status, h.state, h.exio, h.inport1, h.outport1, h.cycle = status, state, exio, inport1, outport1, seq
    return h


# --- CHG ---------------------------------------------------------------------------------
_CMD = struct.Struct("<Bi")


def chg_size(nj: int) -> int:
    """Payload bytes of a CHG frame for ``nj`` joints."""
    return 1 + _CMD.size * (2 * nj + len(VALUED)) + 1


def encode_chg(chg: Chg) -> bytes:
    """CHG payload from a Chg record. Raises ValueError naming the entry for NaN/inf/out-of-int32 values."""
    parts = [bytes([chg.nj])]
    for name, c in chg.entries():
        if isinstance(c, Cmd):
            v = chgmod.as_wire_int(c.value, name) if c.com else 0
            if not (-2**31 <= v < 2**31):
                raise ValueError(f"chg.{name}.value {v} does not fit in 32 bits")
            if not (0 <= int(c.com) <= 255):
                raise ValueError(f"chg.{name}.com {c.com} is not a command code")
            parts.append(_CMD.pack(int(c.com), v))
    flags = 0
    for bit, name in enumerate(UNVALUED):
        if getattr(chg, name).com:
            flags |= 1 << bit
    parts.append(bytes([flags]))
    return b"".join(parts)


def decode_chg(data: bytes) -> Chg:
    """A Chg from a CHG payload (as the robot side sees it)."""
    if not data:
        raise FrameLengthError("empty CHG payload")
    nj = data[0]
    if not (1 <= nj <= MAX_NJ):
        raise FrameLengthError(f"CHG claims nj={nj}")
    if len(data) != chg_size(nj):
        raise FrameLengthError(f"CHG payload is {len(data)} bytes, expected {chg_size(nj)} for nj={nj}")
    chg = Chg(nj=nj)
    off = 1
    for _, c in chg.entries():
        if isinstance(c, Cmd):
            c.com, c.value = _CMD.unpack_from(data, off)
            off += _CMD.size
    flags = data[off]
    for bit, name in enumerate(UNVALUED):
        getattr(chg, name).com = (flags >> bit) & 1
    return chg
