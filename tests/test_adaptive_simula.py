"""rccl.adaptive against simula in an environment (separate process, lockstep): the examples are the tests.

The world truth (contact force, tool point) is computed on the test side from the joint
angles simula reports, with Pinocchio on the URDF and the same environment model.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

pin = pytest.importorskip("pinocchio")
EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
sys.path.insert(0, str(EXAMPLES))

from adaptive_sim import environment_simula          # noqa: E402
from rcci.models import load_robot               # noqa: E402
from rci.simula.environment import parse_environment  # noqa: E402

PUMA = load_robot("puma260")
PM = pin.buildModelFromUrdf(str(PUMA.urdf_path))
PD = PM.createData()


def tool_points(env_words, qs):
    env = parse_environment(list(env_words))
    return env, np.array([env.tool_point(PM, PD, q)[0] for q in qs])


def test_guarded_move_stops_within_two_samples_of_contact_force_passing_the_limit():
    import adaptive_guarded_move as g

    with environment_simula(*g.ENV) as sim:
        arm, r_down, r_up = g.main(sim.url)
    end = r_down.ended
    assert end is not None and end.reason == "limit" and end.what == "fz"
    assert end.value > g.LIMIT_N
    assert r_down.status == "done" and r_up.status == "done" and r_up.ended is None
    tr = arm.adaptive_trace
    q_meas = np.array([x[3] for x in tr])
    q_cmd = np.array([x[2] for x in tr])
    env, p_meas = tool_points(g.ENV, q_meas)
    _, p_cmd = tool_points(g.ENV, q_cmd)
    force = env.boxes[0].stiffness * np.maximum(0.0, g.TABLE_Z - p_meas[:, 2])   # true normal force
    k_cross = int(np.argmax(force > g.LIMIT_N))
    assert force[k_cross] > g.LIMIT_N and k_cross > 0
    going_down = np.diff(p_cmd[:, 2]) < -1e-7          # command k+1 still lower than command k
    k_stop = k_cross + int(np.argmin(going_down[k_cross:])) + 1
    assert k_stop - k_cross <= 2, (k_cross, k_stop, force[k_cross - 2:k_stop + 2])
    # and it went back up to where it started
    assert p_meas[-1, 2] == pytest.approx(p_meas[0, 2], abs=2e-4)


def test_compliant_edge_following_holds_the_force_and_a_deviation_limit_catches_the_slip():
    import adaptive_edge_follow as g
    from rccl.adaptive.force import ForceEstimator, JointModel
    from rccl.kinematics import puma260 as kin
    from rccl.transform import trsl

    with environment_simula(*g.ENV) as sim:
        arm, reqs, t_settled = g.main(sim.url)
    end = reqs["slide"].ended
    assert end is not None and (end.reason, end.what) == ("limit", "dz")
    assert reqs["home"].status == "done" and reqs["home"].ended is None
    tr = arm.adaptive_trace
    t = np.array([x[0] for x in tr])
    q_meas = np.array([x[3] for x in tr])
    env, p = tool_points(g.ENV, q_meas)
    joints = {j for x in tr for j in x[4]}
    assert len(joints) == 1                                     # one joint force-servoed for fz
    joint = joints.pop()
    force = env.boxes[0].stiffness * np.maximum(0.0, g.FACE_Z - p[:, 2])
    sliding = (t > t_settled + 0.5) & (p[:, 0] < g.EDGE_X - 0.003) & (t < end.t)
    assert sliding.sum() > 100                                  # > 2.8 s of sliding at 36 Hz
    # Table 4.4: the Coulomb variation of the force-servoed joint, through its lever (J^-T)
    model = JointModel.for_robot("puma260")
    err = np.where(np.arange(6) == joint, model.coulomb_uncertainty(), 0.0)
    q_mid = q_meas[np.flatnonzero(sliding)[len(np.flatnonzero(sliding)) // 2]]
    band = ForceEstimator(kin, model).force_bound(kin.jacobian6(q_mid), trsl(0, 0, g.PROBE), err)[2]
    mean = float(force[sliding].mean())
    assert abs(mean - g.FORCE_N) <= band, (mean, band)
    assert float(force[sliding].std()) < band
    # the non-compliant directions follow the path: y stays put, x advances along the face
    assert np.ptp(p[sliding, 1]) < 2e-4
    assert p[sliding, 0][-1] - p[sliding, 0][0] > 0.025
    # the slip: the probe went over the edge and fell before the limit ended the motion
    k_end = int(np.argmin(np.abs(t - end.t)))
    assert p[k_end, 0] > g.EDGE_X and p[k_end, 2] < g.FACE_Z - 0.005
    # never a jump: not at the slip, not at lock (the comply offset returns at a bounded speed)
    assert np.max(np.linalg.norm(np.diff(p, axis=0), axis=1)) < 3e-3
    # back home, every joint position servoed again
    assert not tr[-1][4]
    assert p[-1, 2] == pytest.approx(p[0, 2], abs=3e-4)


def test_circle_tracing_reproduces_figure_5_3(tmp_path):
    import adaptive_circle as g

    with environment_simula() as sim:
        arm, fn, r_p0, r_stop, r_park = g.main(sim.url)
    assert all(r.status == "done" for r in (r_p0, r_stop, r_park))
    t_a_end = r_p0.finished_t
    t_b_end = r_stop.finished_t
    # called once per sample while p0's motions ran (twice as often if called per equation/segment)
    span = (t_b_end - (t_a_end - g.APPROACH_M / g.APPROACH_SPEED)) * 36
    assert span - 60 <= fn.calls <= span + 60, (fn.calls, span)
    ts, xy = g.world_xy(arm)
    centre = np.array([0.20, -0.12])
    stopped = (ts > t_a_end + 1.0) & (ts < t_b_end - 0.5)
    r = np.linalg.norm(xy[stopped] - centre, axis=1)
    assert np.all(np.abs(r - g.RADIUS) < 1.5e-3), (r.min(), r.max())          # (b): the circle itself
    ang = np.unwrap(np.arctan2(*(xy[stopped] - centre).T[::-1]))
    assert abs(ang[-1] - ang[0]) > 2 * np.pi * 0.9                              # about a full turn
    approach = (ts < t_a_end) & (ts > t_a_end - g.APPROACH_M / g.APPROACH_SPEED + 1.0)
    off_line = np.abs(xy[approach, 1] - centre[1])
    assert off_line.max() > 0.8 * g.RADIUS                                     # (a): circle on the line
    # E.8 with acceleration: the 2 cm jump of the circle's first call, the moving target and the
    # exits from the modified segments (Figure 5.4) all keep every commanded joint within its limits
    from rccl.limits import load_limits
    lim = load_limits("puma260")
    q_cmd = np.array([x[1] for x in arm.adaptive_trace])
    acc = np.abs(np.diff(q_cmd, 2, axis=0)) * 36 ** 2
    assert np.max(acc / lim.joint_acceleration) <= 1.0
    assert arm.gen.functional.limited >= 1                # the first call's jump was spread out
    out = g.plot(arm, t_a_end, tmp_path / "fig53.png")
    assert out.stat().st_size > 10_000


def test_conveyor_tracking_follows_the_belt():
    import adaptive_conveyor as g

    with environment_simula(*g.ENV) as sim:
        arm, enc, track = g.main(sim.url)
    assert track.status == "done"
    ts, err = g.tracking_error(arm, track)
    assert len(ts) > 100
    # one sample of belt motion is 0.28 mm at 1 cm/s and 36 Hz; the encoder counts 0.1 mm
    assert err.mean() < 1.0e-3 and err.max() < 2.0e-3, (err.mean(), err.max())
    assert enc.travel() > 0.08                                      # the belt really moved


def test_evalfn_ends_a_motion_with_its_code_and_limits_hold_for_one_motion_only():
    import math

    import rccl.adaptive
    from rccl import EQ, T6, TL, Trsf, makeposition
    from rccl.adaptive.exceptions import MonitorError
    from rccl.exceptions import TrajectoryFault

    with environment_simula() as sim:
        with rccl.adaptive.open(sim.url, robot="puma260", record=True, timeout=2.0) as arm:
            x0 = arm.t6
            low, high = x0.copy(), x0.copy()
            low[2, 3] -= 0.06
            p_low = makeposition("LOW", T6, EQ, Trsf("LOW", low), TL, T6)
            p_high = makeposition("HIGH", T6, EQ, Trsf("HIGH", high), TL, T6)
            arm.setmod("cartesian")
            arm.setvel(0.03, math.radians(20))
            seen = []

            def below(s):
                seen.append(s.sample)
                z = arm.kinematics.fk(s.q)[2, 3]
                return "deep enough" if z < x0[2, 3] - 0.03 else None

            arm.evalfn(below)
            r1 = arm.move(p_low)
            r2 = arm.move(p_high)          # no monitor: the evalfn was for the previous motion only
            r3 = arm.move(p_low)
            arm.waitfor(r3)
            z_end_r1 = None
            for t, _, _, q, _ in arm.adaptive_trace:
                if abs(t - r1.finished_t) < 1e-9:
                    z_end_r1 = arm.kinematics.fk(q)[2, 3]
            end = r1.ended
            assert (end.reason, end.what, end.code) == ("monitor", "below", "deep enough")
            assert r2.ended is None and r3.ended is None
            assert np.all(np.diff(seen) == 1)                  # every sample, once
            assert z_end_r1 is not None and z_end_r1 > low[2, 3] + 0.02   # it did not go all the way
            assert abs(arm.measured_q() - arm.kinematics.module.ik(low, arm.kinematics.config_of(arm.q), arm.q)).max() < 1e-3

            def broken(s):
                raise RuntimeError("sensor unplugged")

            arm.evalfn(broken)
            r4 = arm.move(p_high)
            with pytest.raises(TrajectoryFault, match="broken raised RuntimeError: sensor unplugged"):
                arm.waitfor(r4, timeout=10)
            assert r4.status == "failed"
            with pytest.raises(MonitorError):
                arm.evalfn(42)


def test_conditional_motion_runs_on_contact_and_drops_the_rest_of_the_queue():
    import math

    import adaptive_guarded_move as g
    import rccl.adaptive
    from rccl import EQ, T6, TL, Trsf, makeposition
    from rccl.adaptive.exceptions import SpecError
    from rccl.events import START, move_ev, start_ev
    from rccl.transform import trsl

    with environment_simula(*g.ENV) as sim:
        with rccl.adaptive.open(sim.url, robot="puma260", record=True, timeout=2.0) as arm:
            tool = Trsf("PROBE", trsl(0.0, 0.0, g.PROBE))
            x0 = arm.t6 @ tool.matrix
            down, aside, back = x0.copy(), x0.copy(), x0.copy()
            down[2, 3] = g.TABLE_Z - 0.03
            aside[0, 3] += 0.03
            back[1, 3] += 0.02
            back[2, 3] += 0.01
            pos = {n: makeposition(n, T6, tool, EQ, Trsf(n, m), TL, tool)
                   for n, m in (("DOWN", down), ("ASIDE", aside), ("BACK", back))}
            arm.setmod("cartesian")
            arm.setvel(0.01, math.radians(10))
            arm.limit("fz", g.LIMIT_N)
            # DOWN waits for its start flag until the branch and the continuation are queued: a
            # lockstep simula runs faster than real time, so the contact could otherwise come
            # before this thread attaches the branch (cond then refuses: "has already ended")
            e_down = move_ev(arm, pos["DOWN"], start=None)
            r_down = e_down.request
            arm.setvel(0.03, math.radians(20))
            r_back = arm.cond("fz", pos["BACK"])          # on contact: back off up and sideways
            r_aside = arm.move(pos["ASIDE"])              # the normal continuation: dropped on contact
            with pytest.raises(SpecError, match="conditional"):
                arm.last = r_back
                arm.cond("fz", pos["ASIDE"])              # the tree stays pruned
            arm.last = r_aside
            start_ev(START, e_down)
            arm.waitfor(r_down)
            assert r_down.ended.what == "fz" and r_down.chosen is r_back
            arm.waitfor(r_back, timeout=30)
            assert r_aside.status == "failed" and "conditional motion to BACK" in str(r_aside.error)
            assert r_back.status == "done"
        q = arm.measured_q()
    p = tool_points(g.ENV, [q])[1][0]
    np.testing.assert_allclose(p, back[:3, 3], atol=3e-4)
