"""The control task's timing summary: a record for programs, a table in milliseconds for people."""
from __future__ import annotations

import re

import pytest

from rci.timing import CycleTiming

PERIOD = 1 / 36


def _timing() -> CycleTiming:
    t = CycleTiming(capacity=256)
    for i in range(100):
        jitter = 0.0005 if i == 50 else 0.0001 * (i % 3)       # one HOW 0.5 ms late
        t.add(arrival=i * PERIOD + jitter, lateness=0.0002, duration=0.0004 + 0.0001 * (i % 2),
              user_time=0.0001, period=PERIOD)
    t.late_cycles, t.late_run_max, t.late_limit = 1, 1, 10
    return t


def test_summary_fields_stay_seconds_for_programs():
    s = _timing().summary()
    assert s.cycles == 100 and s.period == pytest.approx(PERIOD)
    assert s.duration_max == pytest.approx(0.0005)
    assert s.as_dict()["late_limit"] == 10


def test_summary_prints_as_a_table_in_milliseconds():
    s = _timing().summary()
    text = str(s)
    assert text == repr(s)                  # what a prompt shows is the table too
    lines = text.splitlines()
    assert lines[0] == "timing over 100 cycles at 36 Hz, period 27.778 ms"
    assert lines[1].split() == ["p50", "p99", "max"]
    duration = next(line for line in lines if line.startswith("cycle duration"))
    assert duration.split()[2:] == ["0.450", "ms", "0.500", "ms", "0.500", "ms"]
    jitter = next(line for line in lines if line.startswith("HOW interval jitter"))
    assert jitter.split()[-2:] == ["0.500", "ms"]
    assert "late 1 (longest run 1 of 10 allowed)" in lines[-1]
    # no raw floats: every number has at most three decimals
    assert not re.search(r"\d\.\d{4,}", text), text
    # the columns line up under their headings
    widths = {len(line) for line in lines[1:-1]}
    assert len(widths) == 1, lines


def test_an_empty_summary_prints_too():
    text = str(CycleTiming().summary())
    assert text.startswith("timing over 0 cycles\n")
