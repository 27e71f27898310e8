"""RCCL programs that should run, or fail at once with a clear error (issue 13, item 6).

Against real lockstep simula processes: arm power (a move with power off is refused, power
coming back starts from where the brakes held the arm), ``waitfor`` on a position no motion
will reach, and bad arguments to ``rccl.open``, ``setconf`` and ``waitfor``.
"""
from __future__ import annotations

import time

import numpy as np
import pytest

import rccl
from rccl import EQ, T6, TL, Trsf, makeposition
from rccl.exceptions import BadRequest, PowerOff, TrajectoryFault
from rccl.position import joint_position
from rci.simula.process import SimulaProcess


def waist_turn(arm, delta: float, name: str):
    q = arm.q.copy()
    q[0] += delta
    return joint_position(name, arm.kinematics, q), q


def settle(arm, seconds: float = 0.3) -> np.ndarray:
    arm.rci.wait(seconds)
    return arm.measured_q()


def test_a_move_with_power_off_is_refused_and_power_on_makes_it_run():
    with SimulaProcess("-p", lockstep=True) as sim:          # simula starts with the arm's power off
        with rccl.open(sim.url, robot="puma260", timeout=2.0) as arm:
            assert not arm.powered
            p, q = waist_turn(arm, 0.3, "p")
            with pytest.raises(PowerOff, match=r"move\('p'\): the arm's power is off.*power_on\(\)"):
                arm.move(p)
            q0 = arm.measured_q()
            arm.power_on()
            assert arm.powered
            arm.move(p)
            arm.waitfor(p.end)
            assert np.allclose(settle(arm), q, atol=2e-3) and abs(arm.measured_q()[0] - q0[0]) > 0.29


@pytest.mark.parametrize("trajectory", ["quartic", "ruckig"])
def test_power_off_during_a_motion_ends_it_and_power_on_starts_from_where_the_brakes_held(trajectory):
    with SimulaProcess("-p", "--power-on", lockstep=True) as sim:
        with rccl.open(sim.url, robot="puma260", timeout=2.0, trajectory=trajectory) as arm:
            q0 = arm.measured_q()
            p, q = waist_turn(arm, 1.0, "far")
            arm.settime(0.2, 5.0)
            req = arm.move(p)
            assert arm.rci.wait(10, until=lambda: abs(arm.measured_q()[0] - q0[0]) > 0.1)
            arm.power_off()
            assert not arm.powered
            with pytest.raises(TrajectoryFault, match="power went off during the motion"):
                arm.waitfor(p.end)
            assert req.status == "failed" and isinstance(req.error.cause, PowerOff)
            held = settle(arm)
            assert 0.1 < abs(held[0] - q0[0]) < 0.9                  # stopped part way, where the brakes hold
            assert np.allclose(settle(arm), held, atol=1e-9)          # and stays there with power off
            arm.recover()                                             # the fault is acknowledged...
            with pytest.raises(PowerOff):
                arm.move(p)                                           # ...but moves wait for power
            arm.power_on()
            assert np.allclose(settle(arm, 0.5), held, atol=2e-3)     # no jump to where it had been sent
            # (p.end was signalled by the failed motion too, and that wait was cut short by the
            # fault: wait for the new request itself)
            arm.waitfor(arm.move(p))
            assert np.allclose(settle(arm), q, atol=2e-3)


def test_waitfor_a_position_no_motion_will_reach_raises_at_once():
    with SimulaProcess("-p", "--power-on", lockstep=True) as sim:
        with rccl.open(sim.url, robot="puma260", timeout=2.0) as arm:
            never, _ = waist_turn(arm, 0.2, "never")
            t0 = time.monotonic()
            with pytest.raises(BadRequest, match=r"waitfor\(never.end\): no motion to it is queued or running"):
                arm.waitfor(never.end)
            assert time.monotonic() - t0 < 0.5
            p, _ = waist_turn(arm, 0.2, "p")
            arm.move(p)
            arm.waitfor(p.end)                       # queued: waits, and returns when it ends
            with pytest.raises(BadRequest, match="would never come"):
                arm.waitfor(p.end)                   # that end was waited for already: nothing more will come
            arm.move(p)
            arm.rci.wait(until=lambda: not arm.gen.busy, seconds=10)
            arm.waitfor(p.end)                       # ended before the waitfor: returns at once (RCCL's counter)


def test_waitfor_timeout_names_the_event_and_bad_timeouts_are_refused():
    with SimulaProcess("-p", "--power-on", lockstep=True) as sim:
        with rccl.open(sim.url, robot="puma260", timeout=2.0) as arm:
            p, _ = waist_turn(arm, 0.5, "slow")
            arm.settime(0.2, 30.0)
            arm.move(p)
            with pytest.raises(TimeoutError, match=r"waitfor\(slow.end\): not signalled within 0.2 s"):
                arm.waitfor(p.end, timeout=0.2)
            for bad in (-1, "1", float("nan")):
                with pytest.raises(BadRequest, match="timeout="):
                    arm.waitfor(p.end, timeout=bad)
            arm.recover()


@pytest.mark.parametrize("kwargs, message", [
    ({"robot": "puma"}, r"robot='puma': no such robot; known: microbo, panda, puma260"),
    ({"timeout": -1}, r"timeout must be a number of seconds > 0 or None"),
    ({"rate_hz": 0}, r"rate_hz must be 4..1000"),
])
def test_bad_open_arguments_name_the_argument_and_the_choices(kwargs, message):
    with pytest.raises(ValueError, match=message):
        rccl.open("socket://127.0.0.1:9", **kwargs)       # refused before any connection is tried


def test_setconf_refuses_what_is_not_a_configuration():
    with SimulaProcess("-p", "--power-on", lockstep=True) as sim:
        with rccl.open(sim.url, robot="puma260", timeout=2.0) as arm:
            with pytest.raises(BadRequest, match=r"setconf\(123\): not a configuration of the puma260.*ArmConfig"):
                arm.setconf(123)
            with pytest.raises(BadRequest, match="'x' in 'xyz'"):
                arm.setconf("xyz")
            arm.setconf("ru")
            arm.setconf(None)
