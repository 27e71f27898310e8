"""RCCL against simula in lockstep (a separate process over a socket): the whole stack, end to end.

The controller side uses the generated kinematics; the tool path is measured on the world
side with Pinocchio on the URDF from the joint angles simula reports in ``how``.
"""
from __future__ import annotations

import time
import warnings

import numpy as np
import pytest

import rccl
from rccl import EQ, T6, TL, Trsf, makeposition
from rccl.exceptions import SingularPath, UnreachableTarget
from rccl.limits import load_limits
from rccl.plots import line_deviation, pinocchio_fk
from rccl.transform import rot, trsl

SimulaProcess = pytest.importorskip("rci.simula.process").SimulaProcess

START = np.radians([0.0, 80.0, -170.0, 10.0, -60.0, 0.0])   # well away from singularities
LIM = load_limits("puma260")


@pytest.fixture(scope="module")
def sim():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # Python kinematics when the C kernels are not built
        with SimulaProcess("-p", "--power-on", lockstep=True) as s:
            yield s


@pytest.fixture(scope="module")
def world():
    return pinocchio_fk("puma260")


def open_arm(sim, rate_hz: int = 36):
    return rccl.open(sim.url, robot="puma260", rate_hz=rate_hz, record=True, on_error="raise", timeout=2.0)


def go_start(arm):
    arm.setmod("joint")
    arm.setvel(0.2, 2.0)
    start = makeposition("start", T6, EQ, Trsf("S", arm.kinematics.fk(START)), TL, T6)
    arm.move(start)
    arm.waitfor(start.end)
    return arm.t6


def tail(arm, n0):
    tr = arm.trace[n0:]
    return np.array([x[0] for x in tr]), np.array([x[1] for x in tr]), np.array([x[2] for x in tr])


def test_cartesian_straight_line_within_a_tenth_of_a_millimetre_at_36_hz(sim, world):
    with open_arm(sim, 36) as arm:
        base = go_start(arm)
        goal = trsl(-0.06, 0.05, 0.03) @ base @ rot("z", 0.3)
        p = makeposition("p", T6, EQ, Trsf("P", goal), TL, T6)
        arm.setmod("cartesian")
        arm.setvel(0.1, 1.0)
        n0 = len(arm.trace)
        arm.move(p)
        arm.waitfor(p.end)
        arm.rci.wait(0.3)
    _, qc, qm = tail(arm, n0)
    a, b = base[:3, 3], goal[:3, 3]
    for q, what in ((qc, "commanded"), (qm, "measured")):
        pts = np.array([world(x)[:3, 3] for x in q])
        dev = line_deviation(pts, a, b)
        assert dev.max() <= 1e-4, f"{what} path deviates {dev.max() * 1e3:.4f} mm from the line"
        assert np.linalg.norm(pts[-1] - b) <= 1e-4, f"{what} end point misses by {np.linalg.norm(pts[-1] - b) * 1e3} mm"
    assert len(qm) > 20


def test_transitions_keep_velocity_and_acceleration_continuous(sim):
    with open_arm(sim, 36) as arm:
        base = go_start(arm)
        arm.setmod("cartesian")
        arm.setvel(0.12, 1.2)
        ps = [makeposition(f"p{i}", T6, EQ, Trsf(f"P{i}", o @ base), TL, T6) for i, o in enumerate(
            [trsl(-0.05, 0.0, 0.0), trsl(-0.05, 0.05, 0.0), trsl(0.0, 0.05, 0.02) @ rot("x", 0.2)])]
        n0 = len(arm.trace)
        for p in ps:
            arm.move(p)
        arm.waitfor(ps[-1].end)
    t, qc, _ = tail(arm, n0)
    dt = float(np.median(np.diff(t)))
    v = np.diff(qc, axis=0) / dt
    acc = np.diff(v, axis=0) / dt
    assert np.all(np.abs(np.diff(v, axis=0)) <= LIM.joint_acceleration * dt * 1.05)
    assert np.all(np.abs(v) <= LIM.joint_velocity)
    assert np.max(np.abs(np.diff(acc, axis=0)) / LIM.joint_acceleration) < 0.7


