"""The recorder: the thesis's information buffer (2.2.3) that logs control cycles to a file.

The control level appends one record per cycle into a preallocated ring (never blocks,
never allocates; when the ring is full the record is dropped and counted). The planning
level dumps the ring to disk in CRC-protected blocks (``flush``), by hand or from a
background writer thread (``start_writer``). The file format is in docs/log-format.md;
``read_log`` reads it back and raises ``LogFormatError`` naming the file and the block on
corruption. After a crash the log is readable up to the last block that reached the disk.

A write that fails (a full disk, a quota, an I/O error) never reaches the control level and
never leaves half a block behind: the file is cut back to the end of its last complete
block, ``written`` counts only whole blocks, the records that could not be written are
counted in ``lost``, recording stops, and the program is told as it chose with
``on_write_error``: ``"warn"`` (a ``RecorderWarning``), ``"raise"`` (a ``LogWriteError`` from
``flush``, ``check`` or ``close``), or a function called with the ``LogWriteError`` (e.g. to
end the control: ``lambda e: setattr(session, "terminate", codes.R_USER_BASE + 1)``).
``close`` then still writes the end marker if it fits, so the file reads back complete up to
its last whole block either way.
"""
from __future__ import annotations

import errno
import gzip
import json
import lzma
import os
import struct
import sys
import threading
import time
import warnings
import zlib
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, Union

import numpy as np

from .chg import UNVALUED, VALUED, Chg, Cmd, as_wire_int
from .exceptions import LogFormatError, LogWriteError, RecorderWarning
from .how import How

MAGIC = b"RCILOG\x00\x01"       # 6 letters, NUL, format version 1
BLOCK_MAGIC = b"BLK1"
END_MAGIC = b"END1"
_U32 = struct.Struct("<I")
_BLOCK = struct.Struct("<4sIII")  # magic, n records, payload bytes, crc32 of payload
_END = struct.Struct("<4sQ")      # magic, total records
FORMAT_VERSION = 1
WRITE_ERROR_CHOICES = ("warn", "raise")
MARKS_KEPT = 8                    # flush ends remembered: how far close() may cut back for the end marker
OnWriteError = Union[str, Callable[[LogWriteError], None]]


def record_dtype(nj: int, nadc: int, user_fields: Mapping[str, tuple[str, tuple[int, ...] | int]] | None = None) -> np.dtype:
    """The numpy dtype of one log record (little-endian, packed). See docs/log-format.md."""
    fields: list[tuple] = [
        ("t", "<f8"),                 # host time since the log was created, s
        ("cycle", "<u4"),             # HOW sequence number
        ("robot_time_ns", "<u8"),     # robot clock, ns
        ("rate_hz", "<u2"),
        ("lateness", "<f4"),          # HOW arrival minus its expected time, s
        ("duration", "<f4"),          # HOW arrival to end of f2, s
        ("how_status", "<u2"),
        ("how_state", "<u2"),
        ("how_exio", "<u2"),
        ("how_pos", "<i4", (nj,)),    # encoder counts
        ("how_inport1", "<u2"),
        ("how_outport1", "<u2"),
        ("how_pendant", "u1", (3,)),
        ("how_adcr", "<i2", (nadc,)),  # 12-bit ADC counts
        ("chg_motion_com", "u1", (nj,)),
        ("chg_motion_value", "<i4", (nj,)),
        ("chg_setparam_com", "u1", (nj,)),
        ("chg_setparam_value", "<i4", (nj,)),
        ("chg_com", "u1", (len(VALUED),)),     # setparamALL adco hand rate checking outport1 pendant zindex
        ("chg_value", "<i4", (len(VALUED),)),
        ("chg_flags", "u1"),                   # bit0 end, bit1 stop, bit2 power_on, bit3 power_off
    ]
    for name, spec in (user_fields or {}).items():
        if not name.isidentifier() or any(name == f[0] for f in fields):
            raise ValueError(f"user field name {name!r} is not an identifier or clashes with a built-in field")
        dt, shape = spec
        shape = (shape,) if isinstance(shape, int) else tuple(shape)
        dt = np.dtype(dt).newbyteorder("<") if np.dtype(dt).itemsize > 1 else np.dtype(dt)
        fields.append(("u_" + name, dt.str, shape) if shape else ("u_" + name, dt.str))
    return np.dtype(fields)


def _dtype_to_json(dt: np.dtype) -> list:
    out = []
    for name in dt.names:
        sub, _ = dt.fields[name]
        if sub.subdtype is not None:
            base, shape = sub.subdtype
            out.append([name, base.str, list(shape)])
        else:
            out.append([name, sub.str, []])
    return out


