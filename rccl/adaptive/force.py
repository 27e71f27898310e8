"""Cartesian force estimation from joint motor currents (thesis 4.37, 4.52-4.57), in the tool frame.

The chain, per sample:

    t_a = G^T K_adc (v_adc - f_adc(qd)) - t_g(q)      (4.37: net joint torque the arm exerts)
    q6  = J6^-T t_a                                    (4.56, J6 the frame-6 Jacobian)
    q_T = F(T6->tool) q6                               (1.22-1.23: the same force in the tool frame)

``t_a`` is what the joints push with beyond gravity and (modelled) friction, so ``q_T`` is
the force/torque the tool exerts on the world, (fx, fy, fz, mx, my, mz) in N and N*m,
about the tool frame's origin. Friction is subtracted at the ADC level (4.37) from the
measured joint velocity; a joint at rest has no modelled friction, so its static friction
(Table 4.6) and the Coulomb variation (Table 4.4) remain as errors, amplified by at most
cond(J) (4.57). Near a singularity the estimate is refused (``ForceEstimateError``) rather
than reported with an unbounded error.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rci.conversions import Conversions, friction_torque

from ..transform import force_map
from .exceptions import ForceEstimateError

# estimate: the thesis's best PUMA 260 condition number is 1.8 (4.7); beyond 1e3 the 4.57
# bound lets a 0.1 N*m friction error become newtons of force error at any tool, so we refuse.
MAX_CONDITION = 1.0e3


@dataclass(frozen=True)
class JointModel:
    """What the controller believes about the joints: conversions (4.28-4.38), gravity coefficients (4.24),
    friction of eq. 4.27 (Tables 4.2/4.3/4.5) and its variation (Table 4.4). SI, joint level."""

    conv: Conversions
    gravity_coeffs: dict
    coulomb_pos: np.ndarray
    coulomb_neg: np.ndarray
    viscous_pos: np.ndarray
    viscous_neg: np.ndarray
    static_pos: np.ndarray
    static_neg: np.ndarray
    variation: np.ndarray
    max_dac: np.ndarray        # DAC counts of the motor current limit (as rci.checks computes it, A.5.1)
    dac_per_joint_torque: np.ndarray = None   # K_dac G^-T (4.35), 6x6, derived from conv

    def __post_init__(self) -> None:
        n = self.conv.n
        m = self.conv.joint_torques_to_dac(np.eye(n)).T        # column k: DAC values of a unit torque on joint k
        object.__setattr__(self, "dac_per_joint_torque", m)

    @classmethod
    def for_robot(cls, robot: str = "puma260", conv: Conversions | None = None) -> "JointModel":
        """Thesis values from the robot data file (``rci.robot_model``)."""
        from rci.robot_model import load_robot

        m = load_robot(robot)
        fr = m.friction
        n = m.n_joints
        var = fr.variation.values if fr.variation is not None else np.zeros(n)
        conv = conv or Conversions.from_model(m)
        adc = np.abs(conv.currents_to_adc(np.asarray(m.max_current, float)))
        max_dac = np.minimum(adc * conv.kappa, 2047.0)
        return cls(conv, {k: v.value for k, v in m.gravity_coeffs.items()},
                   np.array(fr.coulomb_pos.values, float), np.array(fr.coulomb_neg.values, float),
                   np.array(fr.viscous_pos.values, float), np.array(fr.viscous_neg.values, float),
                   np.array(fr.static_pos.values, float), np.array(fr.static_neg.values, float),
                   np.array(var, float), np.floor(max_dac))

    def friction(self, qd: np.ndarray) -> np.ndarray:
        """Kinetic friction torque of eq. 4.27 at joint velocities qd (rad/s), 0 at rest."""
        return friction_torque(qd, self.coulomb_pos, self.coulomb_neg, self.viscous_pos, self.viscous_neg)

    def coulomb_uncertainty(self) -> np.ndarray:
        """Table 4.4 band of the Coulomb friction per joint (N*m): variation x the larger Coulomb value."""
        return self.variation * np.maximum(self.coulomb_pos, self.coulomb_neg)


class ForceEstimator:
    """Net joint torques and tool-frame forces from ``how`` readings (4.37, 4.56), for one robot.

    ``kin`` is the generated kinematics module (``jacobian6``, ``gravity``); ``model`` the
    controller's JointModel. Velocities below ``rest_speed`` rad/s count as rest (no friction).
    """

    def __init__(self, kin, model: JointModel, rest_speed: float = 1e-3) -> None:
        self.kin = kin
        self.model = model
        self.rest_speed = float(rest_speed)

    def net_torques(self, q: np.ndarray, qd: np.ndarray, v_adc: np.ndarray) -> np.ndarray:
        """t_a (4.37), N*m per joint, from joint angles (rad), velocities (rad/s) and motor ADC counts."""
        qd = np.where(np.abs(qd) < self.rest_speed, 0.0, qd)
        conv = self.model.conv
        f_adc = conv.friction_to_adc(self.model.friction(qd))
        t_g = self.kin.gravity(q, self.model.gravity_coeffs)
        return conv.net_torques(np.asarray(v_adc, float), f_adc, t_g)

    @staticmethod
    def frame6_force(jac6: np.ndarray, t_a: np.ndarray, where: str = "force estimate") -> np.ndarray:
        """q6 = J6^-T t_a (4.56): the force/torque in frame 6 that the joint torques t_a exert."""
        try:
            f6 = np.linalg.solve(jac6.T, t_a)
        except np.linalg.LinAlgError:
            raise ForceEstimateError(f"{where}: the Jacobian is singular, forces cannot be recovered (4.56)") from None
        return f6

    def tool_force(self, q: np.ndarray, t_a: np.ndarray, t6_to_tool: np.ndarray,
                   jac6: np.ndarray | None = None, check: bool = True) -> np.ndarray:
        """Force/torque the tool exerts, in the tool frame (N, N*m); ``t6_to_tool`` is the tool seen from link 6.

        With ``check`` the Jacobian's condition number is computed and a value above
        ``MAX_CONDITION`` raises ForceEstimateError naming it (4.57).
        """
        j = self.kin.jacobian6(q) if jac6 is None else jac6
        if check:
            c = float(np.linalg.cond(j))
            if not np.isfinite(c) or c > MAX_CONDITION:
                raise ForceEstimateError(
                    f"force estimate at q = {np.round(q, 4).tolist()} rad: Jacobian condition number {c:.3g} > "
                    f"{MAX_CONDITION:g}; a torque error would be amplified that much (4.57)")
        return force_map(t6_to_tool) @ self.frame6_force(j, t_a)

    def force_bound(self, jac6: np.ndarray, t6_to_tool: np.ndarray, torque_error: np.ndarray) -> np.ndarray:
        """Per tool component, the force error that per-joint torque errors ``torque_error`` (N*m, >= 0) can cause.

        |F J6^-T| |dt|: the worst case of each row, the honest error bar of an estimate.
        """
        m = force_map(t6_to_tool) @ np.linalg.inv(jac6.T)
        return np.abs(m) @ np.abs(torque_error)
