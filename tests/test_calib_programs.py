"""The measurement plans: paths that do what the thesis's experiments need."""
from __future__ import annotations

import numpy as np
import pytest

from rcci.calib.experiments import (FRICTION_POSES, friction_plans, gravity_plans,
                               sensitivity_plans, static_plan)
from rcci.calib.robot import robot_info
from rcci.calib.work import find_passes

INFO = robot_info("puma260")


@pytest.mark.parametrize("joint", sorted(FRICTION_POSES))
def test_friction_window_has_no_potential_energy_change(joint):
    plan = friction_plans([joint])[0]
    lo, hi = plan.meta["window"]
    q = np.array(plan.meta["pose"])
    # gravity work over the window must vanish whatever the coefficients: every
    # regressor column integrates to zero
    th = np.linspace(lo, hi, 401)
    rows = []
    for x in th:
        qq = q.copy()
        qq[joint - 1] = x
        rows.append(INFO.regressor(qq)[joint - 1])
    integral = np.trapezoid(np.array(rows), th, axis=0)
    assert np.abs(integral).max() < 1e-9


@pytest.mark.parametrize("joint", [1, 2])
def test_friction_path_cruises_through_the_window_at_each_speed(joint):
    for plan in friction_plans([joint]):
        lo, hi = plan.meta["window"]
        s = plan.path.sample(36.0)
        assert INFO.lower[joint - 1] <= s[:, joint - 1].min()
        assert s[:, joint - 1].max() <= INFO.upper[joint - 1]
        passes = find_passes(s[:, joint - 1], lo, hi)
        expected = [v for v, n in zip(plan.meta["speeds"], plan.meta["trips"]) for _ in range(2 * n)]
        assert len(passes) == len(expected), plan.name
        for p, v in zip(passes, expected):
            speed = np.abs(np.diff(s[p.first:p.last + 1, joint - 1])) * 36.0
            assert speed == pytest.approx(v, rel=1e-6)


def test_fast_passes_of_joints_2_to_6_are_read_at_every_servo_tick():
    """The fast passes go to a log read at 1 kHz; together the two logs of a joint
    cover every speed, each once, and both use the same window."""
    for j in (2, 3, 4, 5, 6):
        slow, fast = friction_plans([j])
        assert (slow.name, slow.rate_hz) == (f"friction-j{j}", 72)
        assert (fast.name, fast.rate_hz) == (f"friction-j{j}-servo", 1000)
        assert slow.meta["window"] == fast.meta["window"]
        assert max(slow.meta["speeds"]) < min(fast.meta["speeds"])
        assert len(fast.meta["trips"]) == len(fast.meta["speeds"])
    assert [p.rate_hz for p in friction_plans([1])] == [72]


def test_friction_sweeps_turn_without_halting():
    """A joint standing at the turns cools (4.5.3) and would read higher friction on
    the fast passes, where the turns are a larger share of the time."""
    for plan in friction_plans([5]):
        lo, hi = plan.meta["window"]
        sweeps = [seg for seg in plan.path.segments if seg.distance > hi - lo]
        assert len(sweeps) == 2 * sum(plan.meta["trips"])
        assert all(seg.dwell == 0.0 for seg in sweeps)
        assert plan.warmup.duration >= 200.0


def test_every_plan_stays_within_the_joint_ranges():
    plans = (friction_plans() + sensitivity_plans(None, 0.05)
             + gravity_plans(INFO.regressor, INFO.lower, INFO.upper)
             + [static_plan(INFO.lower, INFO.upper)])
    for plan in plans:
        s = plan.path.sample(36.0)
        inside = 0.5 * np.pi / 180  # the controller's range check allows no rounding slack
        assert (s >= INFO.lower + inside).all() and (s <= INFO.upper - inside).all(), plan.name


