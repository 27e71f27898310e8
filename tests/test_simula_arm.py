"""Unit tests of the simulated arm (rci.simula.arm): servo, calibration, current mode, sensors."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from rci import codes
from rci.chg import CUR, POS, STOPCAL, Chg
from rcci.models import load_robot
from rci.simula.arm import SimulatedArm
from rci.simula.exceptions import ParamsError
from rci.simula.params import PulleyLoad, load_params, parse_load, truth_from_model

PUMA = load_robot("puma260")
DT = 1 / 36


def quiet_truth(model=PUMA, **kw):
    """Thesis values, warm joints, no position variation: friction exactly as eq. 4.27."""
    t = truth_from_model(model)
    d = replace(t.disturbances, start_warm=True, **kw)
    return replace(t, variation=np.zeros(model.n_joints), disturbances=d)


def powered(arm: SimulatedArm) -> SimulatedArm:
    c = Chg(nj=arm.n)
    c.power_on.com = 1
    arm.apply(c, DT)
    return arm


def cycle(arm: SimulatedArm, **motion) -> None:
    """One control cycle: motion={joint index: (com, value)} then one period of physics."""
    c = Chg(nj=arm.n)
    for j, (com, value) in motion.items():
        c.motion[int(j)].issue(com, value)
    arm.apply(c, DT)
    arm.step(DT)


def thesis_gravity(q, c12, c13, c15):
    """Eq. 4.24 (thesis), written out here independently of the simulator."""
    t1, t2, t3, t4, t5, t6 = q
    s23, c23 = np.sin(t2 + t3), np.cos(t2 + t3)
    w = (c23 * np.cos(t4) * np.sin(t5) + np.cos(t5) * s23) * c15
    return np.array([0.0, w + s23 * c13 + np.cos(t2) * c12, w + s23 * c13,
                     -s23 * np.sin(t4) * np.sin(t5) * c15,
                     (c23 * np.sin(t5) + np.cos(t4) * np.cos(t5) * s23) * c15, 0.0])


def test_pos_reaches_target_at_cycle_end_and_respects_velocity_limit():
    arm = powered(SimulatedArm(PUMA, quiet_truth(), seed=1, start="ready"))
    e = arm.counters()
    cycle(arm, **{"1": (POS, int(e[1] + 300))})            # 300 counts of joint 2 in one period
    assert arm.counters()[1] == e[1] + 300
    q_before = arm.q.copy()
    far = int(e[1] + 300 + 11136.6 * 1.0)                    # 1 rad in 1/36 s: beyond 2.99 rad/s
    cycle(arm, **{"1": (POS, far)})
    moved = abs(arm.q[1] - q_before[1])
    assert moved == pytest.approx(PUMA.max_velocity[1] * DT, rel=1e-6)
    for _ in range(20):                                       # keeps going at the limit until there
        arm.step(DT)
    assert arm.counters()[1] == far


def test_uncalibrated_refuses_motion_then_zindex_stopcal_calibrates():
    arm = powered(SimulatedArm(PUMA, quiet_truth(), seed=3))
    assert np.all(arm.counters() == 0) and not arm.state & codes.CALIB_OK
    cycle(arm, **{"0": (POS, 100)})
    s = arm.sample()
    assert s.status == codes.ST_NOT_CALIBRATED and np.all(s.pos == 0)
    # calibration program: zindex all joints, creep each one until it freezes on its mark
    c = Chg()
    c.zindex.issue(1, 0b111111)
    arm.apply(c, DT)
    assert arm.state & codes.ZINDEX_ACTIVE
    target = arm.counters().astype(float)
    for _ in range(400):
        pos = arm.counters()
        target = target + 25.0 * np.sign(np.diag(arm.conv.R))   # each joint creeps toward + angle
        cycle(arm, **{str(j): (POS, int(target[j])) for j in range(6) if not arm.found[j]})
        if arm.found.all():
            break
    assert arm.found.all()
    frozen = arm.counters().copy()
    cycle(arm, **{"0": (POS, int(frozen[0] + 500))})          # ignored until STOPCAL
    assert arm.counters()[0] == frozen[0]
    # the true count at each mark is a multiple of the counts per motor turn; find it
    # from the potentiometers as a real calibration program would
    pots = arm.sample().adcr[6:12].astype(float)
    q_coarse = PUMA.lower + (pots + 2000) / 4000 * (PUMA.upper - PUMA.lower)
    e_coarse = arm.conv.angles_to_counts(q_coarse)
    n = arm.counts_per_rev
    true_marks = np.rint(e_coarse / n) * n
    cycle(arm, **{str(j): (STOPCAL, int(true_marks[j])) for j in range(6)})
    s = arm.sample()
    assert s.state & codes.CALIB_OK and s.state & codes.ZINDEX_OK and not s.state & codes.ZINDEX_ACTIVE
    np.testing.assert_array_equal(s.pos, np.rint(arm.conv.angles_to_counts(arm.q)))  # offsets now zero
    cycle(arm, **{"0": (POS, int(s.pos[0] + 100))})
    assert arm.sample().status == codes.ST_OK and arm.counters()[0] == s.pos[0] + 100


def _dac_for(arm: SimulatedArm, joint: int, torque: float) -> tuple[int, float]:
    """Integer DAC for a joint torque on one joint (others zero); and the torque it really gives."""
    tj = np.zeros(arm.n)
    tj[joint] = torque
    v = int(np.rint(arm.conv.joint_torques_to_dac(tj)[joint]))
    dac = np.zeros(arm.n)
    dac[joint] = v
    return v, float(arm.conv.dac_to_joint_torques(dac)[joint])


def test_current_mode_follows_eq_4_27_stiction_coulomb_viscous():
    """Joint 1 (no gravity): sticks below F_s+, breaks away above, settles at (tau - Fc+)/Fv+."""
    arm = powered(SimulatedArm(PUMA, quiet_truth(), seed=2, start="ready"))
    fr = PUMA.friction
    fc, fv, fs = fr.coulomb_pos.values[0], fr.viscous_pos.values[0], fr.static_pos.values[0]
    sign = np.sign(arm.conv.G[0, 0] * 1.0)                   # G11 < 0: a positive motor torque turns joint 1 negatively
    v_below, t_below = _dac_for(arm, 0, 0.95 * fs)
    q0 = arm.q[0]
    for _ in range(36):
        cycle(arm, **{"0": (CUR, v_below)})
    assert t_below < fs and arm.q[0] == q0 and arm.qd[0] == 0.0   # stiction holds
    v_break, t_break = _dac_for(arm, 0, fs * 1.05)
    cycle(arm, **{"0": (CUR, v_break)})
    assert arm.qd[0] > 0
    # J qdd = tau - Fc+ - Fv+ qd with J = link inertia (Pinocchio crba) + reflected rotor:
    # qd(t) = v_ss + (qd0 - v_ss) exp(-t Fv / J), v_ss = (tau - Fc+) / Fv
    v_run, t_run = _dac_for(arm, 0, fc + 0.03)
    qd0 = arm.qd[0]
    J = arm._inertia(arm.q)[0, 0]
    for _ in range(36 * 3):
        cycle(arm, **{"0": (CUR, v_run)})
    v_ss = (t_run - fc) / fv
    assert arm.qd[0] == pytest.approx(v_ss + (qd0 - v_ss) * np.exp(-3.0 * fv / J), rel=0.01)
    # below Coulomb the joint decelerates and sticks again
    v_stop, _ = _dac_for(arm, 0, 0.5 * fc)
    for _ in range(36):
        cycle(arm, **{"0": (CUR, v_stop)})
    assert arm.qd[0] == 0.0
    assert sign < 0


def test_current_mode_gravity_compensation_holds_and_external_torque_moves():
    """The zero-gravity idea (2.2.2): DAC = tortodac(t_g) holds joint 2; a push beyond F_s moves it."""
    arm = powered(SimulatedArm(PUMA, quiet_truth(), seed=4, start="nest"))
    q0 = arm.q.copy()
    tg = thesis_gravity(arm.q, 5.509, -1.762, -1.192)
    np.testing.assert_allclose(arm.gravity(), tg, atol=1e-9)       # URDF + Pinocchio = eq. 4.24
    dac = arm.conv.tortodac(tg)
    for _ in range(72):
        cycle(arm, **{str(j): (CUR, int(dac[j])) for j in range(6)})
    np.testing.assert_allclose(arm.q, q0, atol=1e-12)
    arm.set_external_torque(1, PUMA.friction.static_pos.values[1] + 0.5)
    for _ in range(9):
        dac = arm.conv.tortodac(arm.gravity())
        cycle(arm, **{str(j): (CUR, int(dac[j])) for j in range(6)})
    assert arm.q[1] > q0[1] + 1e-3
    arm.set_external_torque(1, 0.0)


def test_adc_reports_the_torques_through_the_conversions():
    """Joint 1 at constant speed (no gravity): G^T K_adc v_adc averages Fc+ + Fv+ v (4.36, 4.27)."""
    truth = replace(quiet_truth(), hold_std=np.zeros(6), hold_mean=np.zeros(6))
    arm = powered(SimulatedArm(PUMA, truth, seed=5, start="ready"))
    e = arm.counters()
    speed = 0.5                                                # rad/s, positive joint direction
    step = arm.conv.R[0, 0] * speed * DT
    torques = []
    for k in range(1, 180):
        cycle(arm, **{"0": (POS, int(round(e[0] + k * step)))})
        if k > 18:                                              # after the 15 ms filter settled
            torques.append(arm.conv.adc_to_joint_torques(arm.sample().adcr[:6]))
    mean = np.mean(torques, axis=0)
    fr = PUMA.friction
    v = abs(step) * 36 / abs(arm.conv.R[0, 0])
    assert mean[0] == pytest.approx(fr.coulomb_pos.values[0] + fr.viscous_pos.values[0] * v, abs=0.01)
    # the other joints are at rest with zero holding friction: they read their gravity load
    np.testing.assert_allclose(mean[1:], arm.gravity()[1:], atol=0.02)


def test_pulley_mass_adds_m_g_r_to_the_joint_torque():
    truth = quiet_truth()
    m, r = 2.0, 0.05
    means = []
    for load in (None, PulleyLoad(3, m, r, 1)):
        arm = powered(SimulatedArm(PUMA, truth, seed=6, start="ready", load=load))
        e = arm.counters()
        step = arm.conv.R[2, 2] * 0.3 * DT                    # joint 3 at +0.3 rad/s
        vals, true = [], []
        for k in range(1, 180):
            cycle(arm, **{"2": (POS, int(round(e[2] + k * step)))})
            if k > 18:
                tj = arm.conv.adc_to_joint_torques(arm.sample().adcr[:6])[2]
                vals.append(tj - arm.gravity()[2])
                true.append(arm.conv.motor_to_joint_torques(arm.motor_torque)[2] - arm.gravity()[2])
        # the ADC (ripple, filter, noise, 12 bits) reads the true joint torque on average
        assert np.mean(vals) == pytest.approx(np.mean(true), abs=0.03)
        means.append(np.mean(true))
    extra = means[1] - means[0]
    assert extra == pytest.approx(m * PUMA.gravity * r + truth.disturbances.pulley_friction, abs=1e-9)


def test_cold_joint_has_more_friction_than_warm():
    t = truth_from_model(PUMA)
    cold = powered(SimulatedArm(PUMA, replace(t, disturbances=replace(t.disturbances, warmup_time=4.0)), seed=7, start="ready"))
    assert np.all(cold.friction.cold_factor() == pytest.approx(1.2))
    e = cold.counters()
    for k in range(1, 36 * 10):
        cycle(cold, **{"0": (POS, int(e[0] - k * 20))})          # +0.1 rad/s (R11 < 0)
    assert cold.friction.cold_factor()[0] < 1.05 and cold.friction.cold_factor()[1] == pytest.approx(1.2)


def test_friction_variation_stays_within_table_4_4():
    arm = SimulatedArm(PUMA, truth_from_model(PUMA), seed=8, start="ready")
    qs = np.linspace(-3, 3, 2001)
    pat = np.array([arm.friction.pattern(np.full(6, q)) for q in qs])
    assert np.all(np.abs(pat) <= 1.0) and np.all(pat.max(axis=0) > 0.5)


def test_same_seed_same_sensor_stream():
    runs = []
    for _ in range(2):
        arm = powered(SimulatedArm(PUMA, truth_from_model(PUMA), seed=11, start="nest"))
        e = arm.counters()
        out = []
        for k in range(1, 60):
            cycle(arm, **{"1": (POS, int(e[1] + 40 * k)), "4": (CUR, 50)})
            s = arm.sample()
            out.append(np.concatenate([s.pos, s.adcr]))
        runs.append(np.array(out))
    np.testing.assert_array_equal(runs[0], runs[1])
    other = powered(SimulatedArm(PUMA, truth_from_model(PUMA), seed=12, start="nest"))
    cycle(other)
    assert not np.array_equal(other.sample().adcr, runs[0][0][6:])


def test_joint_limit_stops_the_joint_and_reports():
    arm = powered(SimulatedArm(PUMA, quiet_truth(), seed=9, start="ready"))
    e = arm.counters()
    beyond = arm.conv.angles_to_counts(np.r_[arm.q[:5], PUMA.upper[5] + 0.2])
    for _ in range(200):
        cycle(arm, **{"5": (POS, int(beyond[5]))})
        s = arm.sample()
        if s.status:
            break
    assert s.status == codes.ST_JOINT_LIMIT and arm.q[5] == pytest.approx(PUMA.upper[5])
    assert e[0] == arm.counters()[0]


def test_params_file_changes_the_ground_truth(tmp_path):
    p = tmp_path / "fit.toml"
    p.write_text('[calib]\nschema = "rcci-calib-params/1"\nrobot = "puma260"\n\n'
                 '[gravity_coeffs]\nc12 = 5.3\nc13 = -1.7\nc15 = -1.25\nc15_error = 0.01\nunit = "N*m"\n\n'
                 '[friction]\ncoulomb_pos = [0.7, nan, 0.8, 0.17, 0.18, 0.14]\n\n'
                 '[motors]\ntorque_sensitivity = [0.07, 0.075, 0.08, 0.036, 0.035, 0.03]\n')
    truth = load_params(p, "puma260", truth_from_model(PUMA))
    assert truth.coulomb_pos[0] == 0.7 and truth.coulomb_pos[1] == 1.620   # NaN keeps the thesis value
    arm = SimulatedArm(PUMA, truth, seed=0, start="ready")
    for q in (PUMA.poses["ready"], PUMA.poses["j3A"], np.array([0.3, 0.5, -1.0, 0.7, 1.1, 0.2])):
        np.testing.assert_allclose(arm.gravity(q), thesis_gravity(q, 5.3, -1.7, -1.25), atol=1e-9)
    assert arm.conv.sigma[0] == 0.07


@pytest.mark.parametrize("robot, changes", [
    ("puma560", {"cy2": 1.5, "cz3": 9.2, "cx4": 0.05, "cz5": 0.06, "cy6": -0.02}),   # the minimal set
    ("microbo", {"c15": -0.4}),                                                  # a [gravity_grouping]
])
def test_params_file_moves_the_gravity_of_any_arm(tmp_path, robot, changes):
    """Changed coefficients of an arm other than the thesis's: simula's Pinocchio gravity is
    the generated regressor (rccl.kinematics) with the new values, on random poses."""
    import rccl.kinematics

    model = load_robot(robot)
    kin = rccl.kinematics.load(robot)
    p = tmp_path / "fit.toml"
    p.write_text(f'[calib]\nschema = "rcci-calib-params/1"\nrobot = "{robot}"\n\n[gravity_coeffs]\n'
                 + "".join(f"{n} = {v}\n" for n, v in changes.items()))
    arm = SimulatedArm(model, load_params(p, robot, truth_from_model(model)), seed=0, start="ready")
    c = np.array([changes.get(n, model.gravity_coeffs[n].value) for n in kin.GRAVITY_COEFFS])
    for q in np.random.default_rng(3).uniform(model.lower, model.upper, (20, model.n_joints)):
        want = np.asarray(kin.gravity_regressor(q)).reshape(model.n_joints, -1) @ c
        np.testing.assert_allclose(arm.gravity(q), want, atol=1e-9)


def test_a_mass_coefficient_cannot_be_moved(tmp_path):
    """The Microbo's c12 is g times the masses the lift carries: no centre of mass changes it."""
    model = load_robot("microbo")
    p = tmp_path / "fit.toml"
    p.write_text('[calib]\nschema = "rcci-calib-params/1"\nrobot = "microbo"\n\n[gravity_coeffs]\nc12 = 200.0\n')
    with pytest.raises(ParamsError, match="c12 of robot microbo cannot be changed"):
        SimulatedArm(model, load_params(p, "microbo", truth_from_model(model)), seed=0, start="ready")


