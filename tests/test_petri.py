"""Petri nets of event flag triples (rccl.petri, thesis 1.4.5 and 5.6.3): the thesis's net, the
two-arm program, and deliberately broken programs, each found with the firing sequence that shows it."""
from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

from rccl import petri
from rccl.events import DONE, START, Deadlock, EventError

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def load_example(name: str):
    spec = importlib.util.spec_from_file_location(f"petri_example_{name}", EXAMPLES / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_the_thesis_net_is_safe_and_every_run_completes_with_a_stop_status():
    a = petri.analyse(petri.thesis_net())
    assert a.bounded and a.safe and a.bound == 1
    assert a.live and a.ok                           # every transition can fire, every run ends properly
    assert a.markings == 8 and not a.deadlocks and not a.livelocks and not a.unreachable
    # the only end: motion completed (p5) with the status last set to a stop code (p7), never p6 left
    assert a.final == [{"p1": 1, "p2": 1, "p5": 1, "p7": 1}]


def test_the_thesis_net_without_the_stop_priority_of_rule_3_can_leave_the_status_stuck():
    """Drop rule 3's test (begin only while the stop flag is NULL): a motion stopped before it began
    can still begin, and then no transition ends it (the stop was already consumed): a deadlock."""
    net = petri.thesis_net()
    ts = [t for t in net.transitions if not t.name.startswith("stopped")]
    ts = [petri.NetTransition(t.name, {k: v for k, v in t.inputs.items() if k != "p2'"},
                           {k: v for k, v in t.outputs.items() if k != "p2'"}) if t.name.startswith("begin") else t
          for t in ts]
    a = petri.analyse(petri.Net(net.places, ts, net.initial, net.is_final, "no rule 3"))
    assert a.deadlocks
    d = a.deadlocks[0]
    assert d.marking.get("p6") == 1 and d.marking.get("p4") == 1          # active, status stuck at a start code
    assert d.sequence[-1].startswith("begin") and "set stop" in d.sequence


def test_the_two_arm_program_is_deadlock_free_and_safe():
    ex = load_example("two_arm_flags")
    prog = petri.record(ex.plan, "puma", "microbo")
    assert [e.arm for e in prog.efts] == ["puma", "microbo", "puma", "microbo"]
    a = petri.check(prog)                              # raises on any finding
    assert a.safe and a.ok and len(a.final) == 1
    # the Microbo's first motion begins only after the PUMA's first ended, in every run
    net = prog.net()
    for t in net.transitions:
        if t.name.startswith("microbo: #2") and "begins" in t.name:
            assert "#2.start set" in t.inputs
    # the ending transitions of #1 set #2's start flag: that is the only way it gets set
    setters = [t.name for t in net.transitions if t.outputs.get("#2.start set") and not t.inputs.get("#2.start set")]
    assert setters and all(s.startswith(("puma: #1", "planning: move_ev(microbo")) for s in setters)


def test_the_two_arm_program_runs_after_its_check(tmp_path):
    out = subprocess.run([sys.executable, str(EXAMPLES / "two_arm_flags.py"), "--simula"], capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert "safe" in out.stdout and "every run ends in one" in out.stdout
    ended = [line for line in out.stdout.splitlines() if line.startswith("motion ")]
    assert len(ended) == 4 and all(f"status {DONE}," in line for line in ended)


def test_a_wait_on_a_postponed_motion_is_a_deadlock_with_its_sequence():
    def plan(ev, puma):
        a = ev.move_ev(puma, "pa", start=None)
        ev.wait_ev(a)                                   # nobody but this blocked planning level can start it
        ev.start_ev(START, a)
    a = petri.analyse(petri.record(plan, "puma").net())
    assert len(a.deadlocks) == 1
    d = a.deadlocks[0]
    assert d.sequence == ["planning: move_ev(puma to pa, start postponed) -> #1"]
    assert d.marking["planning at 1"] == 1 and d.marking["#1.pending"] == 1 and d.marking["#1.start NULL"] == 1
    with pytest.raises(Deadlock, match="reached by: planning: move_ev"):
        petri.check(plan, "puma")


def test_two_arms_waiting_for_each_other_deadlock_and_the_sequence_names_both_start_conditions():
    def plan(ev, puma, mic):
        b = ev.move_ev(mic, "pb", start=None)
        a = ev.move_ev(puma, "pa", start=b)
        ev.start_after(b, a)                            # the runtime refuses this at once; found before running
        ev.wait_ev(a)
    a = petri.analyse(petri.record(plan, "puma", "microbo").net())
    assert len(a.deadlocks) == 1
    seq = a.deadlocks[0].sequence
    assert seq[-1].startswith("planning: start_after(#1, #2)")
    assert "puma: #2 to pa begins (rule 1)" in a.unreachable and "microbo: #1 to pb begins (rule 1)" in a.unreachable


def test_waiting_for_a_follower_to_begin_before_starting_its_leader_hangs_the_planning_level():
    """The Microbo's motion starts when the PUMA's ends; the planning level waits for the Microbo's to
    begin before it starts the PUMA's: every run hangs at the wait (statement 2)."""
    def plan(ev, puma, mic):
        a = ev.move_ev(puma, "pa", start=None)
        b = ev.move_ev(mic, "pb", start=a)
        ev.wait_ev(b, started=True)
        ev.start_ev(START, a)
    a = petri.analyse(petri.record(plan, "puma", "microbo").net())
    assert a.deadlocks and all(f.marking.get("planning at 2") == 1 for f in a.deadlocks)


def test_a_stop_set_before_the_start_deletes_the_motion_and_its_begin_is_unreachable():
    def plan(ev, puma):
        a = ev.move_ev(puma, "pa", start=None)
        ev.stop_ev(-7, a)                               # forgot start_ev: rule 3 deletes the motion
        ev.wait_ev(a)
    a = petri.analyse(petri.record(plan, "puma").net())
    assert not a.deadlocks and len(a.final) == 1        # the program ends...
    assert a.unreachable == ["puma: #1 to pa begins (rule 1)"]     # ...but the arm never moves
    with pytest.raises(EventError, match="begins .rule 1. can never happen"):
        petri.check(plan, "puma")


def test_a_stop_that_may_come_before_the_start_is_a_race_both_ends_reachable():
    def plan(ev, puma):
        a = ev.move_ev(puma, "pa")
        ev.stop_ev(-7, a)                               # may stop it, or delete it before it began
        ev.wait_ev(a)
    a = petri.analyse(petri.record(plan, "puma").net())
    assert a.ok
    names = {t.name for t in a.net.transitions}
    assert "puma: #1 to pa is deleted: stop before start (rule 3)" in names


def test_an_unbounded_place_is_found_with_the_sequence_that_pumps_it():
    """Thesis Figure 2.8: the one-way queue is bounded by its free slots; without them it is not."""
    good = petri.analyse(petri.queue_net(3))
    assert good.bounded and good.bound == 3 and good.live and not good.safe
    bad = petri.analyse(petri.queue_net(None))
    assert not bad.bounded and not bad.ok
    (f,) = bad.unbounded
    assert "'items'" in f.what and f.sequence == ["producer puts an item"] and f.marking["items"] == petri.OMEGA


def test_token_passing_is_safe_and_live_and_mutual_exclusion_holds():
    """Thesis Figure 2.7: the two tasks are never in the shared data at the same time."""
    net = petri.token_passing_net()
    a = petri.analyse(net)
    assert a.safe and a.live and a.markings == 4
    m0 = net.marking(net.initial)
    seen, todo = {m0}, [m0]
    while todo:
        m = todo.pop()
        named = net.named(m)
        assert not (named.get("1 in data") and named.get("2 in data"))
        for k in net.enabled(m):
            m2 = net.fire(m, k)
            if m2 not in seen:
                seen.add(m2)
                todo.append(m2)
    assert len(seen) == 4


def test_a_net_that_loses_an_action_is_not_live():
    t = [petri.NetTransition("once", {"a": 1}, {"b": 1}), petri.NetTransition("loop", {"b": 1}, {"b": 1})]
    a = petri.analyse(petri.Net(["a", "b"], t, {"a": 1}))
    assert not a.live and [f.what for f in a.not_live] == ["'once' can never fire again"]
    assert a.not_live[0].sequence == ["once"]


def test_malformed_nets_and_foreign_efts_are_refused_with_what_and_where():
    with pytest.raises(petri.NetError, match="unknown place 'nowhere'"):
        petri.Net(["a"], [petri.NetTransition("t", {"nowhere": 1}, {})], {"a": 1})
    with pytest.raises(petri.NetError, match="arc weight 0"):
        petri.Net(["a"], [petri.NetTransition("t", {"a": 0}, {})], {"a": 1})
    prog = petri.FlagProgram()
    with pytest.raises(EventError, match="wait_ev: 'x' is not an EFT"):
        prog.wait_ev("x")
    with pytest.raises(petri.NetError, match="more than 1 coverability nodes"):
        petri.analyse(petri.thesis_net(), limit=1)


def test_the_command_line_checks_a_plan_file_and_the_thesis_net():
    ok = subprocess.run([sys.executable, "-m", "rccl.petri", str(EXAMPLES / "two_arm_flags.py") + ":plan",
                         "puma", "microbo"], capture_output=True, text=True, timeout=60)
    assert ok.returncode == 0 and "safe" in ok.stdout
    thesis = subprocess.run([sys.executable, "-m", "rccl.petri"], capture_output=True, text=True, timeout=60)
    assert thesis.returncode == 0 and "8 reachable markings" in thesis.stdout
