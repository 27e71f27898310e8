"""bench.comm_rates (reports/comm-rates.md, thesis Table 2.1): the planning <-> control traffic of
RCCL and RCI programs, counted on a real lockstep simula; and the pick and place example run as a
user runs it."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from bench.comm_rates import measure, measure_gravity, measure_teach, render

ROOT = Path(__file__).resolve().parent.parent


def cells_of(text: str, key: str) -> list[str]:
    row = next(line for line in text.splitlines() if line.startswith(f"| {key}"))
    return [c.strip() for c in row.split("|")[1:-1]]


def test_the_guarded_move_sends_its_requests_and_gets_their_flags():
    t = measure("adaptive_guarded_move")
    assert len(t.requests) >= 2                          # down until the force limit, then back up
    assert all(r.status in ("done", "failed") for r in t.requests)
    assert len(t.c1) == len(t.c3) == len(t.requests)
    assert 200 < sum(t.c1) / len(t.c1) < 2000           # a position and its parameters as JSON
    assert 2.0 < t.seconds < 60.0
    text = render([("guarded", "RCCL guarded motion program", "guarded move", t)], "python -m bench.comm_rates", (0, 0))
    cells = cells_of(text, "guarded")
    assert float(cells[7]) == round(2 * len(t.requests) / t.seconds, 2)          # messages/s
    assert cells[9:] == ["1.2", "0.23"]                                          # the thesis's row


def test_the_teach_program_writes_one_goal_and_waits_one_arrival_per_jog():
    keys = "2++r3-rq"
    t = measure_teach(keys)
    jogs = sum(keys.count(k) for k in "+-")
    assert len(t.c1) == len(t.c3) == jogs
    assert all(60 < n < 300 for n in t.c1)              # a 6-joint vector as JSON
    assert 0.3 < t.seconds < 60.0                       # 2-degree jogs at 0.2 rad/s, a fraction of a second each
    text = render([("teach", "Manual teach mode program", "teach", t)], "python -m bench.comm_rates", (0, 0))
    assert cells_of(text, "teach")[9:] == ["1.3", "0.03"]


def test_the_gravity_measurement_hands_over_one_plan_and_waits_one_end():
    t = measure_gravity(warmup=False, segments=1)       # the report's run: the whole sweep and its warm-up
    assert len(t.c1) == len(t.c3) == 1
    assert sum(t.c1) > 200                              # the sweep's segment and notes
    assert 1.0 < t.seconds < 60.0                       # the approach and one 180-degree pass at 20 deg/s


def test_the_pick_and_place_example_runs_as_a_user_runs_it():
    out = subprocess.run([sys.executable, str(ROOT / "examples" / "pick_and_place.py"), "--parts", "1"], capture_output=True,
                         text=True, timeout=300, cwd=ROOT)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "1 parts placed" in out.stdout     # bench.comm_rates runs all 3
