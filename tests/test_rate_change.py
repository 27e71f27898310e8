"""The timing contract of a rate change, on a real simula process (docs/protocol.md, "Timing: one cycle").

A HOW's ``rate_hz`` is the rate at which the robot executes the CHG answering it: the
period from that HOW to the next. A CHG that commands a new rate runs at the old rate, and
the very next HOW carries the new rate and begins the first period at it. Checked here
through 36 -> 250 -> 1000 Hz against simula's simulated clock (``how.time_ns``), in
lockstep and in real time, with a joint moving at 40 % of its speed limit throughout (the
velocity check must measure each step over the period it really took).
"""
from __future__ import annotations

import numpy as np
import pytest

from rci import codes, protocol
from rci.chg import POS, Chg
from rci.link import open_link
from rci.session import Session
from rci.simula.process import SimulaProcess

#: f1 call number -> the rate its CHG commands
SWITCH = {12: 250, 40: 1000}
CYCLES = 140
SPEED_SHARE = 0.4          # of joint 1's speed limit


def _drive(s: Session, log: list[dict]):
    """f1: log the cycle, command joint 1 along a ramp at SPEED_SHARE of its limit, switch rates."""
    lim = s.checker.limits
    state: dict = {}

    def f1() -> None:
        how = s.how
        if not state:
            c0 = int(how.pos[0])
            q0 = float(lim.counts_to_rad(how.pos)[0])
            probe = how.pos.copy()
            probe[0] += 1000
            counts_per_rad = 1000.0 / (float(lim.counts_to_rad(probe)[0]) - q0)
            toward_middle = 1.0 if q0 < 0.5 * (lim.lower[0] + lim.upper[0]) else -1.0
            state.update(target=float(c0), step_per_s=toward_middle * SPEED_SHARE * float(lim.max_velocity[0])
                         * counts_per_rad, n=0)
        state["n"] += 1
        task = s.control_task
        log.append({"n": state["n"], "cycle": how.cycle, "time_ns": how.time_ns, "rate": how.rate_hz,
                    "task_rate": s.rate_hz, "task_period": task.period, "pos": int(how.pos[0]),
                    "overruns": how.robot_overruns, "received": how.received, "commanded": None})
        # this CHG runs for one period at the rate of the HOW it answers
        state["target"] += state["step_per_s"] / how.rate_hz
        s.chg.motion[0].issue(POS, int(round(state["target"])))
        new = SWITCH.get(state["n"])
        if new is not None:
            s.chg.rate.issue(1, new)
            log[-1]["commanded"] = new
    return f1


def _run(lockstep: bool) -> tuple[list[dict], Session]:
    log: list[dict] = []
    with SimulaProcess("-p", "--power-on", lockstep=lockstep) as sim:
        with Session(sim.url, "puma260", rate_hz=36, on_error="raise", signals=False, lock_memory=False,
                     overrun="count", lockstep_timeout=2.0) as s:
            s.control(_drive(s, log))
            assert s.wait(20.0, until=lambda: len(log) >= CYCLES), f"only {len(log)} cycles"
            assert s.termination is None and s.in_control, s.termination
            s.release()
    return log, s


def _check_contract(log: list[dict], exact_next: bool) -> None:
    cycles = [r["cycle"] for r in log]
    assert cycles == list(range(cycles[0], cycles[0] + len(cycles))), "HOWs lost"
    for a, b in zip(log, log[1:]):
        spacing_ns = b["time_ns"] - a["time_ns"]
        # the period from a HOW to the next is the one the first announced (simulated time, ns)
        assert abs(spacing_ns - 1e9 / a["rate"]) <= 2, (a, b, spacing_ns)
    for r in log:
        assert r["task_rate"] == r["rate"] and r["task_period"] == pytest.approx(1.0 / r["rate"])
    rates = [r["rate"] for r in log]
    assert rates[0] == 36 and rates[-1] == 1000
    assert sorted(set(rates), key=rates.index) == [36, 250, 1000]
    for i, r in enumerate(log):
        if r["commanded"] is None:
            continue
        nxt = log[i + 1]
        assert r["rate"] != r["commanded"]          # the commanding CHG ran at the old rate ...
        if exact_next or nxt["overruns"] == r["overruns"]:
            assert nxt["rate"] == r["commanded"]      # ... and the next HOW carries the new one


