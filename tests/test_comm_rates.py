"""bench.comm_rates (reports/comm-rates.md, thesis Table 2.1): the planning <-> control traffic of
an RCCL program, counted on a real lockstep simula."""
from __future__ import annotations

from bench.comm_rates import measure, render


def test_the_guarded_move_sends_its_requests_and_gets_their_flags():
    t = measure("adaptive_guarded_move")
    assert len(t.requests) >= 2                          # down until the force limit, then back up
    assert all(r.status in ("done", "failed") for r in t.requests)
    assert 200 < t.request_bytes / len(t.requests) < 2000      # a position and its parameters as JSON
    assert 2.0 < t.seconds < 60.0
    text = render([("guarded", "RCCL guarded motion program", "guarded move", t)], "python -m bench.comm_rates", (0, 0))
    row = next(line for line in text.splitlines() if line.startswith("| guarded"))
    cells = [c.strip() for c in row.split("|")[1:-1]]
    assert float(cells[7]) == round(2 * len(t.requests) / t.seconds, 2)          # messages/s
    assert cells[9:] == ["1.2", "0.23"]                                          # the thesis's row
