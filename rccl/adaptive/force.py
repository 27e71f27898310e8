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

Two details of the sensors the per-sample estimate follows when it is given the sample
period (``net_torques(..., dt=, sample=)``, as the control level does):

* a joint counts as moving as soon as its encoder count changed over the period: joint
  values measured from integer counts are exactly constant at rest, and one count per
  period is slower than any fixed speed threshold on a fine encoder (the Stanford boom's
  and the Microbo's prismatic joints: 0.2 mm/s at 36 Hz), yet the joint slid and its
  friction was the kinetic one;
* the ADC reads the motor current through the current-sense filter (Appendix C, first
  order, 15 ms), so the model torque it is compared with goes through the same filter:
  at 36 Hz the reading still holds 16 % of the period before, at 1 kHz 94 %.

What is left unknown is the error bar of ``JointModel.torque_error`` (static friction at
rest, Coulomb variation and a cold joint's excess in motion); ``ForceEstimator.error_bar``
maps it to the tool frame (thesis 6.2).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rcci.models import JointFriction, load_robot
from rci.conversions import Conversions, friction_torque

from ..transform import force_map
from .exceptions import ForceEstimateError

# estimate: the thesis's best PUMA 260 condition number is 1.8 (4.7); beyond 1e3 the 4.57
# bound lets a 0.1 N*m friction error become newtons of force error at any tool, so we refuse.
MAX_CONDITION = 1.0e3
# thesis Appendix C: the current-sense low-pass before the ADC, first order
FILTER_TAU = 0.015
# thesis 4.5.3: a joint's friction is "as much as 20 %" higher before it has warmed up
COLD_EXCESS = 0.20
# a joint whose count moved by less than this (counts per period) is at rest: measured joint
# values come from integer counts, so a joint that did not move reads exactly the same value
REST_COUNTS = 1e-3


@dataclass(frozen=True)
class JointModel(JointFriction):
    """What the controller believes about the joints: conversions (4.28-4.38), gravity coefficients (4.24),
    friction of eq. 4.27 (Tables 4.2/4.3/4.5; the fields of ``JointFriction``) and its variation
    (Table 4.4). SI, joint level."""

    conv: Conversions
    gravity_coeffs: dict
    variation: np.ndarray
    max_dac: np.ndarray        # DAC counts of the motor current limit (as rci.checks computes it, A.5.1)
    dac_per_joint_torque: np.ndarray = None   # K_dac G^-T (4.35), 6x6, derived from conv
    # static friction a joint at rest holds (Table 4.6 standard deviation), N*m / N; None: the data
    # file has no Table 4.6 and it is estimated from its Table 4.5 (``static_error_of``)
    static_error: np.ndarray = None
    static_error_source: str = ""

    def __post_init__(self) -> None:
        n = self.conv.n
        m = self.conv.joint_torques_to_dac(np.eye(n)).T        # column k: DAC values of a unit torque on joint k
        object.__setattr__(self, "dac_per_joint_torque", m)
        if self.static_error is None:
            err, src = static_error_of(None, self.static_pos, self.static_neg)
            object.__setattr__(self, "static_error", err)
            object.__setattr__(self, "static_error_source", src)

    @classmethod
    def for_robot(cls, robot: str = "puma260", conv: Conversions | None = None) -> "JointModel":
        """Thesis values from the robot data file (``models``)."""
        m = load_robot(robot)
        fr = m.friction
        n = m.n_joints
        var = fr.variation.values if fr.variation is not None else np.zeros(n)
        conv = conv or Conversions.from_model(m)
        adc = np.abs(conv.currents_to_adc(np.asarray(m.max_current, float)))
        max_dac = np.minimum(adc * conv.kappa, 2047.0)
        arrays = JointFriction.arrays(fr)
        static, source = static_error_of(fr.static_typical_std, arrays["static_pos"], arrays["static_neg"])
        return cls(conv=conv, gravity_coeffs={k: v.value for k, v in m.gravity_coeffs.items()},
                   **arrays, variation=np.array(var, float), max_dac=np.floor(max_dac),
                   static_error=static, static_error_source=f"{m.path.name}: {source}")

    def friction(self, qd: np.ndarray) -> np.ndarray:
        """Kinetic friction torque of eq. 4.27 at joint velocities qd (rad/s), 0 at rest."""
        return friction_torque(qd, self.coulomb_pos, self.coulomb_neg, self.viscous_pos, self.viscous_neg)

    def coulomb_uncertainty(self) -> np.ndarray:
        """Table 4.4 band of the Coulomb friction per joint (N*m): variation x the larger Coulomb value."""
        return self.variation * np.maximum(self.coulomb_pos, self.coulomb_neg)

    def torque_error(self) -> np.ndarray:
        """Per joint, what the model cannot know of the torque a joint's motor current carries
        (N*m, N for a prismatic joint; one standard deviation): at rest the static friction
        the joint holds (``static_error``), in motion the Coulomb band (Table 4.4) plus a cold
        joint's excess (4.5.3); the larger of the two, since a joint may do either."""
        moving = (self.variation + COLD_EXCESS) * np.maximum(self.coulomb_pos, self.coulomb_neg)
        return np.maximum(self.static_error, moving)


# thesis Tables 4.5 and 4.6 (PUMA 260): the static friction a joint holds after a halt has a
# standard deviation of 0.13-0.47 of its breakaway value F_s, 0.28 on average over the six joints
STATIC_STD_PER_FS = 0.28


def static_error_of(table_4_6_std, static_pos: np.ndarray, static_neg: np.ndarray) -> tuple[np.ndarray, str]:
    """The standard deviation of the static friction a joint holds at rest (N*m / N), and where it
    comes from: the data file's Table 4.6 when it has one, else ``STATIC_STD_PER_FS`` x its F_s."""
    if table_4_6_std is not None:
        return np.abs(np.array(table_4_6_std.values, dtype=float)), "friction.static_typical_std (Table 4.6)"
    fs = 0.5 * (np.asarray(static_pos, float) + np.asarray(static_neg, float))
    return STATIC_STD_PER_FS * fs, (f"no Table 4.6: {STATIC_STD_PER_FS} x friction.static_pos/neg "
                                    "(the PUMA 260's ratio of Table 4.6 to Table 4.5)")


def gravity_vector(kin, coeffs) -> np.ndarray:
    """The gravity coefficients (4.24) as the array the generated ``gravity`` takes (its fast entry)."""
    names = getattr(kin, "GRAVITY_COEFFS", None)
    if names is None or not isinstance(coeffs, dict):
        return coeffs
    return np.array([float(getattr(coeffs[n], "value", coeffs[n])) for n in names])


def condition_1(jac: np.ndarray, jac_inv: np.ndarray, work: np.ndarray | None = None) -> float:
    """cond_1(J) = ||J||_1 ||J^-1||_1 (max column sums): within a factor 6 of the 2-norm condition of
    4.57 for a 6x6 matrix, bounds the same error amplification, and costs microseconds, not an SVD.
    A 6x7 J (7 joints) takes its pseudo-inverse J^+ (7x6) for J^-1. ``work`` (optional) is a scratch array of J's shape."""
    work = np.empty(jac.shape) if work is None else work
    np.abs(jac, out=work)
    n1 = max(np.add.reduce(work, 0).tolist())
    inv_work = work if jac_inv.shape == work.shape else work.T   # a 6x7 J: J^+ is 7x6
    np.abs(jac_inv, out=inv_work)
    return float(n1 * max(np.add.reduce(inv_work, 0).tolist()))


class ForceEstimator:
    """Net joint torques and tool-frame forces from ``how`` readings (4.37, 4.56), for one robot.

    ``kin`` is the generated kinematics module (``jacobian6``, ``gravity``); ``model`` the
    controller's JointModel. Called without a sample period, velocities below ``rest_speed``
    rad/s count as rest (no friction); with one, see ``net_torques``.
    """

    def __init__(self, kin, model: JointModel, rest_speed: float = 1e-3) -> None:
        self.kin = kin
        self.model = model
        self.rest_speed = float(rest_speed)
        self._dt = None                     # the sample period the per-period constants are for
        self._rest: list[float] = []        # per joint: below this speed (rad/s, m/s) it did not move
        self._keep = 0.0                    # exp(-dt / FILTER_TAU): the filter's memory over one period
        self._filtered: np.ndarray | None = None   # the model torque through the filter, last sample
        self._sample: int | None = None
        conv = model.conv
        n = conv.n
        # 4.37 is linear in the ADC counts: t_a = A v_adc + b - f(qd) - t_g with A = G^T K_adc
        # (the ADC-level friction f_adc = K_adc^-1 G^-T f maps back through A to f itself)
        self._b = conv.adc_to_joint_torques(np.zeros(n))
        self._adc_to_torque = conv.adc_to_joint_torques(np.eye(n)).T - self._b[:, None]
        self._gravity_coeffs = gravity_vector(kin, model.gravity_coeffs)
        self._fc_pos, self._fc_neg = model.coulomb_pos.tolist(), model.coulomb_neg.tolist()
        self._fv_pos, self._fv_neg = model.viscous_pos.tolist(), model.viscous_neg.tolist()

    def _for_period(self, dt: float) -> None:
        self._dt = dt
        step = np.abs(np.diag(self.model.conv.R))          # counts per rad (per m) of each joint's own encoder
        self._rest = (REST_COUNTS / step / dt).tolist()
        self._keep = math.exp(-dt / FILTER_TAU)
        self._filtered = None

    def model_torques(self, q: np.ndarray, qd: np.ndarray, rest=None) -> np.ndarray:
        """Gravity (4.24) plus the kinetic friction of 4.27 at qd (none below ``rest``, per joint
        or one speed): the joint torques the motors supply in free air (N*m, N)."""
        t = self.kin.gravity(np.ascontiguousarray(q, dtype=float), self._gravity_coeffs).copy()
        rest = [self.rest_speed] * len(t) if rest is None else rest
        for j, v in enumerate(qd.tolist()):      # 4.27 friction; at rest none is modelled
            if v > rest[j]:
                t[j] += self._fc_pos[j] + self._fv_pos[j] * v
            elif v < -rest[j]:
                t[j] += -self._fc_neg[j] + self._fv_neg[j] * v
        return t

    def net_torques(self, q: np.ndarray, qd: np.ndarray, v_adc: np.ndarray, dt: float | None = None,
                    sample: int | None = None) -> np.ndarray:
        """t_a (4.37), N*m per joint, from joint angles (rad), velocities (rad/s) and motor ADC counts.

        With the sample period ``dt`` (s) and the running sample number ``sample``, ``qd`` is
        taken as the measured motion over the last period (a joint whose count did not move
        is at rest), and the model torque goes through the current-sense filter the ADC reads
        through; the filter state carries over from the previous sample only when ``sample``
        follows it (else it starts settled, as after a long steady stretch).
        """
        t = self._adc_to_torque @ np.asarray(v_adc, dtype=float)
        t += self._b
        if dt is None:
            t -= self.model_torques(q, qd)
            return t
        if dt != self._dt:
            self._for_period(dt)
        m = self.model_torques(q, qd, self._rest)
        last = self._filtered
        if last is not None and sample is not None and self._sample is not None and sample == self._sample + 1:
            m += self._keep * (last - m)         # y_k = a y_(k-1) + (1 - a) m_k, a = exp(-dt / tau)
        self._filtered, self._sample = m, sample
        t -= m
        return t

    @staticmethod
    def frame6_force(jac6: np.ndarray, t_a: np.ndarray, where: str = "force estimate") -> np.ndarray:
        """q6 = J6^-T t_a (4.56): the force/torque in frame 6 that the joint torques t_a exert
        (a 6x7 J6: the least-squares force; t_a's part in J's null space is self-motion, no force)."""
        try:     # 6x7 (7 joints): the least-squares f, nearest J^T f = t_a
            f6 = np.linalg.solve(jac6.T, t_a) if jac6.shape[1] == 6 else np.linalg.pinv(jac6.T) @ t_a
        except np.linalg.LinAlgError:
            raise ForceEstimateError(f"{where}: the Jacobian is singular, forces cannot be recovered (4.56)") from None
        return f6

    def tool_force(self, q: np.ndarray, t_a: np.ndarray, t6_to_tool: np.ndarray,
                   jac6: np.ndarray | None = None, check: bool = True) -> np.ndarray:
        """Force/torque the tool exerts, in the tool frame (N, N*m); ``t6_to_tool`` is the tool seen from link 6.

        With ``check`` the Jacobian's condition number (1-norm, ``condition_1``) is computed
        and a value above ``MAX_CONDITION`` raises ForceEstimateError naming it (4.57).
        """
        j = self.kin.jacobian6(q) if jac6 is None else jac6
        if check:
            try:
                c = condition_1(j, np.linalg.inv(j) if j.shape[1] == 6 else np.linalg.pinv(j))
            except np.linalg.LinAlgError:
                c = np.inf
            self.check_condition(q, c)
        return force_map(t6_to_tool) @ self.frame6_force(j, t_a)

    @staticmethod
    def check_condition(q: np.ndarray, condition: float) -> None:
        """ForceEstimateError if cond_1(J) (``condition_1``) is above MAX_CONDITION or not finite (4.57)."""
        if not condition <= MAX_CONDITION:
            raise ForceEstimateError(
                f"force estimate at q = {np.round(q, 4).tolist()} rad: Jacobian condition number {condition:.3g} > "
                f"{MAX_CONDITION:g} (1-norm); a torque error would be amplified that much (4.57)")

    def error_bar(self, jac6_inv: np.ndarray, t6_to_tool: np.ndarray,
                  fmap: np.ndarray | None = None) -> np.ndarray:
        """Per tool-frame component (N, N*m), the free-air error of the force estimate here that
        the model's torque errors (``JointModel.torque_error``, one standard deviation per joint)
        add up to through the lever of each joint: |F(T6->tool) J6^-T| e (thesis 6.2's figure:
        0.5 N*m of static friction, about 4.5 N at the PUMA 260's best configuration).
        ``fmap``: F(T6->tool) when the caller already holds it (the adaptive control's tool maps)."""
        m = (force_map(t6_to_tool) if fmap is None else fmap) @ np.asarray(jac6_inv).T
        return np.abs(m) @ self.model.torque_error()

    def force_bound(self, jac6: np.ndarray, t6_to_tool: np.ndarray, torque_error: np.ndarray) -> np.ndarray:
        """Per tool component, the force error that per-joint torque errors ``torque_error`` (N*m, >= 0) can cause.

        |F J6^-T| |dt|: the worst case of each row, the honest error bar of an estimate.
        """
        m = force_map(t6_to_tool) @ (np.linalg.inv(jac6.T) if jac6.shape[1] == 6 else np.linalg.pinv(jac6.T))
        return np.abs(m) @ np.abs(torque_error)
