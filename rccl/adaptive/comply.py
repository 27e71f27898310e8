"""Compliant motion by the Paul-Shimano method (thesis 5.4.3, E.6): ``comply(spec, values)`` / ``lock(spec)``.

Chosen tool-frame directions are *compliant*: along/about each, one joint is force
servoed instead of position servoed, and the path is allowed to move freely:

* the drive equation grows a comply transform, T6 = D_a C_drive C_comply (E.6); each
  sample the observed deviation along the compliant directions (E.2) is absorbed into it,
  so the position-servoed joints follow the path *as displaced by the force*;
* for each compliant direction i the joint j best placed to act along it is chosen: the
  one contributing most to a pure motion along i, the largest |J_T[i, j] (J_T^-1)[j, i]|
  (J_T the tool-frame Jacobian; these shares sum to 1 over the joints), each joint used
  once. This is our reading of Paul and Shimano's rule; the thesis gives no formula;
* that joint is run in current mode with the net torque t_a = (J_T^T q)_j (4.52) of the
  requested force q, converted by 4.38 with the gravity loading and the friction of
  4.27 (in the direction the joint moves, or, at rest, the direction it is asked to push).

The force held is then the requested one within the friction uncertainty of the chosen
joint (Table 4.4), divided by its lever |J_T[i, j]|.

Compliance stays on for every later motion until ``lock`` takes the direction out; a
locked direction's comply offset then returns to zero at a bounded speed
(``RETURN_SPEED``), so the arm rejoins the planned path smoothly instead of jumping.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import spec as specmod
from .exceptions import SpecError
from .force import JointModel

# estimate: 2 cm/s and 0.2 rad/s, a gentle return to the planned path after lock (slow next to the
# 0.5 m/s and 3 rad/s Cartesian limits of rccl.limits)
RETURN_SPEED = np.array([0.02, 0.02, 0.02, 0.2, 0.2, 0.2])


def select_joints(jac_tool: np.ndarray, axes: list[int], jinv: np.ndarray | None = None) -> dict[int, int]:
    """The joint (0-based) best placed for each compliant tool axis (0-5), each joint used at most once.

    Score of joint j for axis i: |J_T[i, j] (J_T^-1)[j, i]|, the share of a unit motion
    along axis i that joint j provides. ``jinv`` is J_T^-1 if the caller has it. Raises
    SpecError if the Jacobian is singular.
    """
    if jinv is None:
        try:
            jinv = np.linalg.inv(jac_tool)
        except np.linalg.LinAlgError:
            raise SpecError("comply: the Jacobian is singular here; no joint can be chosen for compliance") from None
    taken: set[int] = set()
    out: dict[int, int] = {}
    for i in axes:
        score = np.abs(jac_tool[i, :] * jinv[:, i]).tolist()
        best, best_j = -1.0, -1
        for j, v in enumerate(score):
            if j not in taken and v > best:
                best, best_j = v, j
        out[i] = best_j
        taken.add(best_j)
    return out


@dataclass
class Compliance:
    """Compliant axes (tool frame) with their forces, and the comply transform as a tool-frame differential."""

    forces: dict[int, float] = field(default_factory=dict)   # axis 0-5 -> N or N*m exerted by the tool
    offset: np.ndarray = field(default_factory=lambda: np.zeros(6))   # C_comply (m, rad), tool frame
    joints: dict[int, int] = field(default_factory=dict)     # axis -> force-servoed joint (last choice)
    free: np.ndarray = field(default_factory=lambda: np.ones(6))   # 1.0 on the non-compliant axes

    @property
    def active(self) -> bool:
        return bool(self.forces)

    def comply(self, spec: str, *values: float) -> None:
        """Make the named force/torque components compliant with these values (N, N*m; signed)."""
        items = specmod.parse(spec, values, f"comply({spec!r})", allow_dev=False, positive=False)
        for (_, i), v in items.items():
            self.forces[i] = v
            self.free[i] = 0.0

    def lock(self, spec: str) -> None:
        """Take the named components out of compliance (``lock("fz")``); the offset then returns to 0 (``release``)."""
        where = f"lock({spec!r})"
        for tok in specmod.tokens(spec, where):
            _, i = specmod.component(tok, where, allow_dev=False)
            self.forces.pop(i, None)
            self.joints.pop(i, None)
            self.free[i] = 1.0

    def release(self, dt: float) -> None:
        """Move the offsets of non-compliant axes towards zero by at most RETURN_SPEED x dt (one sample)."""
        off = self.offset
        if not (off * self.free).any():
            return
        for i, x in enumerate(off.tolist()):
            if x != 0.0 and i not in self.forces:
                step = float(RETURN_SPEED[i]) * dt
                off[i] = 0.0 if abs(x) <= step else (x - step if x > 0 else x + step)

    def absorb(self, dev_tool: np.ndarray) -> None:
        """Take the observed tool-frame deviation along the compliant axes into the comply transform (E.6)."""
        off = self.offset
        for i in self.forces:
            off[i] = dev_tool[i]

    def joint_offsets(self, jac6: np.ndarray, tool_to_6: np.ndarray) -> np.ndarray:
        """Joint displacement (rad) realising the comply offset: J6^-1 D^-1 offset (E.8 for small changes)."""
        if not np.any(self.offset):
            return np.zeros(jac6.shape[0])
        return np.linalg.solve(jac6, tool_to_6 @ self.offset)

    def select(self, jac_tool: np.ndarray) -> dict[int, int]:
        self.joints = select_joints(jac_tool, sorted(self.forces))
        return self.joints

    def net_torques(self, jac_tool: np.ndarray) -> np.ndarray:
        """t_a = J_T^T q (4.52) of the requested compliant forces (N*m per joint)."""
        q = np.zeros(6)
        for i, v in self.forces.items():
            q[i] = v
        return jac_tool.T @ q


def servo_dac(model: JointModel, joints: list[int], t_a: np.ndarray, t_g: np.ndarray, qd: np.ndarray,
              qd_path: np.ndarray | None = None, rest_speed: float = 1e-3,
              correction: dict[int, float] | None = None) -> np.ndarray:
    """DAC values (float) of 4.38 for the force-servoed ``joints``: K_dac G^-T (t_a + t_g) + f_dac.

    Only the entries of ``joints`` are meaningful; t_a elsewhere is taken as 0 (those joints
    are position servoed, their torque is the servo's business). Friction (4.27) is
    compensated in the direction the joint moves; at rest, in the direction the path asks it
    to move (``qd_path``), or, if the path stands still too, the direction of the torque.
    A joint in ``correction`` gets that friction term instead (the static-friction
    correction of thesis 4.6, ``rccl.adaptive.stiction``).
    """
    u = np.array(t_g, dtype=float)           # t_a + t_g + f, only the chosen joints get t_a and f
    for j in joints:
        ta = float(t_a[j])
        if correction is not None and j in correction:
            u[j] += ta + correction[j]
            continue
        v = float(qd[j])
        moving = abs(v) > rest_speed
        vp = 0.0 if qd_path is None else float(qd_path[j])
        if moving:
            sign = 1.0 if v > 0 else -1.0
        elif abs(vp) > rest_speed:
            sign = 1.0 if vp > 0 else -1.0
        else:
            sign = 1.0 if ta > 0 else (-1.0 if ta < 0 else 0.0)
        speed = abs(v) if moving else 0.0
        if sign > 0:
            f = float(model.coulomb_pos[j]) + float(model.viscous_pos[j]) * speed
        elif sign < 0:
            f = -float(model.coulomb_neg[j]) - float(model.viscous_neg[j]) * speed
        else:
            f = 0.0
        u[j] += ta + f
    # 4.38 with f_dac = K_dac G^-T f: v_dac = K_dac G^-T (t_a + t_g + f)
    return model.dac_per_joint_torque @ u
