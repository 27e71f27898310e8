"""Free-air force estimates on every shipped arm (issue 25, defect 5; thesis 4.37, 4.56, 6.2).

Each arm runs on its own lockstep ``simula --robot ROBOT -p --power-on`` (the defaults a user
gets: cold joints, ADC noise, servo ripple, static friction drawn at every halt). From the
control's first sample (where the issue's 8 N limit tripped, t = 0.028 s) its 5 cm probe
goes 3 cm along its axis at 1 cm/s touching nothing, and a monitor reads the tool-frame
force estimate every sample. The estimate must
stay within ``TRIP_BARS`` of its error bar (``ForceEstimator.error_bar``: the arm's data
file's friction through the Jacobian), and a force limit at or under that bar is refused
before the motion moves, one between one and ``TRIP_BARS`` bars is warned about, each with
the figure. The pure tests pin down the two sensor details the estimate now follows: a
joint whose count moved slid (kinetic friction), and the ADC's 15 ms filter.
"""
from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

import rccl.adaptive
import rccl.kinematics
from rcci.models import load_robot
from rccl import EQ, T6, TL, Trsf, makeposition
from rccl.exceptions import TrajectoryFault
from rccl.adaptive.force import ForceEstimator, JointModel, FILTER_TAU
from rccl.adaptive.limit import TRIP_BARS, ForceEstimateWarning, ForceLimitRefused, Limit
from rccl.transform import trsl

ROBOTS = ("puma260", "microbo", "puma560", "stanford")
PROBE = 0.05        # m along z6
DROP = 0.03         # m along the probe's own axis (down at the PUMAs' ready pose)
SPEED = 0.01        # m/s: a slow move
TOOL = trsl(0.0, 0.0, PROBE)


def _kin(robot):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)      # Python kinematics without the C kernels
        return rccl.kinematics.load(robot)


def ready_bar(robot: str) -> np.ndarray:
    """The estimate's free-air error bar (6,) at the ready pose with the probe, from the data file."""
    kin = _kin(robot)
    q = np.asarray(load_robot(robot).poses["ready"], float)
    return ForceEstimator(kin, JointModel.for_robot(robot)).error_bar(np.linalg.inv(kin.jacobian6(q)), TOOL)


# --- the model's figures -------------------------------------------------------------------------
def test_puma260_error_bar_is_the_thesis_figure():
    """Thesis 6.2: ~4.5 N of translational force error from Table 4.6's static friction; at ready
    with a 5 cm probe the PUMA 260's largest force bar is that figure."""
    bar = ready_bar("puma260")
    assert 3.5 <= bar[:3].max() <= 5.5, bar
    assert JointModel.for_robot("puma260").static_error_source.endswith("(Table 4.6)")


