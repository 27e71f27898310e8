"""bench/rccl_cycle.py, short run: the whole-control-function rows (Arm._cycle on synthetic HOWs) are
written beside the step-only tables, and the report's sections from other scripts are kept.

Correctness of the report only: the speeds are the bench's (reports/bench-rccl.md), never asserted here.
"""
from __future__ import annotations

import math
import re

import numpy as np
import pytest

from bench import arm_cycle, rccl_cycle

BLEND = "## Blending through queued positions: quartic vs Ruckig\n\nblend table kept verbatim\n\n"
RATE = "## Rate change in the middle of a move (simula, lockstep)\n\nrate table kept verbatim\n"
# an older report: other scripts' sections both between this script's own ones and after them
OLD = ("# RCCL trajectory generator: cost per control cycle\n\nold step table\n\n"
       f"{rccl_cycle.JERK_HEADING}\n\nold ruckig rows\n\n{BLEND}"
       f"{rccl_cycle.CONTROL_HEADING}\n\nold control rows\n\n{RATE}")


@pytest.fixture(scope="module")
def report(tmp_path_factory) -> str:
    out = tmp_path_factory.mktemp("bench") / "bench-rccl.md"
    out.write_text(OLD)
    assert rccl_cycle.main(["--cycles", "150", "--repeats", "1", "--out", str(out)]) == 0
    return out.read_text()


def control_rows(text: str) -> list[list[str]]:
    section = text[text.index(rccl_cycle.CONTROL_HEADING):]
    section = section[:section.index("\n## ")] if "\n## " in section else section
    return [[c.strip() for c in line.strip("|").split("|")] for line in section.splitlines()
            if re.match(r"\| (quartic|ruckig) \|", line)]


def test_every_generator_mode_and_feature_has_a_control_function_row(report):
    rows = control_rows(report)
    assert {(r[0], r[1], r[2]) for r in rows} == set(rccl_cycle.CONTROL_ROWS)
    assert len(rows) == len(rccl_cycle.CONTROL_ROWS) == 2 * 2 * len(arm_cycle.FEATURES)
    for r in rows:
        mean, median, p99, top = (float(x) for x in r[3:7])
        assert 0 < median <= p99 <= top and 0 < mean <= top, r
        pairs = [tuple(float(x) for x in cell.split(",")) for cell in r[7:11]]
        assert all(len(p) == 2 and all(math.isfinite(v) for v in p) for p in pairs), r
        step_alone, step, adaptive, _rest = pairs
        assert 0 < step_alone[0] <= step_alone[1] and 0 < step[0] <= step[1] and 0 < adaptive[0] <= adaptive[1], r
        # the whole cycle holds the step: its median is above the step's alone on the same tour
        assert median > step[0], r


def test_the_text_gives_the_adaptive_cost_and_the_ruckig_verdict_with_the_load(report):
    section = report[report.index(rccl_cycle.CONTROL_HEADING):]
    for feature in arm_cycle.FEATURES:
        assert re.search(rf"- \*{feature}\*: median [\d.-]+ us, p99 [\d.-]+ us", section), feature
    verdict = re.search(r"Target \(issue 18: .*? on the whole control function, Ruckig joint mode, const "
                        r"targets: (.*?)\. The step alone", section)
    assert verdict and verdict.group(1).count("**") == 2 * len(arm_cycle.FEATURES)
    # "load average" mid-sentence on a loaded machine, "Load average" opening the sentence on a quiet one
    assert re.search(r"[Ll]oad average \(1 min\) [\d.]+ before the run, [\d.]+ when the control-function rows "
                     r"started, [\d.]+ after", section)


def test_the_step_only_tables_are_still_written(report):
    head = report[:report.index(rccl_cycle.JERK_HEADING)]
    assert sum(1 for line in head.splitlines() if re.match(r"\| (puma260|microbo) \|", line)) == len(rccl_cycle.ROWS)
    jerk = report[report.index(rccl_cycle.JERK_HEADING):report.index(rccl_cycle.CONTROL_HEADING)]
    assert sum(1 for line in jerk.splitlines() if line.startswith("| puma260 |")) == len(rccl_cycle.RUCKIG_ROWS)


def test_other_scripts_sections_are_kept_and_the_old_own_ones_replaced(report):
    for heading in ("## Blending through queued positions", "## Rate change in the middle of a move"):
        assert report.count(heading) == 1
    assert "blend table kept verbatim" in report and "rate table kept verbatim" in report
    assert report.count(rccl_cycle.CONTROL_HEADING) == 1 and report.count(rccl_cycle.JERK_HEADING) == 1
    assert "old control rows" not in report and "old ruckig rows" not in report and "old step table" not in report


def test_the_synthetic_how_follows_the_commands():
    la = arm_cycle.LinklessArm("puma260", "ruckig", "joint", rccl_cycle.START["puma260"], rccl_cycle.RATE_HZ)
    arm = la.arm
    la.queue(rccl_cycle.tour(arm.kinematics, "puma260", "const")[:1], "monitor")
    for _ in range(4):      # a few cycles into the 5 cm move
        la.next_how()
        arm._cycle()
    commanded = np.array([m.value for m in arm.rci.chg.motion])
    la.next_how()
    assert np.abs(np.asarray(arm.rci.how.pos) - commanded).max() <= 1          # counts, with -1..1 of noise
    assert arm.gen.request is not None and arm.gen.request.checks               # the monitor rides the motion
    assert arm.adaptive.last is not None and arm.adaptive.last.torque is not None


def test_an_unknown_feature_is_named():
    la = arm_cycle.LinklessArm("puma260", "quartic", "joint", rccl_cycle.START["puma260"], rccl_cycle.RATE_HZ)
    with pytest.raises(ValueError, match="feature 'sensor'"):
        la.queue(rccl_cycle.tour(la.arm.kinematics, "puma260", "const"), "sensor")
