"""Event flag triples across processes on the Zenoh bus (rccl.bus.planning, rccl.bus.arm), with real OS processes.

Two real-time simula processes (-p --power-on), two arm processes (``python -m rccl.bus.arm``)
each driving one of them, and the planning level in this test's process (the bus's hub,
on loopback). The arms' links to their simulas are sockets here (they are robust on a
loaded machine; docs/zenoh.md has the Zenoh link's own tests); the flags, requests and
reports cross the Zenoh bus. Faults are real: an arm process is killed mid-plan.
"""
from __future__ import annotations

import importlib.util
import os
import signal
import time
from contextlib import ExitStack
from pathlib import Path

import numpy as np
import pytest

from rccl.bus import arm as bus_arm
from rccl.bus.planning import (ArmLost, BusEvents, arm_key, flags_key, position_from_wire, position_to_wire, set_key)
from rccl.events import DONE, Deadlock, EventError, UnknownEvent
from rccl.exceptions import MotionError
from rccl.position import joint_position
from rccl.session import load_kinematics
from rci.bus import Bus
from rci.bus.link import free_endpoint
from rci.simula.process import SimulaProcess

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
RATE_HZ = 50
SAMPLE_S = 1.0 / RATE_HZ
HOW_TIMEOUT_S = 0.25          # the arm processes' wait for a HOW: generous on a loaded 2-core machine
WATCHDOG_S = 0.25
# this process is the planning level of run_bus: under load its heartbeat thread waited over the
# default 0.5 s silence for a CPU and the arms gave it up mid-plan (docs/zenoh.md)
PLANNER_SILENCE_S = 1.0


