"""The contract's functions that a redundant (7-joint) arm's generated module defines
differently: the inverse Jacobian computations as least-squares solutions, and the inverse
kinematics while its closed-form solver is missing.

A 6 x 7 Jacobian J has no inverse. ``joint_from_cartesian`` gives the minimum-norm joint
rates dq = J^+ dc (the smallest |dq| with J dq = dc; exact where J has rank 6) and
``force_from_torque`` the least-squares force f = (J^T)^+ tau (the f whose J^T f is nearest
to tau; the part of tau in J's null space, self-motion, has no Cartesian force), both with
J observed in frame 4 or in the last frame (``frame=6`` names the last link frame: the
contract's name). Near a singularity (rank < 6) they raise
``Singular`` rather than return huge rates: sigma_min / sigma_max < ``RANK_TOL``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, ClassVar

import numpy as np

from rcci.models.kinematics import NoSolver
from rccl.kinematics import exceptions

#: smallest singular value relative to the largest below which J counts as rank-deficient
RANK_TOL = 1e-9


@dataclass(frozen=True)
class NoConfig:
    """The configuration record of a redundant arm whose solver (and so its configuration
    signs) does not exist yet: no fields, one configuration."""

    signs: ClassVar[tuple[int, ...]] = ()

    @classmethod
    def all(cls) -> tuple["NoConfig", ...]:
        return (cls(),)

    def __str__(self) -> str:
        return "-"


def missing_solver(name: str) -> dict[str, Callable]:
    """ik, ik_all and config_of of an arm whose closed-form solver is missing: ik and ik_all
    raise NoSolver naming it (no numerical iteration stands in for a closed form);
    config_of gives the one configuration record NoConfig (a list for a batch), so motions
    to joint-defined positions (RCCL's joint mode to ``park``) run without the solver."""
    def fail(what: str) -> Callable:
        def run(*args, **kwargs):
            raise NoSolver(f"{name}.{what}: no inverse kinematics for this redundant (7-joint) arm yet: "
                           "its closed-form solver with a free parameter (derive/inverse_redundant.py, "
                           "plugged in by derive.redundant) has not been derived; rerun "
                           f"`python -m derive --robot {name}` once it exists")
        run.__name__ = what
        return run

    def config_of(q):
        """The configuration of q: NoConfig() (a list of them for a batch (N, n))."""
        q = np.asarray(q, dtype=float)
        return [NoConfig() for _ in range(q.shape[0])] if q.ndim == 2 else NoConfig()
    return {"ik": fail("ik"), "ik_all": fail("ik_all"), "config_of": config_of}


def _into(name: str, what: str, out, value: np.ndarray) -> np.ndarray:
    """numpy's ``out=`` convention: ``value`` written into ``out`` (float64, writable, the result's shape)."""
    if not (isinstance(out, np.ndarray) and out.dtype == np.float64 and out.shape == value.shape
            and out.flags.writeable):
        raise exceptions.InvalidInput(f"{name}.{what}: out must be a writable float64 numpy array of shape "
                                      f"{value.shape}, got {getattr(out, 'shape', type(out).__name__)}")
    out[...] = value
    return out


def least_squares(robot) -> tuple[dict[int, Callable], dict[int, Callable]]:
    """{frame: joint_from_cartesian}, {frame: force_from_torque} of a redundant ``robot``
    (rccl.kinematics.runtime.Robot) from its Jacobian kernels ``jacobian4`` and
    ``jacobian6`` (the last frame); each entry is ``fn(q, x, out=None)``."""
    def pinv(q, frame: int, what: str) -> np.ndarray:
        (j,) = robot.call(f"jacobian{frame}", q)
        u, s, vt = np.linalg.svd(j, full_matrices=False)
        ratio = s[..., -1] / s[..., 0]
        if np.any(ratio < RANK_TOL):
            raise exceptions.Singular(f"{robot.name}.{what}: the Jacobian has rank < 6 (sigma_min / sigma_max = "
                                      f"{float(np.min(ratio)):.3g}) at q = {np.asarray(q).tolist()}")
        return np.swapaxes(vt, -1, -2) @ (np.swapaxes(u, -1, -2) / s[..., :, None])  # J^+, (..., n, 6)

    def joint(frame: int) -> Callable:
        def joint_from_cartesian(q, dc, out=None):
            """Minimum-norm dq = J^+ dc, dc observed in frame 4 or the last frame (6 x n J)."""
            res = (pinv(q, frame, "joint_from_cartesian") @ np.asarray(dc, float)[..., :, None])[..., 0]
            return res if out is None else _into(robot.name, "joint_from_cartesian", out, res)
        return joint_from_cartesian

    def force(frame: int) -> Callable:
        def force_from_torque(q, tau, out=None):
            """Least-squares f = (J^T)^+ tau = (J^+)^T tau, observed in frame 4 or the last frame."""
            p = np.swapaxes(pinv(q, frame, "force_from_torque"), -1, -2)
            res = (p @ np.asarray(tau, float)[..., :, None])[..., 0]
            return res if out is None else _into(robot.name, "force_from_torque", out, res)
        return force_from_torque

    return {f: joint(f) for f in (4, 6)}, {f: force(f) for f in (4, 6)}
