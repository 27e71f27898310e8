"""RCCL on the Franka Emika Panda (7 joints, issue 28 item 1) against ``simula --robot panda`` in lockstep.

A joint-mode program moves the redundant arm through joint-defined positions
(``rccl.position.joint_position``: the targets carry their joints, so no inverse kinematics is
needed) and the encoders must reach each target. The world side is simula's Pinocchio model
of models/urdf/panda.urdf; the generated kinematics (rccl.kinematics.panda) give the tool
frame T7. The Panda's closed-form inverse needs the free value q7: a Cartesian target is
reached with q7 held by the default rule (docs/redundancy.md). An RCI recorder logs the Panda's
seven encoders; one made for six joints is refused before it could drop a cycle.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from rcci.models import load_robot
from rccl import EQ, T6, TL, Trsf, makeposition
from rccl.position import joint_position
from rccl.plots import pinocchio_fk

from rccl_arm import lockstep_simula, open_arm, tail

MODEL = load_robot("panda")
READY = MODEL.poses["ready"]
#: joint targets (rad) around the ready pose, every joint moved, inside the Franka ranges
TARGETS = {
    "A": READY + np.radians([30.0, 15.0, -20.0, 25.0, 30.0, -20.0, 40.0]),
    "B": READY + np.radians([-40.0, -10.0, 25.0, -20.0, -35.0, 25.0, -60.0]),
}


@pytest.fixture(scope="module")
def sim():
    yield from lockstep_simula("panda")


def test_targets_inside_the_ranges():
    for name, q in TARGETS.items():
        assert MODEL.within_limits(q), name


def test_joint_mode_program_reaches_its_targets(sim):
    world = pinocchio_fk("panda")
    with open_arm(sim, "panda") as arm:
        assert arm.rci.nj == 7
        arm.setmod("joint")
        arm.setvel(0.2, math.radians(60.0))
        n0 = len(arm.trace)
        for name, q in TARGETS.items():
            pos = joint_position(name, arm.kinematics, q)
            arm.move(pos)
            arm.waitfor(pos.end)
            arm.rci.wait(0.3)                                  # let the servos settle
            q_meas = arm.measured_q()
            assert q_meas.shape == (7,)
            assert np.abs(q_meas - q).max() < 2e-3, (name, q_meas - q)
            # the tool frame where the generated kinematics and simula's Pinocchio model put it
            t7 = arm.kinematics.fk(q_meas)
            assert np.allclose(t7, world(q_meas), atol=1e-9)
            assert np.linalg.norm(t7[:3, 3] - arm.kinematics.fk(q)[:3, 3]) < 2e-3
        cmd, meas = tail(arm, n0)
        assert cmd.shape[1] == 7 and len(cmd) > 36
        assert np.all(cmd >= MODEL.lower - 1e-9) and np.all(cmd <= MODEL.upper + 1e-9)
        arm.move(arm.park)
        arm.waitfor(arm.park.end)
        arm.rci.wait(0.3)
        assert np.abs(arm.measured_q() - MODEL.poses["ready"]).max() < 2e-3


def test_a_move_to_a_pose_holds_q7_by_default(sim):
    """A joint-mode move to a Cartesian target: the inverse kinematics needs q7, and RCCL's
    default rule for the free parameter (rccl.redundancy, docs/redundancy.md) holds the q7 the
    arm has; the target is reached with it."""
    with open_arm(sim, "panda") as arm:
        arm.setmod("joint")
        q7 = float(arm.q[6])
        t7 = arm.kinematics.fk(TARGETS["A"])
        pos = makeposition("P", T6, EQ, Trsf("P", t7), TL, T6)
        arm.move(pos)
        arm.waitfor(pos.end)
        assert arm.q[6] == q7
        assert np.allclose(arm.kinematics.fk(arm.q), t7, atol=1e-9)


def test_the_example_reaches_its_targets(sim, capsys):
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parent.parent / "examples" / "panda.py"
    spec = importlib.util.spec_from_file_location("example_panda", path)
    ex = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(ex)
    reached = ex.run(sim.url, timeout=2.0)
    assert list(reached) == list(ex.TARGETS)
    for name, (error, q) in reached.items():
        assert error < 2e-3 and MODEL.within_limits(q), (name, error)
    out = capsys.readouterr().out
    assert all(f"{name}: joints" in out for name in ex.TARGETS)


def test_the_recorder_logs_seven_joints_and_refuses_a_six_joint_one(sim, tmp_path):
    """rci.recorder on a 7-joint arm: Recorder(nj=7) logs every cycle's seven encoder counts; a
    six-joint recorder is refused by Session.record with the count to use (it would have failed
    in the control cycle, ending the control)."""
    from rci.recorder import Recorder, read_log

    with open_arm(sim, "panda") as arm:
        with pytest.raises(ValueError, match="holds 6 joints, the panda has 7: make it with Recorder"):
            arm.rci.record(Recorder(tmp_path / "six.rcilog", robot="panda"))
        rec = Recorder(tmp_path / "seven.rcilog", robot="panda", nj=7)
        arm.rci.record(rec)
        arm.setmod("joint")
        arm.setvel(0.2, math.radians(60.0))
        p = joint_position("A", arm.kinematics, TARGETS["A"])
        arm.move(p)
        arm.waitfor(p.end)
        arm.rci.record(None)
        rec.close()
    log = read_log(tmp_path / "seven.rcilog")
    assert len(log) > 10 and log.records["how_pos"].shape[1] == 7
    assert len(np.unique(log.records["how_pos"][:, 6])) > 1      # joint 7 moved and was logged