@pytest.mark.parametrize("text, match", [
    ("not toml [", "not valid TOML"),
    ('[calib]\nschema = "other"\nrobot = "puma260"\n', "schema"),
    ('[calib]\nschema = "rcci-calib-params/1"\nrobot = "microbo"\n', "robot 'microbo'"),
    ('[calib]\nschema = "rcci-calib-params/1"\nrobot = "puma260"\n[friction]\ncoulomb_pos = [1, 2]\n',
     r"\[friction\] coulomb_pos"),
    ('[calib]\nschema = "rcci-calib-params/1"\nrobot = "puma260"\n[simula]\nadc_noise = -1\n', "adc_noise"),
])
def test_bad_params_file_is_named(tmp_path, text, match):
    p = tmp_path / "bad.toml"
    p.write_text(text)
    with pytest.raises(ParamsError, match=match) as info:
        load_params(p, "puma260", truth_from_model(PUMA))
    assert str(p) in str(info.value)


def test_load_spec_parsing():
    assert parse_load("pulley:joint=3,mass=2.5,radius=0.04", 6) == PulleyLoad(3, 2.5, 0.04, 1)
    assert parse_load("none", 6) is None
    for bad in ("pulley:joint=9,mass=1,radius=0.1", "pulley:mass=1", "spring:k=1", "pulley:joint=1,mass=-1,radius=1"):
        with pytest.raises(ValueError, match="load"):
            parse_load(bad, 6)