def test_gravity_repeats_do_equal_gravity_work_in_both_segments():
    plans = gravity_plans(INFO.regressor, INFO.lower, INFO.upper)
    repeats = [p for p in plans if p.meta["role"] == "repeat"]
    assert {p.meta["position"] for p in repeats} == {"j5", "j4", "j3A", "j3B"}
    for p in repeats:
        q0 = np.array(p.meta["q_start"])
        j = p.meta["joint"] - 1
        q0[j] = p.meta["phi_low"]
        assert np.abs(INFO.regressor(q0)[j]).max() < 1e-9, p.name


def test_static_plan_has_275_halts():
    plan = static_plan(INFO.lower, INFO.upper)
    dwells = [s for s in plan.path.segments if s.dwell > 0]
    assert len(dwells) == 275


def test_program_records_exactly_the_path_over_a_real_link(tmp_path):
    """run_plan against the reference robot-side monitor (lockstep, TCP): the log holds
    the path (not the approach), in order, with the plan's metadata."""
    import threading
    import time

    from rcci.calib.logs import load_trace
    from rcci.calib.program import run_plan
    from rci.conversions import Conversions
    from robot_monitor import EchoArm, Monitor

    conv = Conversions.for_robot("puma260")
    (plan,) = friction_plans([1], speeds_deg=(30, 60), trips=1)
    plan.warmup = None
    mon = Monitor(EchoArm(pos0=conv.angles_to_counts(np.full(6, 0.3))), lockstep=True)
    port: list[int] = []

    def serve() -> None:
        try:
            mon.serve_tcp(ready=port.append)
        except BrokenPipeError:  # the monitor answers BYE after the client has gone
            pass

    threading.Thread(target=serve, daemon=True).start()
    deadline = time.monotonic() + 5
    while not port and time.monotonic() < deadline:
        time.sleep(0.01)
    try:
        run = run_plan(f"socket://127.0.0.1:{port[0]}", plan, str(tmp_path / "f.rcilog"))
    finally:
        mon.stop_event.set()
    tr = load_trace(run.path)
    assert tr.meta["experiment"] == "friction" and tr.meta["joint"] == 1
    q = conv.counts_to_angles(tr.counts)
    setpoints = plan.path.sample(36.0)
    # EchoArm reaches each POS target in the cycle after it was sent
    n = min(len(q), len(setpoints)) - 1
    assert np.abs(q[1:n, 0] - setpoints[:n - 1, 0]).max() < 1e-3
    assert len(find_passes(q[:, 0], *plan.meta["window"])) == 4
    assert tr.t[1] - tr.t[0] == pytest.approx(1 / 36.0)


def test_friction_program_on_simula_fits_the_simulated_joint(tmp_path):
    """A short friction program on a real simula process (lockstep, warm joints): the
    recorded log fits to the simulator's Coulomb friction within Table 4.2's bounds."""
    from rcci.calib.fitting import run_fit
    from rcci.calib.logs import load_trace
    from rcci.calib.program import run_plan
    from rci.simula.process import SimulaProcess

    (plan,) = friction_plans([6], speeds_deg=(30, 60, 90), trips=1)
    plan.warmup = None
    with SimulaProcess("-p", "--warm", lockstep=True, seed=7) as sim:
        run = run_plan(sim.url, plan, str(tmp_path / "f6.rcilog"))
    assert run.records > 100
    # this simula runs on the data file, so its torque sensitivities are Table 4.1's: the one
    # case where assuming them is right, and the fit says it assumed them
    out = run_fit("friction", [load_trace(run.path)], INFO, None, assume_datafile=True)
    assert out.assumed and "Table 4.1" in out.assumed[0]
    (r,) = out.results
    fr = INFO.nominal["friction"]
    assert abs(r.plus.coulomb - fr["coulomb_pos"]["values"][5]) <= fr["coulomb_pos"]["uncertainty"][5]
    assert abs(r.minus.coulomb - fr["coulomb_neg"]["values"][5]) <= fr["coulomb_neg"]["uncertainty"][5]


