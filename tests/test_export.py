"""`.rcilog` exported to MCAP and Parquet (issue 18, item 3), read back with the mcap
reader and pyarrow, every raw value compared with the log (the SI channels and columns:
tests/test_export_si.py).

Two logs: one recorded here on a lockstep simula process with a user field (a vector), and
a shipped calibration log (compressed, 6337 cycles at 1 kHz).
"""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from mcap.reader import make_reader

from rci.chg import POS
from rci.export import columns, to_mcap, to_parquet, topic
from rci.recorder import Recorder, read_log
from rci.session import Session
from rci.simula.process import SimulaProcess

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def recorded(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("export") / "run.rcilog"
    rec = Recorder(path, robot="puma260", rate_hz=100,
                   user_fields={"k": ("i4", ()), "tau": ("f8", (6,))}, meta={"test": "export"})
    with SimulaProcess("-p", "--power-on", lockstep=True) as sim:
        with Session(sim.url, "puma260", rate_hz=100, signals=False, lock_memory=False) as s:
            s.record(rec)

            def f1():
                rec.user["k"] = s.how.cycle
                rec.user["tau"] = np.sin(s.how.cycle * np.arange(1, 7) / 7.0)   # doubles, not round numbers
                s.chg.motion[1].issue(POS, int(s.how.pos[1]) + 3)
            s.control(f1)
            s.wait(until=lambda: s.timing.count >= 60, seconds=10)
            s.release()
    rec.close()
    return path


@pytest.mark.parametrize("which", ["recorded", "shipped"])
def test_mcap_round_trip_every_value(which, recorded, tmp_path):
    src = recorded if which == "recorded" else ROOT / "calib" / "logs" / "friction-j2.rcilog.xz"
    log = read_log(src)
    out = tmp_path / "run.mcap"
    n = to_mcap(log, out)
    names = log.records.dtype.names
    raw = {topic(x) for x in names}
    si_messages = 0
    got: dict[str, list] = {}
    times: dict[str, list] = {}
    with open(out, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert raw <= {c.topic for c in summary.channels.values()}    # and the SI ones: tests/test_export_si.py
        for schema, channel, message in reader.iter_messages():
            assert schema.encoding == "jsonschema" and channel.message_encoding == "json"
            if channel.topic not in raw:
                si_messages += 1
                continue
            got.setdefault(channel.topic, []).append(json.loads(message.data)["value"])
            times.setdefault(channel.topic, []).append(message.log_time)
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
    for name in names:
        column = log.records[name]
        back = np.array(got[topic(name)], dtype=column.dtype)
        assert back.shape == column.shape and np.array_equal(back, column), name
        assert np.array_equal(times[topic(name)], np.round(log.records["t"] * 1e9).astype(np.int64))
    assert json.loads(meta["rcilog"]["header"]) == log.meta
    assert n == len(log) * len(names) + si_messages and si_messages >= 5 * len(log)


@pytest.mark.parametrize("which", ["recorded", "shipped"])
def test_parquet_round_trip_every_value(which, recorded, tmp_path):
    src = recorded if which == "recorded" else ROOT / "calib" / "logs" / "friction-j2.rcilog.xz"
    log = read_log(src)
    out = tmp_path / "run.parquet"
    assert to_parquet(log, out) == len(log)
    table = pq.read_table(out)
    flat = columns(log)
    assert table.column_names[:len(flat)] == list(flat)      # then the SI columns (tests/test_export_si.py)
    for name, column in flat.items():
        assert np.array_equal(table.column(name).to_numpy(), column), name
    assert json.loads(table.schema.metadata[b"rcilog"]) == log.meta
    if which == "recorded":
        assert np.array_equal(np.stack([flat[f"u_tau_{j}"] for j in range(1, 7)], axis=1), log.user("tau"))


def test_command_line_writes_both_and_refuses_a_damaged_log(recorded, tmp_path):
    run = [sys.executable, "-m", "rci.export"]
    r = subprocess.run([*run, str(recorded), "--mcap", str(tmp_path / "a" / "r.mcap"),
                        "--parquet", str(tmp_path / "a" / "r.parquet")], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    assert "messages" in r.stdout and "rows" in r.stdout and (tmp_path / "a" / "r.mcap").stat().st_size > 0
    bad = tmp_path / "bad.rcilog"
    bad.write_bytes(b"RCILOG\x00\x01" + b"\xff" * 40)
    r = subprocess.run([*run, str(bad), "--mcap", str(tmp_path / "b.mcap")], capture_output=True, text=True,
                       timeout=60)
    assert r.returncode == 2 and str(bad) in r.stderr and not (tmp_path / "b.mcap").exists()
    r = subprocess.run([*run, str(recorded)], capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and "nothing to do" in r.stderr