def _joint_speed(log: list[dict]) -> np.ndarray:
    """Joint 1's speed between successive HOWs, counts per simulated second."""
    pos = np.array([r["pos"] for r in log], float)
    t = np.array([r["time_ns"] for r in log], float) * 1e-9
    return np.abs(np.diff(pos) / np.diff(t))


def test_rate_change_on_a_lockstep_simula_next_how_carries_the_new_rate():
    log, s = _run(lockstep=True)
    _check_contract(log, exact_next=True)
    assert s.timing.count >= CYCLES
    # the arm kept the commanded speed through both changes: no jump by the rate ratio
    speed = _joint_speed(log)[5:]
    steady = np.median(speed)
    assert steady > 0 and np.all(speed < 1.5 * steady), (speed.max(), steady)


def test_rate_change_on_a_real_time_simula_next_how_carries_the_new_rate():
    log, _ = _run(lockstep=False)
    _check_contract(log, exact_next=False)
    # wall clock: the HOWs of each rate come a period of that rate apart (median, under load)
    for rate in (250, 1000):
        seg = [r for r in log if r["rate"] == rate]
        gaps = np.diff([r["received"] for r in seg])
        assert abs(np.median(gaps) - 1.0 / rate) < 0.3 / rate, (rate, np.median(gaps))


def _raw_how(link) -> "protocol.Frame":
    f = link.recv(5.0)
    assert f is not None and f.type == protocol.HOW, f
    return f


def test_simula_reads_the_rate_command_from_the_chg_itself():
    """On the raw protocol (no rci control task): a rate command answers its HOW at the old
    rate and the next HOW carries it; a stale CHG's rate is not executed; a value that is no
    rate is status 4 in the next HOW; START takes Hz only (a thesis code is refused)."""
    with SimulaProcess("-p", "--power-on", lockstep=True) as sim:
        link = open_link(sim.url)
        try:
            link.send(protocol.HELLO, 0, protocol.Hello("puma260", 36, "test").encode())
            assert link.recv(10.0).type == protocol.WELCOME
            link.send(protocol.START, 1, protocol.Start(1).encode())          # code 1 is not a rate in Hz
            f = link.recv(5.0)
            assert f.type == protocol.ERROR and "START rate_hz must be 4..1000 Hz" in protocol.ErrorMsg.decode(f.payload).text
            link.send(protocol.START, 2, protocol.Start(36).encode())
            f0 = _raw_how(link)
            h0 = protocol.decode_how(f0.payload, f0.seq)
            chg = Chg()
            chg.rate.issue(1, 0)                       # thesis code 0: 72 Hz
            link.send(protocol.CHG, f0.seq, protocol.encode_chg(chg))
            f1 = _raw_how(link)
            h1 = protocol.decode_how(f1.payload, f1.seq)
            assert (h0.rate_hz, h1.rate_hz) == (36, 72)
            assert h1.time_ns - h0.time_ns == pytest.approx(1e9 / 36, abs=2)   # CHG(n) ran at 36 Hz
            stale = Chg()
            stale.rate.issue(1, 500)
            link.send(protocol.CHG, f0.seq, protocol.encode_chg(stale))      # for an old cycle: ignored
            link.send(protocol.CHG, f1.seq, protocol.encode_chg(Chg()))
            f2 = _raw_how(link)
            h2 = protocol.decode_how(f2.payload, f2.seq)
            assert h2.rate_hz == 72 and h2.time_ns - h1.time_ns == pytest.approx(1e9 / 72, abs=2)
            bad = Chg()
            bad.rate.issue(1, 5000)
            link.send(protocol.CHG, f2.seq, protocol.encode_chg(bad))
            f3 = _raw_how(link)
            h3 = protocol.decode_how(f3.payload, f3.seq)
            assert h3.status == codes.ST_BAD_COMMAND and h3.rate_hz == 72
            end = Chg()
            end.end.com = 1
            link.send(protocol.CHG, f3.seq, protocol.encode_chg(end))
        finally:
            link.close()