def _dtype_from_json(spec: list, path: str) -> np.dtype:
    try:
        return np.dtype([(n, d, tuple(s)) if s else (n, d) for n, d, s in spec])
    except (TypeError, ValueError) as e:
        raise LogFormatError(path, "header.fields", f"not a valid record layout: {e}") from None


class Recorder:
    """Logs control cycles: ``append`` at the control level, ``flush`` at the planning level.

    ``user_fields`` maps a name to ``(dtype, shape)``; the control function sets values in
    ``recorder.user[name]`` and each record copies them (stored as ``u_<name>``; unset
    float fields are NaN). ``every`` records one cycle in ``every``. ``on_write_error`` says
    how the program hears of a write that failed (module docstring): ``"warn"``, ``"raise"``
    or a function of the ``LogWriteError``.

    Counts (records): ``written`` on disk in whole blocks, ``dropped`` not kept because the
    ring was full, ``lost`` kept but not written because writing failed (``error``).
    """

    def __init__(self, path: str | os.PathLike, *, robot: str, nj: int = 6, nadc: int = 16,
                 rate_hz: int = 36, user_fields: Mapping[str, tuple[str, Any]] | None = None,
                 meta: Mapping[str, Any] | None = None, capacity: int = 1 << 16,
                 block_records: int = 512, every: int = 1, on_write_error: OnWriteError = "warn") -> None:
        if not (on_write_error in WRITE_ERROR_CHOICES or callable(on_write_error)):
            raise ValueError(f"Recorder on_write_error={on_write_error!r}: expected one of "
                             f"{', '.join(map(repr, WRITE_ERROR_CHOICES))} or a function of the LogWriteError")
        self.on_write_error = on_write_error
        self.path = os.fspath(path)
        self.nj, self.nadc = nj, nadc
        self.dtype = record_dtype(nj, nadc, user_fields)
        self.user_names = list(user_fields or {})
        self.user: dict[str, Any] = {}
        self.ring = np.zeros(capacity, dtype=self.dtype)
        self.capacity = capacity
        self.block_records = block_records
        self.every = max(1, int(every))
        self.head = 0          # records appended (producer only)
        self.tail = 0          # records written (consumer only)
        self.dropped = 0
        self.written = 0
        self.lost = 0           # records kept in the ring but not written: the writing failed
        self.error: LogWriteError | None = None
        self._reported = False  # the error went to the program (raised, warned or handed over)
        self._count = 0
        self._t0 = time.monotonic()
        self._lock = threading.Lock()     # serialises flushes (planning-level callers)
        self._writer: threading.Thread | None = None
        self._stop = threading.Event()
        header = {
            "format": "rcilog", "version": FORMAT_VERSION, "robot": robot, "nj": nj, "nadc": nadc,
            "rate_hz": rate_hz, "created_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
            "t0_monotonic": self._t0, "host": os.uname().nodename, "pid": os.getpid(),
            "argv": list(sys.argv), "user_fields": self.user_names, "meta": dict(meta or {}),
            "fields": _dtype_to_json(self.dtype), "record_size": self.dtype.itemsize,
        }
        raw = json.dumps(header, sort_keys=True).encode("utf-8")
        self._fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        self._end = 0           # bytes of the file that hold the header and whole blocks
        try:
            self._write_all(MAGIC + _U32.pack(len(raw)) + raw + _U32.pack(zlib.crc32(raw)))
            os.fsync(self._fd)
        except OSError as e:
            os.close(self._fd)
            raise LogWriteError(self.path, e, written=0, lost=0, where="the header") from None
        self._end = os.lseek(self._fd, 0, os.SEEK_CUR)
        self._marks = [(self._end, 0)]   # (file end, records written) after the header and each flush
        self.closed = False

    # --- control level ------------------------------------------------------------
    def append(self, how: How, chg: Chg | bytes | None, lateness: float = 0.0, duration: float = 0.0) -> None:
        """Record one cycle (called by the control task after f2). Never blocks.

        ``chg`` is the Chg as dispatched, or the CHG payload bytes that were sent.
        """
        self._count += 1
        if (self._count - 1) % self.every:
            return
        if self.head - self.tail >= self.capacity:
            self.dropped += 1
            return
        r = self.ring[self.head % self.capacity]
        r["t"] = time.monotonic() - self._t0
        r["cycle"] = how.cycle & 0xFFFFFFFF
        r["robot_time_ns"] = how.time_ns
        r["rate_hz"] = how.rate_hz
        r["lateness"] = lateness
        r["duration"] = duration
        r["how_status"] = how.status
        r["how_state"] = how.state
        r["how_exio"] = how.exio
        r["how_pos"] = how.pos
        r["how_inport1"] = how.inport1
        r["how_outport1"] = how.outport1
        r["how_pendant"] = how.pendant
        r["how_adcr"] = how.adcr[: self.nadc]
        if isinstance(chg, (bytes, bytearray)):
            _fill_chg_payload(r, chg, self.nj)
        elif chg is not None:
            _fill_chg(r, chg)
        else:
            for k in ("chg_motion_com", "chg_motion_value", "chg_setparam_com", "chg_setparam_value",
                      "chg_com", "chg_value", "chg_flags"):
                r[k] = 0
        for name in self.user_names:
            key = "u_" + name
            if name in self.user:
                try:
                    r[key] = self.user[name]
                except (TypeError, ValueError):
                    r[key] = np.nan if r[key].dtype.kind == "f" else 0
            else:
                r[key] = np.nan if self.dtype[key].base.kind == "f" else 0
        self.head += 1

    # --- planning level -------------------------------------------------------------
    def _write_all(self, data: bytes) -> None:
        """Write every byte of ``data`` (a short write on a filling disk is retried until it fails)."""
        view = memoryview(data)
        while view:
            n = os.write(self._fd, view)
            if n <= 0:
                raise OSError(28, "No space left on device")
            view = view[n:]

    def flush(self) -> int:
        """Write every record appended so far to disk, in blocks; returns how many were written.

        After a failed write it writes nothing: the records appended since count in ``lost``
        (and with ``on_write_error="raise"`` the ``LogWriteError`` is raised).
        """
        with self._lock:
            if self.closed:
                return 0
            if self.error is not None:
                self._discard()
                self._report()
                return 0
            n_total = 0
            try:
                while True:
                    head = self.head
                    n = min(head - self.tail, self.block_records)
                    if n <= 0:
                        break
                    start = self.tail % self.capacity
                    n = min(n, self.capacity - start)     # do not wrap inside one block
                    payload = self.ring[start:start + n].tobytes()
                    self._write_all(_BLOCK.pack(BLOCK_MAGIC, n, len(payload), zlib.crc32(payload)) + payload)
                    self.tail += n
                    n_total += n
                if n_total:
                    os.fsync(self._fd)
            except OSError as e:
                # blocks written in this flush but not fsync'd may not be on the disk: give them up
                # with the block that failed, so that `written` is only what the file holds
                self.tail -= n_total
                self._fail(e)
                self._report()
                return 0
            self.written += n_total
            self._end = os.lseek(self._fd, 0, os.SEEK_CUR)
            if n_total:
                self._marks = (self._marks + [(self._end, self.written)])[-MARKS_KEPT:]
            return n_total

    def _fail(self, e: OSError) -> None:
        """A write failed: cut the file back to its last whole block, stop writing, count the loss."""
        try:
            os.ftruncate(self._fd, self._end)
            os.lseek(self._fd, self._end, os.SEEK_SET)
        except OSError:
            pass                 # a reader stops at the cut block by itself (docs/log-format.md)
        self.error = LogWriteError(self.path, e, written=self.written, lost=0, where=f"byte {self._end}")
        self._discard()

    def _discard(self) -> None:
        """Count the records waiting in the ring as lost (recording has stopped on an error)."""
        head = self.head
        self.lost += head - self.tail
        self.tail = head
        if self.error is not None:
            self.error.lost = self.lost

    def _report(self) -> None:
        """Tell the program of ``error`` once, as ``on_write_error`` says."""
        err = self.error
        if err is None or self._reported:
            if err is not None and self.on_write_error == "raise":
                raise err
            return
        self._reported = True
        if self.on_write_error == "raise":
            raise err
        if self.on_write_error == "warn":
            warnings.warn(RecorderWarning(str(err)), stacklevel=3)
        else:
            self.on_write_error(err)

    def check(self) -> None:
        """Raise the ``LogWriteError`` if writing has failed (whatever ``on_write_error`` says)."""
        if self.error is not None:
            raise self.error

    def start_writer(self, interval: float = 0.2) -> None:
        """Flush from a background (planning-level) thread every ``interval`` s."""
        if self._writer is not None:
            return

        def run() -> None:
            while not self._stop.wait(interval):
                try:
                    self.flush()
                except LogWriteError:
                    pass              # kept in self.error; "raise" raises it in flush/check/close
                if self.error is not None:
                    return            # nothing more can be written: stop polling

        self._writer = threading.Thread(target=run, name="rci-recorder", daemon=True)
        self._writer.start()

    def close(self) -> None:
        """Flush, write the end marker and close the file.

        After a write error the file is closed with the end marker if it fits (else without,
        readable to its last whole block all the same), then the error is reported once more
        with ``on_write_error="raise"``.
        """
        if self.closed:
            return
        self._stop.set()
        if self._writer is not None:
            self._writer.join(timeout=5)
        try:
            self.flush()
        except LogWriteError:
            pass
        with self._lock:
            if self.error is not None:
                self._discard()
            try:
                self._write_end_marker()
            except OSError as e:
                if self.error is None:
                    self.error = LogWriteError(self.path, e, written=self.written, lost=self.lost,
                                               where="the end marker")
            os.close(self._fd)
            self.closed = True
        self._report()

    def _write_end_marker(self) -> None:
        """The end marker after the last whole block; on a full disk the last flush's blocks are
        given up (counted in ``lost``) to make room for it, as often as ``_marks`` allows: a log
        that says it is complete is worth a few records (the cut falls where a page frees)."""
        while True:
            try:
                self._write_all(_END.pack(END_MAGIC, self.written))
                os.fsync(self._fd)
                return
            except OSError as e:
                try:
                    os.ftruncate(self._fd, self._end)       # no half end marker
                except OSError:
                    pass
                if e.errno not in (errno.ENOSPC, errno.EDQUOT) or len(self._marks) < 2:
                    raise
                self._marks.pop()
                end, written = self._marks[-1]
                os.ftruncate(self._fd, end)
                os.lseek(self._fd, end, os.SEEK_SET)
                self.lost += self.written - written
                self.written, self._end = written, end
                if self.error is not None:
                    self.error.written, self.error.lost = self.written, self.lost

    def __enter__(self) -> "Recorder":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _chg_wire_dtype(nj: int) -> np.dtype:
    cmd = np.dtype([("com", "u1"), ("value", "<i4")])
    return np.dtype([("nj", "u1"), ("motion", cmd, (nj,)), ("setparam", cmd, (nj,)),
                     ("single", cmd, (len(VALUED),)), ("flags", "u1")])


