"""The columns of the dynamics fit's model before any grouping: the generated base regressor
(thesis 4.6, rccl.kinematics: its IA_j columns are diagonal rotor inertias), one column per motor
that drives several joints (its rotor inertia J_m reflected off the diagonal, G_m^T G_m less its
diagonal: ``JM<m>``, kg m^2 at the motor) and the friction of eq. 4.27 per joint and direction
(``FC<j>+``/``FC<j>-`` Coulomb, N m; ``FV<j>+``/``FV<j>-`` viscous, N m s/rad). SI, joint level:
joint torques = columns @ parameters. rcci.calib.grouping folds what no motion separates. Which
joints' equations the fit uses: :func:`fitted_joints` (rcci.calib.unmeasured: the Microbo's slides)."""
from __future__ import annotations

from functools import cache

import numpy as np


def rotor_coupling_motors(G: np.ndarray) -> list[int]:
    """Motors (0-based) whose row of G reaches more than one joint."""
    return [m for m in range(G.shape[0]) if np.count_nonzero(G[m]) > 1]


@cache
def _kin(robot: str):
    import rccl.kinematics as kin

    return kin.load(robot)


@cache
def gear(robot: str) -> np.ndarray:
    from rcci.calib.robot import robot_info

    return np.asarray(robot_info(robot).drive.G, float)


@cache
def full_column_names(robot: str) -> tuple[str, ...]:
    """Names of every column the fit's model has: base parameters, rotor couplings, friction
    (before :mod:`rcci.calib.grouping` folds those no motion separates)."""
    n = len(gear(robot))
    fric = tuple(f"{k}{j}{s}" for j in range(1, n + 1) for k in ("FC", "FV") for s in ("+", "-"))
    return (tuple(_kin(robot).BASE_PARAMETERS) + tuple(f"JM{m + 1}" for m in rotor_coupling_motors(gear(robot)))
            + fric)


def full_regressor_columns(robot: str, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
    """(N, n, P): joint torques = this @ the parameters of :func:`full_column_names`, at each row."""
    q, qd, qdd = (np.atleast_2d(np.asarray(x, float)) for x in (q, qd, qdd))
    N, n = q.shape
    Y = np.asarray(_kin(robot).base_regressor(q, qd, qdd)).reshape(N, n, -1)
    G = gear(robot)
    cols = [Y]
    for m in rotor_coupling_motors(G):
        full = np.outer(G[m], G[m])
        off = full - np.diag(np.diag(full))
        cols.append((qdd @ off.T)[:, :, None])
    fr = np.zeros((N, n, 4 * n))
    pos, neg = qd > 0, qd < 0
    for j in range(n):
        fr[:, j, 4 * j] = pos[:, j]
        fr[:, j, 4 * j + 1] = -neg[:, j].astype(float)
        fr[:, j, 4 * j + 2] = qd[:, j] * pos[:, j]
        fr[:, j, 4 * j + 3] = qd[:, j] * neg[:, j]
    cols.append(fr)
    return np.concatenate(cols, axis=2)


#: what the simulated arm adds to the thesis's reason for leaving a joint's equation out
DYNAMICS_DETAIL = {
    "microbo": "on simula their friction varies along the travel with periods of centimetres (Table 4.4's "
               "pattern on a slide, 3-7 N), a force the model lacks that biases the parameters their equations "
               "share with the wrist's (measured: docs/calib.md)",
}


def fitted_joints(robot: str) -> list[int]:
    """Joints (0-based) whose equations the fit uses: all but those whose torque calib does not
    measure (rcci.calib.unmeasured)."""
    from rcci.calib.unmeasured import unmeasured_joints

    out = {j - 1 for j in unmeasured_joints(robot)}
    return [j for j in range(len(gear(robot))) if j not in out]


def left_out(robot: str) -> str | None:
    """Why some joints' equations are not fitted (None: every joint's is)."""
    from rcci.calib.unmeasured import why_unmeasured

    why = why_unmeasured(robot)
    if why is None:
        return None
    return why + ("; " + DYNAMICS_DETAIL[robot] if robot in DYNAMICS_DETAIL else "")
