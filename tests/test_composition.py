"""The composition matrix of issue 25 as a test: every generator x feature x arm x link cell on a lockstep simula.

A representative subset runs by default (each feature at least once, both generators, both
links, three arms); the whole matrix runs with ``-m matrix`` (10 min at load 12-16). A cell
passes the test when it passes, or when the combination is refused with a sentence (the
issue's "refused before the motion starts with a message naming it"); a fail cell fails it. The report with every cell's verdict: ``python -m tests.composition --report
reports/composition.md``. What each cell checks: tests/composition.py.
"""
from __future__ import annotations

import contextlib

import pytest

import composition as cm

SUBSET = {
    ("quartic", "plain", "puma260", "socket"), ("ruckig", "functional", "puma260", "socket"),
    ("quartic", "functional", "puma260", "socket"), ("ruckig", "force_limit", "puma260", "socket"),
    ("ruckig", "compliance", "puma260", "socket"), ("ruckig", "conditional", "puma260", "socket"),
    ("quartic", "event_flags", "puma260", "socket"), ("quartic", "rate_change", "puma260", "socket"),
    ("ruckig", "monitor", "microbo", "zenoh"), ("ruckig", "deviation_limit", "microbo", "zenoh"),
    ("ruckig", "plain", "stanford", "socket"), ("quartic", "feedforward", "puma560", "socket"),
    ("quartic", "collision", "puma260", "socket"), ("ruckig", "collision", "stanford", "socket"),
    ("quartic", "redundancy", "puma260", "socket"), ("quartic", "redundancy", "panda", "socket"),
    ("ruckig", "redundancy", "panda", "socket"),
}
CELLS = [pytest.param(g, f, a, lk, id=f"{a}-{lk}-{g}-{f}",
                      marks=() if (g, f, a, lk) in SUBSET else (pytest.mark.slow, pytest.mark.matrix))
         for a in cm.ARMS for lk in cm.LINKS for g in cm.GENERATORS for f in cm.FEATURES]


@pytest.fixture(scope="module")
def simulas():
    """One lockstep simula per (arm, link), started when a cell first needs it."""
    with contextlib.ExitStack() as stack:
        started: dict = {}

        def get(robot: str, link: str):
            if (robot, link) not in started:
                started[robot, link] = stack.enter_context(cm.simula(robot, link))
            return started[robot, link]
        yield get


@pytest.mark.parametrize("generator, feature, robot, link", CELLS)
def test_cell(simulas, generator, feature, robot, link):
    v = cm.run_cell(simulas(robot, link).url, robot, generator, feature)
    assert v.status != "fail", v.detail
    if v.status == "refused":
        assert len(v.detail.split()) > 5, v.detail     # a sentence, not a bare code
