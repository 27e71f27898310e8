"""The simulator's ground truth: the values simula is built from, to compare fits with.

simula takes its friction and torque sensitivities from the robot data file (the
thesis's Tables 4.1-4.5) and its gravity from Pinocchio on the URDF; the gravity
coefficients it therefore embodies are recovered here by fitting Pinocchio's gravity
torques at random poses to the regressor of 4.24, not copied from Table 4.9.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib.robot import MODELS, RobotInfo


@dataclass(frozen=True)
class Truth:
    """Ground truth in SI units; ``gravity_fit_residual`` (N m) says how exactly the
    URDF's gravity follows 4.24."""

    sigma: np.ndarray
    coulomb_pos: np.ndarray
    coulomb_neg: np.ndarray
    viscous_pos: np.ndarray
    viscous_neg: np.ndarray
    variation: np.ndarray
    gravity: np.ndarray
    gravity_fit_residual: float


def simulator_truth(info: RobotInfo, samples: int = 300, seed: int = 0) -> Truth:
    """Ground truth of simula for ``info``'s robot (data file + Pinocchio gravity)."""
    import pinocchio as pin

    urdf = MODELS / info.nominal["robot"]["urdf"]
    model = pin.buildModelFromUrdf(str(urdf))
    model.gravity.linear = np.array([0.0, 0.0, -float(info.nominal["robot"]["gravity"]["value"])])
    data = model.createData()
    rng = np.random.default_rng(seed)
    A, y = [], []
    for _ in range(samples):
        q = rng.uniform(info.lower, info.upper)
        A.append(info.regressor(q))
        y.append(pin.computeGeneralizedGravity(model, data, q))
    A, y = np.vstack(A), np.concatenate(y)
    c, *_ = np.linalg.lstsq(A, y, rcond=None)
    fr = info.nominal["friction"]
    v = lambda k: np.asarray(fr[k]["values"], dtype=float)  # noqa: E731
    return Truth(sigma=np.asarray(info.nominal["motors"]["torque_sensitivity"]["values"], float),
                 coulomb_pos=v("coulomb_pos"), coulomb_neg=v("coulomb_neg"),
                 viscous_pos=v("viscous_pos"), viscous_neg=v("viscous_neg"),
                 variation=v("variation"), gravity=c,
                 gravity_fit_residual=float(np.abs(A @ c - y).max()))


def simula_variation(robot: str, seed: int, joint: int, window: tuple[float, float]) -> tuple[float, float]:
    """(peak, sqrt(2) x RMS) of the relative Coulomb variation simula applies to
    ``joint`` (1-based) over ``window`` (rad), for a simula started with ``seed``.

    This reads the simulator's own friction pattern (rci.simula), so that the fitted
    Table 4.4 value can be compared with what the logs really contain, not only with
    the bound the simulator was given.
    """
    from rci.robot_model import load_robot
    from rci.simula.arm import Arm
    from rci.simula.params import truth_from_model

    model = load_robot(robot)
    truth = truth_from_model(model)
    arm = Arm(model, truth, seed=seed, start="ready")
    th = np.linspace(window[0], window[1], 4000)
    q = np.zeros((len(th), model.n_joints))
    q[:, joint - 1] = th
    pattern = np.array([arm.friction.pattern(x)[joint - 1] for x in q]) * truth.variation[joint - 1]
    return float(np.abs(pattern).max()), float(np.sqrt(2.0) * pattern.std())