def _example():
    spec = importlib.util.spec_from_file_location("zenoh_flags_two_arm_flags", EXAMPLES / "two_arm_flags.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _simula(stack: ExitStack, robot: str) -> SimulaProcess:
    return stack.enter_context(SimulaProcess("-p", "--power-on", "--watchdog-time", str(WATCHDOG_S), robot=robot,
                                             lockstep=False))


def test_positions_and_keys_cross_the_bus_as_plain_data():
    kin = load_kinematics("puma260")
    q = np.array([0.1, -0.5, 0.3, 0.0, 0.4, -0.2])
    p = position_from_wire(position_to_wire(joint_position("p1", kin, q)), kin)
    assert p.name == "p1" and np.allclose(p.joints, q) and np.allclose(p.solve(), kin.fk(q))
    t6 = kin.fk(q)
    moved = position_from_wire({"name": "c", "t6": t6.tolist()}, kin)
    assert np.allclose(moved.solve(), t6)
    for bad, why in (({"name": "x", "t6": [[1, 2]]}, "4x4"), ("p1", "name"), ({"joints": [0] * 6}, "name")):
        with pytest.raises(EventError, match=why):
            position_from_wire(bad, kin)
    with pytest.raises(EventError, match="not a Position"):
        position_to_wire("over_part")
    assert arm_key("lab", "puma", "request") == "rcci/lab/arm/puma/request"
    assert flags_key("lab", "puma", 3) == "rcci/lab/flags/puma/3" and set_key("lab") == "rcci/lab/flags/set"


def test_the_two_arm_plan_runs_unchanged_across_three_processes():
    """examples/two_arm_flags.py's plan(ev, puma, mic, pos), the planning level here, each arm in its own process."""
    ex = _example()
    with ExitStack() as stack:
        sims = {name: _simula(stack, robot) for name, robot in ex.ARMS.items()}
        out = ex.run_bus({n: s.url for n, s in sims.items()}, free_endpoint(), RATE_HZ, how_timeout=HOW_TIMEOUT_S,
                         silence=PLANNER_SILENCE_S)
        truth = {n: np.array(s.command("state")["state"]["q"]) for n, s in sims.items()}
    e = out["efts"]
    assert {k: x.status for k, x in e.items()} == {"a": DONE, "b": DONE, "c": DONE, "d": DONE}
    assert [x.arm for x in e.values()] == ["puma", "microbo", "puma", "microbo"] and all(x.freed for x in e.values())
    # b (the Microbo) starts after a (the PUMA) ended: one bus hop and at most one of its samples;
    # the bound leaves room for a loaded machine (measured figures: docs/zenoh.md)
    lag = e["b"].t_started - e["a"].t_ended
    assert 0.0 <= lag <= 10 * SAMPLE_S, f"b began {lag * 1e3:.1f} ms after a ended"
    # c and d were started by one publication: each at its arm's next sample (two independent
    # clocks: typically within one sample; the bound leaves room for a loaded machine)
    assert abs(e["c"].t_started - e["d"].t_started) <= 5 * SAMPLE_S
    assert e["c"].t_started >= e["b"].t_ended and e["d"].t_started >= e["b"].t_ended
    # the arm processes reported each motion's end on their channels, with where the robot was
    reports = out["reports"]
    assert sorted((arm, r["where"]) for arm, r in reports) == sorted(
        [("puma", "over_part"), ("puma", "away"), ("microbo", "under_part"), ("microbo", "lift")])
    targets = out["targets"]
    for arm, r in reports:
        assert r["status"] == DONE and abs(r["q"][0] - targets[r["where"]][0]) < 2e-3
    # and the simulas (the world) have each arm at its last target
    assert np.allclose(truth["puma"], targets["away"], atol=5e-3)
    assert np.allclose(truth["microbo"], targets["lift"], atol=5e-3)


def _waist(arm, delta: float, name: str):
    q = arm.q.copy()
    q[0] += delta
    return joint_position(name, arm.kinematics, q)


def test_flags_errors_and_a_killed_arm_process_mid_plan():
    """start_ev / stop_ev on remote EFTs, refusals named, a deadlock found at once, and an arm
    process killed while the plan waits: ArmLost within a bound, the robot holds the arm."""
    with ExitStack() as stack:
        sims = {"puma": _simula(stack, "puma260"), "microbo": _simula(stack, "microbo")}
        listen = free_endpoint()
        bus = stack.enter_context(Bus("flags-faults", tasks=("planning",), listen=(listen,)))
        procs = {}
        for name, robot in (("puma", "puma260"), ("microbo", "microbo")):
            procs[name] = bus_arm.spawn(name, sims[name].url, robot, "flags-faults", (listen,), RATE_HZ,
                                        how_timeout=HOW_TIMEOUT_S)
            stack.callback(_kill, procs[name])
        ev = BusEvents(bus)
        stack.callback(ev.close)
        puma, mic = ev.arm("puma"), ev.arm("microbo")
        assert (puma.robot, mic.robot, puma.rate_hz) == ("puma260", "microbo", RATE_HZ)

        # a held motion nobody starts: the wait is a deadlock at once, named
        held = ev.move_ev(mic, _waist(mic, 0.1, "held"), start=None)
        t0 = time.monotonic()
        with pytest.raises(Deadlock, match="start flag of motion .* 'microbo' to held is not set"):
            ev.wait_ev(held)
        assert time.monotonic() - t0 < 0.5
        # start_ev across the bus starts it; stop_ev ends it where it is with the program's code
        ev.start_ev(5, held)
        assert ev.wait_ev(held, started=True, timeout=5.0) == 5
        ev.stop_ev(-9, held)
        assert ev.wait_ev(held, timeout=5.0) == -9
        ev.free_ev(held)
        with pytest.raises(UnknownEvent, match="freed"):
            ev.status_ev(held)
        # what the arm's process refuses comes back as the same error class, named
        with pytest.raises(MotionError, match="arm 'puma'"):
            ev.move_ev(puma, _waist(puma, 40.0, "far_out"))

        # the PUMA's process is killed while its motion runs and the Microbo's waits for it
        a = ev.move_ev(puma, _waist(puma, 0.5, "long_way"))
        b = ev.move_ev(mic, _waist(mic, -0.1, "after_a"), start=a)
        ev.wait_ev(a, started=True, timeout=5.0)
        time.sleep(0.2)
        os.kill(procs["puma"].pid, signal.SIGKILL)
        t_kill = time.monotonic()
        with pytest.raises(ArmLost, match="waits for motion .* 'puma'.* left the bus"):
            ev.wait_ev(b, timeout=10.0)
        detected = time.monotonic() - t_kill
        assert detected < 1.0, f"the planning level learned of the lost arm after {detected:.3f} s"
        # the robot held the PUMA: its control ended, the joint is still
        state = sims["puma"].command("state")
        q1 = np.array(state["state"]["q"])
        time.sleep(0.3)
        q2 = np.array(sims["puma"].command("state")["state"]["q"])
        assert state["owner"] is None and np.max(np.abs(q2 - q1)) < 1e-4
        # a request to the lost arm is refused at once, not after a wait
        t0 = time.monotonic()
        with pytest.raises(ArmLost, match="'puma'"):
            ev.move_ev(puma, _waist(mic, 0.0, "anything"))
        assert time.monotonic() - t0 <= ev.request_timeout + 0.5
        # the Microbo's process is alive and still serves: its held motion is deleted by stop_abort
        ev.stop_abort(mic)
        assert ev.wait_ev(b, timeout=5.0) < 0
        mic.close()
        assert procs["microbo"].wait(10) == 0


def _kill(proc) -> None:
    if proc.poll() is None:
        proc.kill()
        proc.wait(5)
