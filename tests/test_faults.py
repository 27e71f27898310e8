"""Fault injection against a real simula process (issue 13): every fault stops the arm.

Each test runs one case of ``rci.simula.faults`` (simula and the fault proxy as separate
processes, a controller moving joint 1 in current mode and joint 2 in position mode) and
checks who caught the fault, the code, power, that nothing hung, and the arm's motion
after the error as simula measured it: within one period's travel, and none at all once
the robot applied the end of the control. Lockstep where the fault does not depend on
the clock; the faults that are about time run against real-time simula. ``python -m
bench.faults`` runs every case in both modes (reports/faults.md).
"""
from __future__ import annotations

import pytest

from rci import codes
from rci.simula.faults import run_case


def _ended(r, number: int, *, severe: bool, by: str = "controller"):
    assert not r.invalid, r.invalid
    assert r.outcome == "ended", r
    assert r.detected_by.startswith(by) or r.detected_by.endswith(by), r
    if number:
        assert codes.error_number(r.code) == number, (r.code_name, r.detail)
        assert r.severe == severe, r
    assert r.power_after == ("off" if severe else "on"), r
    assert not r.hung, r.hung
    assert r.motion_after_reaction_deg <= 1e-4, r            # held: nothing moves once the robot ended it
    assert r.motion_cur_deg <= r.period_travel_deg, r
    assert r.motion_pos_deg <= r.period_travel_deg, r
    assert r.ok


def _survived(r):
    assert not r.invalid, r.invalid
    assert r.outcome == "survived" and not r.hung, r
    assert r.power_after == "on"


# --- item 1: the release is obeyed whatever its seq; severe faults power off ------------------
@pytest.mark.parametrize("lockstep", [False, True], ids=["realtime", "lockstep"])
def test_exception_in_f2_after_the_chg_went_out_stops_the_arm(lockstep):
    """The release follows the cycle's CHG with the same seq (a duplicate): simula obeys it."""
    r = run_case("exception in f2", lockstep=lockstep)
    _ended(r, codes.R_USERFUNC, severe=False)
    assert "injected fault in f2" in r.detail
    if lockstep:      # lockstep: the release comes at the instant of the HOW it answers
        assert r.motion_cur_deg == 0.0 and r.motion_pos_deg == 0.0


@pytest.mark.parametrize("lockstep", [False, True], ids=["realtime", "lockstep"])
def test_corrupt_how_is_r_chksum_severe_and_the_arm_stops_powered_off(lockstep):
    _ended(run_case("HOW corrupted", lockstep=lockstep), codes.R_CHKSUM, severe=True)


def test_lost_chg_in_lockstep_ends_the_control_on_both_sides():
    """Lockstep simula used to stay 'running' forever after such a fault; now the release ends it."""
    _ended(run_case("CHG lost", lockstep=True), codes.R_TIMEOUT, severe=True)


def test_overrun_and_hung_function_release_the_arm():
    _ended(run_case("overrun", lockstep=False), codes.R_OVERRUN, severe=False)
    r = run_case("hung function", lockstep=False)
    _ended(r, codes.R_OVERRUN, severe=False)
    assert "still running" in r.detail


def test_delayed_how_is_a_timeout():
    _ended(run_case("HOW delayed", lockstep=False), codes.R_TIMEOUT, severe=True)


# --- faults only the robot can see: simula reacts itself ---------------------------------------
def test_corrupt_chg_is_caught_by_simula_and_blamed_on_the_link():
    r = run_case("CHG corrupted", lockstep=False)
    _ended(r, codes.R_CHKSUM, severe=True, by="simula")
    assert "corrupt frame from the controller" in r.detail


def test_dead_link_to_the_robot_is_r_chglate_and_power_goes_off_although_the_release_is_lost():
    r = run_case("CHG link dead", lockstep=False)
    _ended(r, codes.R_CHGLATE, severe=True)
    assert "late cycles in a row" in r.detail


def test_killed_controller_holds_the_arm_and_switches_power_off():
    r = run_case("controller killed", lockstep=False)
    _ended(r, 0, severe=True, by="simula")
    assert r.code_name.startswith("link lost")


def test_stopped_controller_trips_the_watchdog_current_mode_held_at_the_first_missing_chg():
    r = run_case("controller stopped", lockstep=False)
    _ended(r, 0, severe=True, by="simula")
    assert r.code_name == "watchdog"
    # from the stop on: the rest of the period whose CHG had come, then one period without,
    # then the current-mode joint is held (docs/safety.md) - never the 0.1 s of the watchdog
    assert r.motion_cur_since_fault_deg <= 2 * r.period_travel_deg + 1e-9


# --- faults the policy survives ---------------------------------------------------------------
@pytest.mark.parametrize("name", ["CHG lost", "CHG duplicated", "HOW duplicated"])
def test_isolated_link_faults_are_counted_not_fatal(name):
    r = run_case(name, lockstep=False)
    _survived(r)
    if name == "HOW duplicated":
        assert "duplicate HOWs 1" in r.notes[0]


# --- item 2: one controller owns the arm -------------------------------------------------------
def test_a_second_controller_is_refused_and_the_running_control_goes_on():
    r = run_case("second controller", lockstep=False)
    _survived(r)
    assert any("second controller refused" in n and "robot busy: owned by pid" in n for n in r.notes), r.notes
