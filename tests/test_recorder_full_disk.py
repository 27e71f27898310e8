"""The recorder on a disk that fills up (issue 29, item 4): a real 64 KiB tmpfs, filled by the log itself.

The program is told as it chose (a ``LogWriteError``, a ``RecorderWarning``, or its own
function, here one that ends the control), ``written`` is what the file holds, every record
is counted once (written + lost + dropped = recorded), and ``close()`` leaves a file that
reads back to its last whole block, with its end marker.
"""
from __future__ import annotations

import errno
import os
import subprocess
import warnings

import numpy as np
import pytest

from rci import codes
from rci.chg import POS
from rci.exceptions import ControlTerminated, LogWriteError, RecorderWarning
from rci.how import How
from rci.recorder import Recorder, read_log
from rci.session import Session
from rci.simula.process import SimulaProcess


@pytest.fixture
def small_disk(tmp_path):
    """A 64 KiB tmpfs mounted for the test (root, as CI and `make test` run), unmounted after."""
    disk = tmp_path / "disk"
    disk.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(disk)],
                       capture_output=True, text=True)
    if r.returncode != 0:
        pytest.fail(f"this test mounts a 64 KiB tmpfs and needs root (CAP_SYS_ADMIN): {r.stderr.strip()}")
    try:
        yield disk
    finally:
        subprocess.run(["umount", "-l", str(disk)], check=True)


def _append(rec: Recorder, start: int, n: int) -> None:
    h = How()
    for k in range(start, start + n):
        h.cycle = k
        h.pos[:] = k
        rec.append(h, None)


def _free(path) -> int:
    st = os.statvfs(path)
    return st.f_bavail * st.f_frsize


def test_flush_raises_a_typed_error_and_the_file_reads_back_to_its_last_block(small_disk):
    path = small_disk / "run.rcilog"
    rec = Recorder(path, robot="puma260", block_records=50, on_write_error="raise")
    appended, error = 0, None
    while error is None and appended < 5000:
        _append(rec, appended, 100)
        appended += 100
        try:
            rec.flush()
        except LogWriteError as e:
            error = e
    assert error is not None, "a 64 KiB disk did not fill"
    assert error.errno == errno.ENOSPC and "No space left" in str(error) and str(path) in str(error)
    assert rec.written == error.written and rec.written > 0
    _append(rec, appended, 100)                         # the control goes on appending: counted, never written
    appended += 100
    with pytest.raises(LogWriteError):
        rec.flush()
    with pytest.raises(LogWriteError):                  # close finishes the file, then says it again
        rec.close()
    assert rec.closed
    assert rec.written + rec.lost + rec.dropped == appended
    log = read_log(path, strict=True)                   # whole blocks and the end marker: no damage
    assert log.complete and len(log) == rec.written and log.blocks == rec.written // 50
    assert np.array_equal(log.records["cycle"], np.arange(rec.written))
    assert os.path.getsize(path) + _free(small_disk) <= 64 * 1024


def test_a_full_disk_during_a_control_warns_and_the_control_goes_on(small_disk):
    path = small_disk / "run.rcilog"
    rec = Recorder(path, robot="puma260", rate_hz=100, block_records=32)    # on_write_error="warn", the default
    with SimulaProcess("-p", "--power-on", lockstep=True) as sim:
        with Session(sim.url, "puma260", rate_hz=100, signals=False, lock_memory=False, on_error="raise",
                     timeout=2.0) as s:
            s.record(rec)
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                rec.start_writer(0.02)
                s.control(lambda: s.chg.motion[0].issue(POS, int(s.how.pos[0])))
                assert s.wait(until=lambda: rec.error is not None, seconds=20), "the disk did not fill"
                at_error = s.timing.count
                assert s.wait(until=lambda: s.timing.count >= at_error + 100, seconds=20)
                assert s.in_control                                # the control went on
                s.release()
            s.record(None)
    warned = [w for w in caught if issubclass(w.category, RecorderWarning)]
    assert len(warned) == 1 and "No space left on device" in str(warned[0].message)
    rec.close()                                                    # "warn": close does not raise
    recorded = rec.written + rec.lost + rec.dropped
    assert recorded == rec.head + rec.dropped and recorded >= at_error + 100
    log = read_log(path, strict=True)
    assert log.complete and len(log) == rec.written
    assert np.all(np.diff(log.records["cycle"].astype(np.int64)) == 1)   # no gap inside what was written


def test_the_program_can_end_the_control_when_the_log_cannot_be_written(small_disk):
    path = small_disk / "run.rcilog"
    code = codes.R_USER_BASE + 7
    with SimulaProcess("-p", "--power-on", lockstep=True) as sim:
        with Session(sim.url, "puma260", rate_hz=100, signals=False, lock_memory=False, on_error="raise",
                     timeout=2.0) as s:
            rec = Recorder(path, robot="puma260", rate_hz=100, block_records=32,
                           on_write_error=lambda e: setattr(s, "terminate", code))
            s.record(rec)
            rec.start_writer(0.02)
            s.control(lambda: None)
            with pytest.raises(ControlTerminated) as term:
                s.wait(seconds=30)
            assert term.value.code == code and not s.in_control
    rec.close()
    assert isinstance(rec.error, LogWriteError) and rec.error.errno == errno.ENOSPC
    assert len(read_log(path, strict=True)) == rec.written > 0


def test_on_write_error_is_checked():
    with pytest.raises(ValueError, match="on_write_error='ignore'"):
        Recorder("/dev/null", robot="puma260", on_write_error="ignore")


def test_close_gives_up_the_last_flush_to_make_room_for_the_end_marker(tmp_path, monkeypatch):
    """A disk that fills up just before the end marker (the page the marker needs is the one that
    is not there: it happened on the tmpfs above, now and then): ``close`` cuts back the last
    flush's blocks, counts them lost, and the file reads back complete with ``written`` records."""
    import rci.recorder as recorder

    path = tmp_path / "run.rcilog"
    rec = Recorder(path, robot="puma260", block_records=10, on_write_error="warn")
    _append(rec, 0, 30)
    assert rec.flush() == 30
    _append(rec, 30, 20)
    assert rec.flush() == 20
    real, failed = recorder.Recorder._write_all, []

    def full_once(self, data: bytes) -> None:
        if data.startswith(recorder.END_MAGIC) and not failed:
            failed.append(True)
            raise OSError(errno.ENOSPC, "No space left on device")
        real(self, data)

    monkeypatch.setattr(recorder.Recorder, "_write_all", full_once)
    rec.close()
    assert failed and rec.written == 30 and rec.lost == 20 and rec.error is None
    log = read_log(path, strict=True)
    assert len(log) == 30 and log.complete
