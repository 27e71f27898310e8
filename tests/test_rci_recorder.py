"""The recorder's log format: round trip, crash tolerance, corruption errors (rci.recorder)."""
from __future__ import annotations

import json
import os
import struct
import subprocess
import sys
import textwrap
import zlib

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from rci import protocol
from rci.chg import CUR, POS, Chg
from rci.exceptions import LogFormatError
from rci.how import How
from rci.recorder import MAGIC, Recorder, read_log


def _fill(rec: Recorder, n: int, start: int = 0) -> None:
    h, c = How(), Chg()
    for k in range(start, start + n):
        h.cycle = k
        h.pos[:] = np.arange(6) * k - 30000
        h.adcr[:6] = (k % 4096) - 2048
        c.motion[k % 6].issue(POS if k % 2 else CUR, k - 50)
        rec.user["tau"] = np.full(6, k * 0.5)
        rec.append(h, protocol.encode_chg(c) if k % 3 else c, lateness=1e-5 * k, duration=2e-5)
        c.clear()


def test_round_trip(tmp_path):
    path = tmp_path / "a.rcilog"
    with Recorder(path, robot="puma260", rate_hz=250, user_fields={"tau": ("f8", 6), "flag": ("u1", ())},
                  meta={"operator": "test"}, block_records=64) as rec:
        _fill(rec, 1000)
    log = read_log(path)
    assert log.complete and len(log) == 1000 and log.blocks == 16
    assert log.meta["robot"] == "puma260" and log.meta["rate_hz"] == 250 and log.meta["meta"] == {"operator": "test"}
    r = log.records
    assert np.array_equal(r["cycle"], np.arange(1000))
    assert np.array_equal(r["how_pos"][7], np.arange(6) * 7 - 30000)
    assert r["chg_motion_com"][7][1] == POS and r["chg_motion_value"][7][1] == -43
    assert r["chg_motion_com"][8][2] == CUR and r["chg_motion_value"][8][2] == -42
    assert np.array_equal(log.user("tau")[10], np.full(6, 5.0))
    assert (log.user("flag") == 0).all()                     # never set: 0 for an integer field
    assert log.user_fields == ["tau", "flag"]


def test_header_is_self_describing(tmp_path):
    path = tmp_path / "h.rcilog"
    Recorder(path, robot="microbo", nj=6, nadc=16).close()
    raw = path.read_bytes()
    assert raw[:8] == MAGIC
    (n,) = struct.unpack_from("<I", raw, 8)
    header = json.loads(raw[12:12 + n])
    assert header["format"] == "rcilog" and header["record_size"] == np.dtype(
        [(f, d, tuple(s)) if s else (f, d) for f, d, s in header["fields"]]).itemsize


def test_crashed_writer_is_readable_up_to_last_flushed_block(tmp_path):
    path = tmp_path / "crash.rcilog"
    prog = textwrap.dedent(f"""
        import os, numpy as np
        from rci.recorder import Recorder
        from rci.how import How
        rec = Recorder({str(path)!r}, robot="puma260", block_records=100)
        h = How()
        for k in range(250):
            h.cycle = k
            rec.append(h, None)
        rec.flush()                       # 250 records on disk (blocks of 100, 100, 50)
        for k in range(250, 400):
            h.cycle = k
            rec.append(h, None)           # appended, never flushed
        os.write(rec._fd, b"BLK1" + (100).to_bytes(4, "little"))   # the writer dies mid-block
        os._exit(9)
    """)
    r = subprocess.run([sys.executable, "-c", prog], timeout=60)
    assert r.returncode == 9
    log = read_log(path)
    assert len(log) == 250 and not log.complete and log.truncated_bytes == 8
    assert np.array_equal(log.records["cycle"], np.arange(250))
    with pytest.raises(LogFormatError, match="cut short"):
        read_log(path, strict=True)


def test_corruption_names_file_and_block(tmp_path):
    path = tmp_path / "c.rcilog"
    with Recorder(path, robot="puma260", block_records=100) as rec:
        _fill(rec, 300)
    raw = bytearray(path.read_bytes())
    log = read_log(path)
    size = log.records.dtype.itemsize
    header_end = 12 + struct.unpack_from("<I", raw, 8)[0] + 4
    second_block_payload = header_end + (16 + 100 * size) + 16
    raw[second_block_payload + 5] ^= 0xFF
    bad = tmp_path / "bad.rcilog"
    bad.write_bytes(bytes(raw))
    with pytest.raises(LogFormatError) as e:
        read_log(bad)
    msg = str(e.value)
    assert str(bad) in msg and "block 1" in msg and "records 100..199" in msg and "checksum" in msg


@pytest.mark.parametrize("damage,expect", [
    (lambda b: b"XXXXXXXX" + b[8:], "not an RCI log"),
    (lambda b: b[:7] + b"\x07" + b[8:], "version 7"),
    (lambda b: b[:20] + b"!" + b[21:], "header checksum"),
    (lambda b: b[:5], "too short"),
])
def test_bad_headers(tmp_path, damage, expect):
    path = tmp_path / "x.rcilog"
    Recorder(path, robot="puma260").close()
    path.write_bytes(damage(path.read_bytes()))
    with pytest.raises(LogFormatError, match=expect):
        read_log(path)


def test_full_ring_drops_instead_of_blocking(tmp_path):
    rec = Recorder(tmp_path / "d.rcilog", robot="puma260", capacity=64)
    _fill(rec, 100)
    assert rec.dropped == 36 and rec.head == 64
    rec.close()
    assert len(read_log(tmp_path / "d.rcilog")) == 64


@settings(max_examples=25, deadline=None)
@given(st.lists(st.integers(1, 300), min_size=1, max_size=6), st.integers(1, 128))
def test_any_flush_pattern_keeps_every_record_in_order(tmp_path_factory, chunks, block):
    path = tmp_path_factory.mktemp("f") / "p.rcilog"
    rec = Recorder(path, robot="puma260", block_records=block, capacity=512)
    k = 0
    for n in chunks:
        _fill(rec, n, start=k)
        k += n
        rec.flush()
    rec.close()
    log = read_log(path)
    assert np.array_equal(log.records["cycle"], np.arange(k))