def test_microbo_prismatic_axis_follows_pos():
    mb = load_robot("microbo")
    arm = powered(SimulatedArm(mb, quiet_truth(mb), seed=1, start="ready"))
    e = arm.counters()
    cycle(arm, **{"1": (POS, int(e[1] + 1000))})              # 1000 counts = 5 mm on the lift
    assert arm.q[1] - mb.poses["ready"][1] == pytest.approx(0.005, abs=1e-6)
    lift = arm.conv.adc_to_joint_torques(arm.sample().adcr[:6])[1]
    assert lift > 0.8 * mb.gravity_coeffs["c12"].value                   # the lift carries the arm's weight


def test_dynamic_mode_conserves_energy_without_friction():
    """--dynamic: with no friction and no motor current the arm swings as a free multibody
    (Pinocchio crba/rnea plus reflected rotor inertia): kinetic + potential energy is kept."""
    import pinocchio as pin
    zero = np.zeros(6)
    truth = replace(quiet_truth(), coulomb_pos=zero, coulomb_neg=zero, viscous_pos=zero, viscous_neg=zero,
                    static_pos=zero, static_neg=zero, hold_std=zero, hold_mean=zero)
    arm = powered(SimulatedArm(PUMA, truth, seed=1, start="ready", dynamic=True))
    arm.q = np.radians([0.0, 60.0, -120.0, 30.0, -60.0, 0.0])

    def energy():
        kin = 0.5 * arm.qd @ arm._inertia(arm.q) @ arm.qd
        return kin + pin.computePotentialEnergy(arm.pm, arm.pd, arm.q)

    e0 = energy()
    for _ in range(9):
        cycle(arm, **{str(j): (CUR, 0) for j in range(6)})
    assert np.max(np.abs(arm.qd)) > 0.5                  # it really moved
    kinetic = 0.5 * arm.qd @ arm._inertia(arm.q) @ arm.qd
    assert abs(energy() - e0) < 0.02 * kinetic