def test_waitfor_order_queue_and_hold(sim):
    with open_arm(sim, 72) as arm:
        base = go_start(arm)
        pa = makeposition("pa", T6, EQ, Trsf("A", trsl(0.03, 0.0, 0.0) @ base), TL, T6)
        pb = makeposition("pb", T6, EQ, Trsf("B", trsl(0.03, 0.03, 0.0) @ base), TL, T6)
        ra, rb = arm.move(pa), arm.move(pb)
        arm.waitfor(pa.end)
        assert ra.status == "done" and rb.status == "running"   # a is done, b is under way
        arm.waitfor(pb.end)
        assert rb.status == "done"
        q_end = arm.measured_q()
        arm.rci.wait(0.5)                                        # empty queue: the arm holds
        assert np.allclose(arm.measured_q(), q_end, atol=2e-4)
        assert np.allclose(arm.t6, pb.solve(), atol=1e-9)


def test_joint_mode_interpolates_in_joint_space(sim):
    with open_arm(sim, 36) as arm:
        go_start(arm)
        q_goal = START + np.radians([15.0, -10.0, 10.0, -20.0, 15.0, 30.0])
        p = makeposition("pj", T6, EQ, Trsf("J", arm.kinematics.fk(q_goal)), TL, T6)
        arm.setmod("joint")
        arm.setvel(0.1, 1.0)
        n0 = len(arm.trace)
        arm.move(p)
        arm.waitfor(p.end)
        arm.rci.wait(0.3)
    _, qc, qm = tail(arm, n0)
    d = q_goal - START
    r = qc - START
    assert np.max(np.abs(r - np.outer(r @ d / (d @ d), d))) < 1e-9
    assert np.allclose(qm[-1], q_goal, atol=3e-4)


def test_errors_refused_before_motion_and_the_session_goes_on(sim):
    with open_arm(sim, 36) as arm:
        base = go_start(arm)
        q_before = arm.measured_q()
        far = makeposition("far", T6, EQ, Trsf("F", trsl(0.4, 0.4, 0.4) @ base), TL, T6)
        with pytest.raises(UnreachableTarget, match="far"):
            arm.move(far)
        q_flip = START.copy()
        q_flip[3], q_flip[4] = 0.0, 0.3   # the other side of the wrist singularity theta5 = 0
        q_here = START.copy()
        q_here[3], q_here[4] = 0.0, -0.3
        arm.setmod("joint")
        here = makeposition("here", T6, EQ, Trsf("H", arm.kinematics.fk(q_here)), TL, T6)
        arm.move(here)
        arm.waitfor(here.end)
        arm.setmod("cartesian")
        with pytest.raises(SingularPath, match="singularity"):
            arm.move(makeposition("flip", T6, EQ, Trsf("FL", arm.kinematics.fk(q_flip)), TL, T6))
        assert len(arm.queue) == 0
        arm.setmod("joint")
        back = makeposition("back", T6, EQ, Trsf("BK", arm.kinematics.fk(q_before)), TL, T6)
        arm.move(back)
        arm.waitfor(back.end)
        arm.rci.wait(0.2)
        assert np.allclose(arm.measured_q(), q_before, atol=3e-4)


def test_program_534_runs(sim):
    import importlib.util
    from pathlib import Path
    path = Path(__file__).resolve().parent.parent / "examples" / "rccl_program_534.py"
    spec = importlib.util.spec_from_file_location("rccl_program_534", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    t0 = time.monotonic()
    arm = mod.main(sim.url, record=True)
    assert time.monotonic() - t0 < 120
    qm = np.array([x[2] for x in arm.trace])
    # it went to p0 (T6 = T^-1 B) and came back to park
    p0 = mod.P0_T6
    fk = arm.kinematics.fk
    assert min(np.linalg.norm(fk(q)[:3, 3] - p0[:3, 3]) for q in qm) < 0.02
    assert np.allclose(fk(qm[-1])[:3, 3], arm.park.solve()[:3, 3], atol=2e-4)


def test_primitives_after_close_are_refused(sim):
    arm = open_arm(sim, 36)
    p = arm.park
    arm.close()
    with pytest.raises(rccl.NotRunning, match="not running"):
        arm.move(p)


def test_the_demo_plots_are_written_and_the_line_is_straight(tmp_path, capsys):
    """``python -m rccl.plots`` (run by make demo): its own lockstep simula, both figures, the line's figures."""
    import re

    from rccl import plots

    assert plots.main(["--out", str(tmp_path)]) == 0
    for name in ("rccl-path.png", "rccl-transition.png"):
        assert (tmp_path / name).stat().st_size > 10_000
    line = capsys.readouterr().out.strip().splitlines()[-1]
    measured = float(re.search(r"measured ([0-9.]+) mm", line).group(1))
    assert measured < 0.1, line