_WIRE: dict[int, np.dtype] = {}


def _fill_chg_payload(r: np.void, payload: bytes, nj: int) -> None:
    dt = _WIRE.get(nj)
    if dt is None:
        dt = _WIRE[nj] = _chg_wire_dtype(nj)
    w = np.frombuffer(payload, dtype=dt, count=1)[0]
    r["chg_motion_com"] = w["motion"]["com"]
    r["chg_motion_value"] = w["motion"]["value"]
    r["chg_setparam_com"] = w["setparam"]["com"]
    r["chg_setparam_value"] = w["setparam"]["value"]
    r["chg_com"] = w["single"]["com"]
    r["chg_value"] = w["single"]["value"]
    r["chg_flags"] = w["flags"]


def _fill_chg(r: np.void, chg: Chg) -> None:
    for i, c in enumerate(chg.motion):
        r["chg_motion_com"][i] = c.com
        r["chg_motion_value"][i] = as_wire_int(c.value, f"motion[{i}]") if c.com else 0
    for i, c in enumerate(chg.setparam):
        r["chg_setparam_com"][i] = c.com
        r["chg_setparam_value"][i] = as_wire_int(c.value, f"setparam[{i}]") if c.com else 0
    for k, name in enumerate(VALUED):
        c: Cmd = getattr(chg, name)
        r["chg_com"][k] = c.com
        r["chg_value"][k] = as_wire_int(c.value, name) if c.com else 0
    flags = 0
    for bit, name in enumerate(UNVALUED):
        if getattr(chg, name).com:
            flags |= 1 << bit
    r["chg_flags"] = flags