def test_current_mode_adc_reads_dac_over_kappa_and_clips_at_max_current():
    """For one motor current the DAC value is kappa times the ADC value (4.34 as read); the
    amplifier limits the current to max_current."""
    truth = quiet_truth(adc_noise=0.0, ripple_cur=0.0, ripple_floor=0.0, filter_tau=1e-5)
    arm = powered(SimulatedArm(PUMA, truth, seed=3, start="ready"))
    for _ in range(9):                                     # joint 1 stuck by stiction at 60 DAC counts
        cycle(arm, **{"0": (CUR, 60)})
    assert arm.qd[0] == 0.0
    assert arm.sample().adcr[0] == round(60 / 1.333)
    cycle(arm, **{"0": (CUR, 2047)})                       # asks for 5.7 A
    limit = PUMA.max_current[0] * 0.301 / 0.00111         # 3 A through R_1 = 0.301 ohm, V_g = 1.11 mV/count
    assert arm.qd[0] < 0 and arm.sample().adcr[0] == round(limit)


def test_halts_in_position_mode_leave_table_4_6_static_friction():
    """4.5.5, second method: at each halt, G^T K_adc v_adc - t_g (eq. 4.37, t_a = 0) is the
    static friction; over many halts its mean and spread are those of Table 4.6."""
    arm = powered(SimulatedArm(PUMA, quiet_truth(), seed=21, start="ready"))
    rng = np.random.default_rng(0)
    e = arm.counters()
    samples = []
    for _ in range(120):
        e = e + np.r_[0, rng.integers(-400, 400), 0, 0, 0, 0]
        cycle(arm, **{"1": (POS, int(e[1]))})
        for _ in range(3):                                   # 83 ms at rest: the 15 ms filter settles
            arm.step(DT)
        tj = arm.conv.adc_to_joint_torques(arm.sample().adcr[:6])
        samples.append(tj[1] - arm.gravity()[1])
    samples = np.array(samples)
    fr = PUMA.friction
    assert np.mean(samples) == pytest.approx(fr.static_typical_mean.values[1], abs=0.1)
    assert np.std(samples) == pytest.approx(fr.static_typical_std.values[1], rel=0.2)
    assert samples.max() <= fr.static_pos.values[1] + 0.05 and samples.min() >= -fr.static_neg.values[1] - 0.05


