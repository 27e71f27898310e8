"""RCCL's joint speed limit and RCI's R_REQVEL check agree (issue 13, item 6).

The generator plans with the data file's joint speeds less what rounding the commands to
whole encoder counts can add to a step (rccl.limits.for_link), so a move at full joint
speed runs to its end at every sample rate instead of tripping R_REQVEL by a count.
"""
from __future__ import annotations

import numpy as np
import pytest

import rccl
from rccl import EQ, T6, TL, Trsf, makeposition
from rccl.limits import for_link, load_limits
from rci.conversions import Conversions
from rci.simula.process import SimulaProcess

CONV = Conversions.for_robot("puma260")
LIM = load_limits("puma260")


def test_rounding_step_is_one_count_through_the_coupling():
    r = CONV.rounding_step()
    one_count = np.abs(CONV.counts_to_angles(np.eye(6) + CONV.encoder_offset)).sum(axis=0)
    assert np.allclose(r, one_count)              # sum over motors of one count each, per joint
    assert np.all(r > 0) and np.all(r < 1e-3)


def test_for_link_lowers_each_speed_by_a_count_per_period():
    at_1khz = for_link(LIM, CONV.rounding_step(), 1e-3)
    assert np.allclose(LIM.joint_velocity - at_1khz.joint_velocity, CONV.rounding_step() / 1e-3)
    with pytest.raises(ValueError, match="leaves no joint speed"):
        for_link(LIM, CONV.rounding_step(), 1e-6)


@pytest.mark.parametrize("rate_hz", [36, 250, 1000])
def test_a_move_at_full_joint_speed_runs_to_its_end(rate_hz):
    with SimulaProcess("-p", "--power-on", lockstep=True) as sim:
        with rccl.open(sim.url, robot="puma260", rate_hz=rate_hz, record=True, timeout=2.0) as arm:
            arm.setmod("joint")
            arm.setvel(100.0, 100.0)                 # far above every joint's speed: the joints limit it
            q = arm.q.copy()
            q[0] += 2.5
            q[3] += 2.0
            p = makeposition("P", T6, EQ, Trsf("G", arm.kinematics.fk(q)), TL, T6)
            arm.move(p)
            arm.waitfor(p.end)
            assert arm.gen.slowed == 0
            reached = arm.measured_q()
    assert np.allclose(reached, q, atol=1e-3)
    counts = CONV.angles_to_counts_int(np.array([c for _, c, _ in arm.trace]))
    speed = np.abs(np.diff(CONV.counts_to_angles(counts.astype(float)), axis=0)).max(axis=0) * rate_hz
    assert np.all(speed <= LIM.joint_velocity)                     # what R_REQVEL checks, in counts
    assert speed[0] > LIM.joint_velocity[0] - 2 * CONV.rounding_step()[0] * rate_hz   # and it did run at full speed