def test_error_bar_takes_the_force_map_the_adaptive_control_holds():
    """The adaptive control passes its cached F(T6->tool) (``ToolMaps``) to the error bar where a
    motion starts; the bar is the one computed from the tool transform itself."""
    from rccl.adaptive.deviation import ToolMaps

    kin = _kin("puma560")
    q = np.asarray(load_robot("puma560").poses["ready"], float)
    est = ForceEstimator(kin, JointModel.for_robot("puma560"))
    jinv = np.linalg.inv(kin.jacobian6(q))
    tool = trsl(0.02, -0.01, PROBE)
    np.testing.assert_allclose(est.error_bar(jinv, tool, ToolMaps().of(tool).f), est.error_bar(jinv, tool),
                               rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("robot", ROBOTS[1:])
def test_arms_without_table_4_6_estimate_their_static_friction_and_say_so(robot):
    m = JointModel.for_robot(robot)
    assert "no Table 4.6" in m.static_error_source and f"{robot}.toml" in m.static_error_source
    assert np.all(m.static_error > 0) and np.all(m.torque_error() >= m.static_error)


def test_a_joint_whose_count_moved_has_kinetic_friction_however_slow():
    """One count of the Stanford boom per period at 36 Hz is 0.23 mm/s, under the old 1e-3 m/s
    rest speed: its 20 N of Coulomb friction went into the estimate (the ~20 N steady bias)."""
    kin, model = _kin("stanford"), JointModel.for_robot("stanford")
    est = ForceEstimator(kin, model)
    q = np.asarray(load_robot("stanford").poses["ready"], float)
    dt = 1 / 36
    qd = np.zeros(6)
    qd[2] = 1.0 / model.conv.R[2, 2] / dt                    # one count in one period
    adc = model.conv.joint_torques_to_adc(kin.gravity(q, est._gravity_coeffs) + model.friction(qd))
    np.testing.assert_allclose(est.net_torques(q, qd, adc, dt, 0), 0.0, atol=1e-9)
    assert abs(est.net_torques(q, qd, adc)[2]) > 15.0        # without the period: the old threshold


def test_model_torque_goes_through_the_adc_filter():
    """A joint that starts sliding: the ADC shows 1 - exp(-dt/tau) of the new friction after one
    period, and so does the model the estimate subtracts."""
    kin, model = _kin("puma260"), JointModel.for_robot("puma260")
    est = ForceEstimator(kin, model)
    q = np.asarray(load_robot("puma260").poses["ready"], float)
    dt = 1 / 250
    rest, slide = np.zeros(6), np.array([0.0, 0.1, 0.0, 0.0, 0.0, 0.0])
    g = kin.gravity(q, est._gravity_coeffs)
    a = math.exp(-dt / FILTER_TAU)
    seen = a * g + (1 - a) * (g + model.friction(slide))     # what the filtered current reads
    est.net_torques(q, rest, model.conv.joint_torques_to_adc(g), dt, 7)
    np.testing.assert_allclose(est.net_torques(q, slide, model.conv.joint_torques_to_adc(seen), dt, 8), 0.0,
                               atol=1e-9)


def test_vet_refuses_a_limit_inside_the_bar_and_warns_near_it():
    bar = np.array([2.0, 9.0, 3.0, 0.1, 0.1, 0.1])
    refused = r"\|fy\| <= 8 N: the force estimate's free-air error here is \+-9 N.*above 27 N"
    with pytest.raises(ForceLimitRefused, match=refused):
        Limit.parse("fy", 8.0).vet(bar)
    with pytest.warns(ForceEstimateWarning, match=r"\|fz\| <= 8 N: .*\+-3 N; a limit under 3x that \(9 N\)"):
        Limit.parse("fz", 8.0).vet(bar)
    assert Limit.parse("fx", 8.0).vet(bar) == []
    with pytest.warns(ForceEstimateWarning, match=r"\+-9 N \(the thesis's was 4.5 N, 6.2\); a limit under"):
        Limit.parse("fy", 20.0).vet(bar)
    assert Limit.parse("fy", 27.5).vet(bar) == []
    assert Limit.parse("dz", 0.001).vet(bar) == []           # deviation limits do not watch the estimate


# --- on simula ------------------------------------------------------------------------------------
@pytest.fixture(scope="module", params=ROBOTS)
def arm_sim(request):
    from rci.simula.process import SimulaProcess
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        with SimulaProcess("-p", "--power-on", robot=request.param, lockstep=True) as sim:
            yield request.param, sim


def slow_move(sim, robot: str, limit: tuple | None = None):
    """From the control's first sample, take the probe 3 cm along its axis at 1 cm/s in free air
    with a force monitor (and ``limit`` as ``arm.limit(*limit)``); returns (request, forces (N, 6),
    the error bar at the start)."""
    rows = []

    def record(s):
        rows.append(s.force.copy())

    with rccl.adaptive.open(sim.url, robot=robot, timeout=2.0) as arm:
        tool = Trsf("PROBE", TOOL)
        x0 = arm.t6 @ TOOL
        p = makeposition("DOWN", T6, tool, EQ, Trsf("DOWN", x0 @ trsl(0.0, 0.0, DROP)), TL, tool)
        arm.setmod("cartesian")
        arm.setvel(SPEED, math.radians(10.0))
        kin = arm.adaptive.kin
        bar = arm.adaptive.estimator.error_bar(np.linalg.inv(kin.jacobian6(arm.gen.q)), TOOL)
        arm.evalfn(record, needs=("force",))
        if limit is not None:
            arm.limit(*limit)
        req = arm.move(p)
        try:
            arm.waitfor(req)
        finally:
            arm.rci.wait(0.1)
    return req, np.array(rows), bar


def test_free_air_estimate_in_a_slow_move_stays_within_its_error_bar(arm_sim):
    robot, sim = arm_sim
    req, f, bar = slow_move(sim, robot)
    assert req.status == "done" and req.ended is None
    assert len(f) > 90                                        # ~3 s at 36 Hz
    worst = np.abs(f[:, :3]).max(axis=0)
    assert np.all(worst <= TRIP_BARS * bar[:3]), (robot, worst, bar[:3])


def test_a_limit_the_estimate_cannot_support_is_refused_with_the_figure(arm_sim):
    robot, sim = arm_sim
    i = int(np.argmax(ready_bar(robot)[:3]))
    name = "fx fy fz".split()[i]
    bound = 0.8 * ready_bar(robot)[i]
    with pytest.raises(TrajectoryFault, match=rf"{robot} limit: \|{name}\| <= .* free-air error here is \+-"):
        slow_move(sim, robot, (name, bound))


def test_a_limit_well_above_the_bar_lets_the_free_air_move_finish(arm_sim):
    robot, sim = arm_sim
    bar = ready_bar(robot)
    i = int(np.argmax(bar[:3]))
    name = "fx fy fz".split()[i]
    bound = TRIP_BARS * bar[i] + 1.0
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always", ForceEstimateWarning)
        req, f, _ = slow_move(sim, robot, (name, bound))
    assert req.status == "done" and req.ended is None, req.ended
    assert not [w for w in seen if issubclass(w.category, ForceEstimateWarning)]


def test_a_limit_near_the_bar_is_warned_about_with_the_figure(arm_sim):
    robot, sim = arm_sim
    bar = ready_bar(robot)
    i = int(np.argmax(bar[:3]))
    name = "fx fy fz".split()[i]
    with pytest.warns(ForceEstimateWarning, match=rf"{robot} limit: \|{name}\| <= .*free-air error here is \+-"):
        try:
            slow_move(sim, robot, (name, 2.0 * bar[i]))      # allowed; it may or may not end the motion
        except TrajectoryFault:
            pytest.fail("a limit above the bar must not be refused")