def test_program_error_names_the_program_and_keeps_the_partial_log(tmp_path):
    """A robot that cannot be reached: the error says which program and where."""
    from rcci.calib.exceptions import CalibError
    from rcci.calib.program import run_plan

    (plan,) = friction_plans([1], speeds_deg=(30,), trips=1)
    with pytest.raises(CalibError, match=r"friction-j1 on socket://127.0.0.1:9"):
        run_plan("socket://127.0.0.1:9", plan, str(tmp_path / "x.rcilog"))


@pytest.mark.slow
def test_regen_logs_records_gravity_logs_that_fit(tmp_path):
    """`calib regen-logs --kinds gravity` end to end (a few minutes: -m slow)."""
    from rcci.calib.__main__ import main

    assert main(["regen-logs", "--kinds", "gravity", "--out", str(tmp_path)]) == 0
    logs = sorted(str(p) for p in tmp_path.glob("gravity-*.rcilog.xz"))
    assert len(logs) == 10
    # recorded against the data file's simula, so Table 4.1's sensitivities are its own
    assert main(["fit", "gravity", *logs, "-q", "--assume-datafile"]) == 0


def test_the_thesis_poses_are_checked_on_the_arm_they_are_given():
    """The PUMA 260's friction poses suit it (the same plans as the default's), and another
    arm's are not used where they do not serve it: on the PUMA 560 joint 1's window does not
    fit its +-160 deg (another pose is found), and joint 2's leaves gravity doing work (cy2, and cx3
    with its elbow offset a3), where no pose frees it: a window over which only those small terms
    work is chosen (the upper arm's weight, odd about upright, cancels) and marked gravity-loaded, so
    that the fit takes their mean off (rcci.calib.window_gravity)."""
    from rcci.calib.exceptions import CalibError
    from rcci.calib.experiments import check_friction_pose

    assert [p.name for p in friction_plans(robot=INFO)] == [p.name for p in friction_plans()]
    for mine, default in zip(friction_plans([2], robot=INFO), friction_plans([2])):
        np.testing.assert_array_equal(mine.path.sample(72), default.path.sample(72))
    other = robot_info("puma560")
    # joint 1's thesis window does not fit its +-160 deg: rcci.calib.friction_poses finds one that does
    (plan,) = friction_plans([1], robot=other)
    lo, hi = plan.meta["window"]
    assert other.lower[0] < lo < hi < other.upper[0] and hi - lo >= np.radians(200)
    check_friction_pose(other, 1, lo, hi, np.array(plan.meta["pose"]))
    j2 = friction_plans([2], robot=other)[0]
    lo, hi = j2.meta["window"]
    assert j2.meta["gravity_loaded"] and other.lower[1] < lo < hi < other.upper[1]
    assert "gravity_loaded" not in plan.meta
    qdeg, half = FRICTION_POSES[2]
    q = np.radians(qdeg)
    with pytest.raises(CalibError, match=r"robot puma560: gravity does work on joint 2 .*through cy2, cx3"):
        check_friction_pose(other, 2, q[1] - np.radians(half), q[1] + np.radians(half), q)


@pytest.mark.parametrize("robot", ["puma260", "puma560", "stanford", "microbo"])
def test_every_friction_plan_has_passes(robot):
    """A joint whose top speed stays under its servo-rate threshold (the PUMA 560's joint 4: 52 of
    200 deg/s) gets no empty `friction-jN-servo` plan (its path of no segments stopped the PUMA 560
    campaign with an IndexError), and each log set names only the logs planned."""
    from rcci.calib.exceptions import CalibError

    info = robot_info(robot)
    for j in range(1, len(info.lower) + 1):
        try:
            plans = friction_plans([j], robot=info)
        except CalibError:
            continue                                   # refused with its reason (Microbo 2-3)
        names = [p.name for p in plans]
        for p in plans:
            assert p.path.segments and p.meta["speeds"] and len(p.path.sample(p.rate_hz)) > 1, p.name
            assert p.meta["log_set"] == names