def test_dynamic_mode_without_friction_is_pinocchio_aba():
    """Every joint in current mode, no friction, no rotor inertia: one substep from rest
    gives the accelerations of Pinocchio's forward dynamics (aba) under the motor torques."""
    import pinocchio as pin
    zero = np.zeros(6)
    truth = replace(quiet_truth(), rotor_scale=zero, coulomb_pos=zero,
                    coulomb_neg=zero, viscous_pos=zero, viscous_neg=zero, static_pos=zero, static_neg=zero)
    arm = powered(SimulatedArm(PUMA, truth, seed=1, start="ready", dynamic=True))
    arm.q = np.radians([10.0, 60.0, -120.0, 30.0, -60.0, 20.0])
    dac = np.array([120, -300, 200, 40, -60, 25])
    c = Chg()
    for j in range(6):
        c.motion[j].issue(CUR, int(dac[j]))
    arm.apply(c, DT)
    q0 = arm.q.copy()
    h = DT / int(round(DT * 1000))
    arm._substep(h)
    tj = arm.conv.dac_to_joint_torques(dac.astype(float))
    expected = pin.aba(arm.pm, arm.pm.createData(), q0, np.zeros(6), tj)
    np.testing.assert_allclose(arm.qd / h, expected, rtol=1e-9, atol=1e-9)


