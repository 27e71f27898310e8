"""Issue 30 item 3: progress on a terminal (a rich bar, the old force_terminal=bool(None) drew
none) and elsewhere (a line per log, and lines during a long one), here and on a recording on
a lockstep simula of a hidden truth (rcci.calib.hidden_truth seed 1, simula seed 4)."""
from __future__ import annotations

import io
import os
import time

from rcci.calib import progress as progress_mod
from rcci.calib.hidden_truth import write_hidden_truth
from rcci.calib.progress import Steps, mode, progress
from rcci.calib.regen import regen
from rcci.calib.registry import RecordOptions


def test_lines_per_step_and_during_a_step_when_not_a_terminal():
    out = io.StringIO()
    assert mode(None, out) == "lines" and mode(False, out) == "off" and mode(True, out) == "bar"
    with Steps(2, "recording", stream=out, every_s=0.05) as steps:
        steps.start("friction-j1")
        steps.within(500, 2000)
        time.sleep(0.3)
        steps.finish()
        steps.start("friction-j2")
        steps.finish()
    text = out.getvalue()
    assert "recording [1/2] friction-j1 (started at 0.0 min)" in text
    assert "recording [1/2] friction-j1: 25 % of 2000 cycles" in text
    assert "recording [2/2] friction-j2" in text
    quiet = io.StringIO()
    with Steps(1, "recording", enabled=False, stream=quiet, every_s=0.01) as steps:
        steps.start("static")
        time.sleep(0.05)
    assert quiet.getvalue() == ""


def _read_all(fd: int) -> bytes:
    import select

    data = b""
    while select.select([fd], [], [], 0.2)[0]:
        chunk = os.read(fd, 65536)
        if not chunk:
            break
        data += chunk
    return data


def test_a_bar_is_drawn_on_a_terminal(monkeypatch):
    """On a pseudo-terminal (not in CI) both the log reading and the campaign draw a rich bar: the
    old force_terminal=bool(None) drew nothing anywhere."""
    monkeypatch.delenv("CI", raising=False)
    master, slave = os.openpty()
    term = os.fdopen(slave, "w", encoding="utf-8")
    try:
        assert mode(None, term) == "bar"
        assert list(progress([1, 2], 2, "reading logs", stream=term, name=str)) == [1, 2]
        with Steps(1, "recording", stream=term) as steps:
            steps.start("friction-j5")
            steps.within(300, 600)
            time.sleep(0.3)                   # rich refreshes at 10 Hz
            steps.finish()
        term.flush()
        drawn = _read_all(master).decode("utf-8", "replace")
    finally:
        term.close()
        os.close(master)
    assert "reading logs" in drawn and "recording: friction-j5" in drawn
    assert "friction-j5 (cycles)" in drawn and "300/600" in drawn and "━" in drawn


def test_a_recording_says_how_far_it_is_while_it_runs(tmp_path, monkeypatch, capsys):
    """A static log (2 halts after its 100 s warm-up walk) on a hidden truth, stderr not a terminal:
    a line as it starts and, during it, lines with the share of its cycles done (every 30 s in
    use; every 0.2 s here, so that a quiet machine, which records it in seconds, shows several)."""
    truth = str(tmp_path / "hidden.toml")
    write_hidden_truth(truth, "puma260", 1)
    monkeypatch.setattr(progress_mod, "LINE_EVERY_S", 0.2)
    monkeypatch.delenv("CI", raising=False)
    done = regen(str(tmp_path / "logs"), 4, ("static",), truth, quiet=False,
                 options=RecordOptions(halts=2, rate=6))
    err = capsys.readouterr().err
    assert done["recorded"] == ["static"]
    assert "recording [1/1] static (started at 0.0 min)" in err
    lines = [line for line in err.splitlines() if line.startswith("recording [1/1] static: ")]
    assert all(" s in this step, " in line for line in lines), err        # while simula starts too
    shares = [int(line.split(": ")[1].split(" % of ")[0]) for line in lines if " % of " in line]
    assert len(shares) >= 2 and shares == sorted(shares) and 0 <= shares[0] < shares[-1] <= 100, err