@dataclass
class Log:
    """A log read back: header metadata, the records, and whether the file ended cleanly."""

    path: str
    meta: dict
    records: np.ndarray
    complete: bool                # the end marker was found (the recorder was closed)
    truncated_bytes: int = 0      # bytes of an incomplete last block (crash), ignored
    blocks: int = 0
    notes: list[str] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.records)

    @property
    def user_fields(self) -> list[str]:
        return list(self.meta.get("user_fields", []))

    def user(self, name: str) -> np.ndarray:
        """The column of user field ``name``."""
        return self.records["u_" + name]


def read_log(path: str | os.PathLike, *, strict: bool = False) -> Log:
    """Read a recorder log.

    ``.xz`` and ``.gz`` files are decompressed first. A final block cut short (a crash while writing) is ignored and reported in
    ``Log.truncated_bytes`` / ``Log.complete``; with ``strict=True`` it raises instead.
    Damage anywhere else raises ``LogFormatError`` naming the file, the block and the
    records it held.
    """
    path = os.fspath(path)
    try:
        with open(path, "rb") as f:
            data = f.read()
    except OSError as e:
        raise LogFormatError(path, "file", f"cannot read: {e.strerror}") from None
    if path.endswith((".xz", ".gz")):             # a compressed log (calib/logs/ ships .xz)
        try:
            data = lzma.decompress(data) if path.endswith(".xz") else gzip.decompress(data)
        except (OSError, EOFError, lzma.LZMAError, zlib.error) as e:
            raise LogFormatError(path, "file", f"not a readable {path.rsplit('.', 1)[1]} file: {e}") from None
    if len(data) < len(MAGIC) + 4:
        raise LogFormatError(path, "header", f"file is {len(data)} bytes, too short for a log header")
    if data[:6] != MAGIC[:6]:
        raise LogFormatError(path, "header", f"not an RCI log (starts with {data[:8]!r})")
    if data[:8] != MAGIC:
        raise LogFormatError(path, "header", f"log format version {data[7]} not supported (this reader: {FORMAT_VERSION})")
    (hlen,) = _U32.unpack_from(data, 8)
    hend = 12 + hlen
    if hend + 4 > len(data):
        raise LogFormatError(path, "header", f"header claims {hlen} bytes but the file has {len(data) - 12}")
    raw = data[12:hend]
    (hcrc,) = _U32.unpack_from(data, hend)
    if zlib.crc32(raw) != hcrc:
        raise LogFormatError(path, "header", "header checksum mismatch")
    try:
        meta = json.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as e:
        raise LogFormatError(path, "header", f"header is not valid JSON: {e}") from None
    for key in ("fields", "record_size", "nj", "nadc", "robot"):
        if key not in meta:
            raise LogFormatError(path, "header", f"missing key {key!r}")
    dt = _dtype_from_json(meta["fields"], path)
    if dt.itemsize != meta["record_size"]:
        raise LogFormatError(path, "header", f"record_size {meta['record_size']} disagrees with field layout ({dt.itemsize})")
    off = hend + 4
    chunks: list[bytes] = []
    n_records = 0
    blocks = 0
    complete = False
    truncated = 0
    notes: list[str] = []
    while off < len(data):
        if data[off:off + 4] == END_MAGIC:
            if off + _END.size > len(data):
                truncated = len(data) - off
                break
            _, total = _END.unpack_from(data, off)
            if total != n_records:
                raise LogFormatError(path, f"end marker at byte {off}",
                                     f"says {total} records, blocks hold {n_records}")
            complete = True
            off += _END.size
            if off != len(data):
                raise LogFormatError(path, f"byte {off}", f"{len(data) - off} bytes after the end marker")
            break
        where = f"block {blocks} (records {n_records}.., byte {off})"
        if len(data) - off < _BLOCK.size:
            truncated = len(data) - off
            break
        magic, n, nbytes, crc = _BLOCK.unpack_from(data, off)
        if magic != BLOCK_MAGIC:
            raise LogFormatError(path, where, f"expected block marker {BLOCK_MAGIC!r}, found {magic!r}")
        if nbytes != n * dt.itemsize:
            raise LogFormatError(path, where, f"{n} records of {dt.itemsize} bytes but {nbytes} payload bytes")
        start = off + _BLOCK.size
        if start + nbytes > len(data):
            truncated = len(data) - off
            break
        payload = data[start:start + nbytes]
        if zlib.crc32(payload) != crc:
            raise LogFormatError(path, f"block {blocks} (records {n_records}..{n_records + n - 1}, byte {off})",
                                 "block checksum mismatch: data corrupted")
        chunks.append(payload)
        n_records += n
        blocks += 1
        off = start + nbytes
    if truncated:
        msg = f"last block cut short ({truncated} bytes after record {n_records}): log not closed cleanly"
        if strict:
            raise LogFormatError(path, f"block {blocks} (byte {off})", msg)
        notes.append(msg)
    elif not complete:
        notes.append("no end marker: the recorder was not closed (crash or still writing)")
        if strict:
            raise LogFormatError(path, f"byte {off}", notes[-1])
    records = np.frombuffer(b"".join(chunks), dtype=dt) if chunks else np.zeros(0, dtype=dt)
    return Log(path, meta, records, complete, truncated, blocks, notes)