def test_rotor_inertia_comes_from_the_data_file_and_rotor_scale_moves_it(tmp_path):
    """simula's reflected rotors are the data file's (``RobotModel.rotor_matrix``, coupled wrist
    included); a parameter file's ``[inertials] rotor_scale`` scales each motor's J_m; a negative
    factor is refused naming the table."""
    arm = SimulatedArm(PUMA, quiet_truth(), seed=0, start="ready", dynamic=True)
    np.testing.assert_allclose(arm.rotor, PUMA.rotor_matrix(), rtol=1e-15, atol=0)
    scale = [1.1, 0.9, 1.2, 0.8, 1.3, 0.7]
    path = tmp_path / "p.toml"
    path.write_text('[calib]\nschema = "rcci-calib-params/1"\nrobot = "puma260"\n'
                    f'[inertials]\nrotor_scale = {scale}\n')
    truth = load_params(path, "puma260", quiet_truth())
    arm = SimulatedArm(PUMA, truth, seed=0, start="ready", dynamic=True)
    np.testing.assert_allclose(arm.rotor, PUMA.rotor_matrix(PUMA.motor_inertia * np.array(scale)), rtol=1e-15)
    path.write_text(path.read_text().replace("0.9", "-0.9"))
    with pytest.raises(ParamsError, match=r"\[inertials\] rotor_scale"):
        load_params(path, "puma260", quiet_truth())
