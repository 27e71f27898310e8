"""Kinematic calibration end to end (issue 14, item 8): simula's DH errors, the touch probe,
the fit of the shipped touches, and RCCL moving the simulated arm with the calibrated model."""
from __future__ import annotations

import os
from dataclasses import replace

import numpy as np
import pinocchio as pin
import pytest

from rcci.calib.kinematics import fk_function, nominal_dh
from rcci.models import load_robot

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TRUTH = os.path.join(ROOT, "calib", "logs", "simula-truth.toml")
SHIPPED = os.path.join(ROOT, "calib", "logs", "kinematics.rcilog.xz")
MODEL = load_robot("puma260")


def _truth(errors=None):
    from rci.simula.params import load_params, truth_from_model

    t = load_params(TRUTH, "puma260", truth_from_model(MODEL))
    return t if errors is None else replace(t, dh_errors=errors)


def test_simula_arm_with_dh_errors_is_the_a_matrix_product_exactly():
    """simula moves the URDF's joints by the parameter file's [kinematics]: its link 6 is the
    A-matrix product (3.3, 3.83) with the erroneous table, not a first-order approximation."""
    from rci.simula.arm import SimulatedArm

    rng = np.random.default_rng(0)
    E = rng.normal(0, 1, (6, 4)) * [np.radians(0.5), 0.003, 0.003, np.radians(0.5)]
    arm = SimulatedArm(MODEL, _truth(E), start="ready")
    T6 = fk_function(nominal_dh())
    fid = arm.pm.getFrameId("link6")
    for _ in range(5):
        q = rng.uniform(MODEL.lower, MODEL.upper)
        pin.forwardKinematics(arm.pm, arm.pd, q)
        pin.updateFramePlacements(arm.pm, arm.pd)
        exact = np.array(T6(q, E.ravel()))
        assert np.abs(arm.pd.oMf[fid].homogeneous - exact).max() < 1e-12
        assert np.abs(exact - np.array(T6(q, np.zeros(24))))[:3, 3].max() > 1e-3


def test_kinematic_errors_of_a_prismatic_arm_are_refused():
    from rci.simula.arm import SimulatedArm
    from rci.simula.exceptions import ParamsError
    from rci.simula.params import truth_from_model

    microbo = load_robot("microbo")
    t = replace(truth_from_model(microbo), dh_errors=np.full((microbo.n_joints, 4), 1e-4))
    with pytest.raises(ParamsError, match="prismatic"):
        SimulatedArm(microbo, t, start="ready")


def test_touch_probe_closes_inside_a_block_and_not_outside():
    from rcci.calib.touch import simula_words
    from rci.simula.environment import EnvironmentArm, parse_environment

    env = parse_environment(simula_words())
    arm = EnvironmentArm(MODEL, _truth(), start="ready", environment=env)
    assert arm.sample().inport1 & 2 == 0          # the ready pose is far from every face
    # put the tip 1 mm below the floor (z = -0.20 m): find a pose with the nominal IK
    import rccl.kinematics.puma260 as kin
    from rcci.calib.touch import TIP, pose_t6
    R = np.diag([1.0, -1.0, -1.0])               # probe pointing down
    # the true tip is off the nominal one by the arm's DH errors (about a millimetre)
    arm.q = kin.ik(pose_t6(np.array([0.2, -0.1, -0.21]), R, TIP), kin.Config(-1, 1, 1), None)
    assert arm.sample().inport1 & 2
    arm.q = kin.ik(pose_t6(np.array([0.2, -0.1, -0.19]), R, TIP), kin.Config(-1, 1, 1), None)
    assert arm.sample().inport1 & 2 == 0
    with pytest.raises(ValueError, match="probe must be an inport1 bit"):
        parse_environment(["tool:z=0.1,probe=1.5"])


@pytest.fixture(scope="module")
def shipped_fit(tmp_path_factory):
    """`calib fit kinematics` of the shipped touches, into a parameter file."""
    from rcci.calib.__main__ import main

    path = str(tmp_path_factory.mktemp("kin") / "fitted.toml")
    assert main(["fit", "kinematics", SHIPPED, "-p", path, "-q"]) == 0
    return path


def test_calibrated_kinematics_are_the_measured_arm(shipped_fit):
    """rccl.calibrated's fk is the A-matrix product with the fitted errors; its ik (nominal
    closed form + Newton on the calibrated arm) inverts it to rounding."""
    import rccl.kinematics.puma260 as nominal
    from rccl.calibrated import load_calibrated, read_dh_errors

    kin = load_calibrated(shipped_fit)
    E = read_dh_errors(shipped_fit)
    T6 = fk_function(nominal_dh())
    rng = np.random.default_rng(1)
    done = 0
    while done < 30:
        q = rng.uniform(0.8 * MODEL.lower, 0.8 * MODEL.upper)
        if abs(np.sin(q[4])) < 0.2:
            continue
        T = kin.fk(q)
        assert np.abs(T - np.array(T6(q, E.ravel()))).max() < 1e-12
        try:
            back = kin.ik(T, nominal.config_of(q), q)
        except ValueError:        # at the edge of the reach the nominal arm has no solution
            continue
        assert np.abs(kin.fk(back) - T).max() < 1e-10
        done += 1


def test_bad_calibration_files_are_named(tmp_path, shipped_fit):
    from rccl.calibrated import load_calibrated
    from rccl.exceptions import BadRequest

    with pytest.raises(BadRequest, match="no \\[kinematics\\] section"):
        bare = tmp_path / "bare.toml"
        bare.write_text('[calib]\nschema = "rcci-calib-params/1"\nrobot = "puma260"\n')
        load_calibrated(str(bare))
    with pytest.raises(BadRequest, match="not a calibration of robot 'microbo'"):
        load_calibrated(shipped_fit, "microbo")


def test_rccl_positions_the_simulated_arm_to_the_encoders_floor_with_the_fit(shipped_fit):
    """RCCL on a simula built from the truth: nominal kinematics miss by over a millimetre,
    the calibrated ones by tens of micrometres, near what whole encoder counts leave."""
    from rcci.calib.accuracy import positioning_error

    nominal, calibrated, floor = positioning_error(TRUTH, shipped_fit, n=5, seed=3)
    rms = lambda a: float(np.sqrt(np.mean(a ** 2)))  # noqa: E731
    assert rms(nominal.t6) > 1e-3
    assert rms(calibrated.t6) < 0.1e-3 and rms(calibrated.tip) < 0.1e-3
    assert rms(floor.t6) < 0.04e-3
    assert rms(calibrated.t6) < rms(nominal.t6) / 15
