"""The true values of the dynamics fit's parameters for a simula: its links' inertials read back
from its Pinocchio model (URDF, gravity tuning, DH errors and ``[inertials]`` of the parameter
file applied, as simula builds it), through the generated ``base_parameters``; its rotor
inertias (the data file's joint ``rotor_inertia`` times ``[inertials] rotor_scale``, reflected
by G^T diag(J_m) G); its friction (warm)."""
from __future__ import annotations

import numpy as np

from rcci.calib.exceptions import CalibError


def simula_arm(robot: str, params: dict | None):
    """simula's arm for ``robot`` with the parsed parameter file ``params`` (None: the data file)."""
    from rcci.models import load_robot
    from rci.simula.arm import SimulatedArm
    from rci.simula.exceptions import ParamsError
    from rci.simula.params import apply_params, truth_from_model

    model = load_robot(robot)
    truth = truth_from_model(model)
    if params is not None:
        try:
            truth = apply_params(params, "the logs' truth", robot, truth)
        except ParamsError as exc:
            raise CalibError(str(exc)) from None
    return SimulatedArm(model, truth, seed=0, start="ready", dynamic=True)


def link_inertials(arm) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(masses (n,), centres of mass (n, 3), rotational inertias about them (n, 6): xx yy zz xy
    xz yz), each link in its DH frame (the inputs of the generated ``base_parameters``)."""
    pm = arm.pm
    m, com, rows = [], [], []
    for k in range(1, arm.n + 1):
        frame = pm.frames[pm.getFrameId(f"link{k}")]
        body = frame.placement.actInv(pm.inertias[frame.parentJoint])
        i = np.asarray(body.inertia)
        m.append(body.mass)
        com.append(np.asarray(body.lever))
        rows.append([i[0, 0], i[1, 1], i[2, 2], i[0, 1], i[0, 2], i[1, 2]])
    return np.array(m), np.array(com), np.array(rows)


def truth_parameters(robot: str, params: dict | None) -> np.ndarray:
    """The true value of each column of rcci.calib.identification.column_names (grouped as
    rcci.calib.grouping folds them)."""
    import rccl.kinematics as kin
    from rcci.calib.grouping import grouping
    from rcci.calib.regressor import full_column_names, rotor_coupling_motors
    from rci.simula.params import motor_inertia

    arm = simula_arm(robot, params)
    m, com, inertia = link_inertials(arm)
    G = np.asarray(arm.conv.G, float)
    n = arm.n
    jr = motor_inertia(arm.model, arm.truth)
    beta = np.asarray(kin.load(robot).base_parameters(m, com, inertia, np.diag(arm.rotor)), float)
    coupling = [jr[k] for k in rotor_coupling_motors(G)]
    t = arm.truth
    fric = []
    for j in range(n):
        fric += [t.coulomb_pos[j], t.coulomb_neg[j], t.viscous_pos[j], t.viscous_neg[j]]
    out = np.concatenate([beta, coupling, fric])
    if len(out) != len(full_column_names(robot)):
        raise CalibError(f"robot {robot}: {len(out)} true values for {len(full_column_names(robot))} columns")
    return grouping(robot).K @ out
