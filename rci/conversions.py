"""Unit conversions between robot units and SI, thesis section 4.4.3 (eqs. 4.28-4.38, Appendix D).

The robot speaks in encoder counts (``how.pos``), 12-bit ADC counts of the filtered
motor currents (``how.adcr``) and 12-bit DAC values (``chg.motion[i].value`` with CUR).
The control program thinks in joint angles (rad, or m for a prismatic joint) and joint
torques (N*m, or N). The chain, with every matrix as the thesis names it::

    motor angles     Theta_s = G Theta                       (4.28)
    joint torques    t_j     = G^T t_s                       (4.29)
    encoder counts   e       = R Theta + e0                  (4.30; e0 = encoder offset)
    motor torque     t_s     = K_adc v_adc                   (4.31)
                     k_adc_i = (V_g / R_i) sigma_i           (4.32)
    DAC value        v_dac   = K_dac t_s                     (4.33)
                     k_dac_i = kappa_i / k_adc_i             (4.34, see below)
    joint torque from ADC    t_j = G^T K_adc v_adc           (4.36)
    DAC from joint torque    v_dac = K_dac G^-T t_j          (4.35)
    net (external) torque    t_a = G^T K_adc (v_adc - f_adc) - t_g      (4.37)
    DAC for a net torque     v_dac = K_dac G^-T (t_a + t_g) + f_dac     (4.38)

Two readings of the OCR'd print that this module fixes (derivation wins):

* 4.34 is printed ``k_dac = kappa k_adc``. K_adc is N*m per ADC count and K_dac must be
  DAC counts per N*m (4.33), so the printed product has the wrong dimension. The reading
  that is dimensionally right and makes kappa a pure DAC/ADC ratio (Appendix D measures it
  as one number, 1.333, for every joint) is ``k_dac = kappa / k_adc``: for the same motor
  current the DAC value is kappa times the ADC value.
* 4.35 is printed ``v_dac = K_dac G^-1T e_p``; ``e_p`` is OCR damage for ``t_j`` (the
  equation combines 4.29 and 4.33, which contain no encoder counts).

Friction is handled at the ADC/DAC level, as 4.37/4.38 do: a joint-level friction
torque vector f (eq. 4.27) becomes ``f_adc = K_adc^-1 G^-T f`` and ``f_dac = K_dac G^-T f``.

Every function takes arrays whose last axis is the joint axis, ``(..., n)``, and is
vectorised over any leading axes. Units: rad / m, N*m / N, A, ADC and DAC counts. The
constants come from :mod:`models` (``Conversions.for_robot("puma260")``).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .chg import POS

ADC_MIN, ADC_MAX = -2048, 2047   # 12-bit two's complement (how.adcr)
DAC_MIN, DAC_MAX = -2048, 2047   # 12-bit signed (chg CUR value)


def _rows(x: np.ndarray | float, n: int, what: str) -> np.ndarray:
    """``x`` as a float array whose last axis has length ``n``; ValueError naming ``what`` otherwise."""
    a = np.asarray(x, dtype=float)
    if a.ndim == 0 or a.shape[-1] != n:
        raise ValueError(f"{what}: expected an array with last axis of length {n}, got shape {a.shape}")
    return a


def friction_torque(qd: np.ndarray, coulomb_pos: np.ndarray, coulomb_neg: np.ndarray,
                    viscous_pos: np.ndarray, viscous_neg: np.ndarray) -> np.ndarray:
    """Kinetic friction of eq. 4.27 at joint velocities ``qd`` (rad/s or m/s), joint level (N*m or N).

    f = Fc+ + Fv+ qd for qd > 0, f = -Fc- + Fv- qd for qd < 0, and 0 at qd = 0 (at rest
    the friction is whatever static value in [-Fs-, Fs+] balances the load; 4.27 does not
    fix it). Magnitudes are positive, as in Tables 4.2 and 4.3.
    """
    qd = np.asarray(qd, dtype=float)
    pos = coulomb_pos + viscous_pos * qd
    neg = -coulomb_neg + viscous_neg * qd
    return np.where(qd > 0, pos, np.where(qd < 0, neg, 0.0))


@dataclass(frozen=True)
class Conversions:
    """The constants of 4.4.3 for one robot and the conversions built on them.

    ``G`` gear ratio matrix (4.28), ``R`` encoder ratio matrix (counts per rad or per m,
    4.30), ``encoder_offset`` e0 (counts), ``v_g`` ADC volts per count, ``sense_resistance``
    R_i (ohm), ``sigma`` torque sensitivities (N*m/A, Table 4.1), ``kappa`` DAC/ADC ratio.
    """

    robot: str
    G: np.ndarray
    R: np.ndarray
    encoder_offset: np.ndarray
    v_g: float
    sense_resistance: np.ndarray
    sigma: np.ndarray
    kappa: np.ndarray
    k_adc: np.ndarray = field(init=False)   # N*m of motor torque per ADC count (4.32)
    k_dac: np.ndarray = field(init=False)   # DAC counts per N*m of motor torque (4.34)
    G_inv: np.ndarray = field(init=False)
    R_inv: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        n = self.G.shape[0]
        for name in ("G", "R"):
            m = getattr(self, name)
            if m.shape != (n, n) or not np.all(np.isfinite(m)):
                raise ValueError(f"{self.robot}: conversion matrix {name} must be finite ({n}, {n}), got {m.shape}")
            if abs(np.linalg.det(m)) < 1e-12:
                raise ValueError(f"{self.robot}: conversion matrix {name} is singular")
        for name in ("encoder_offset", "sense_resistance", "sigma", "kappa"):
            v = np.asarray(getattr(self, name), dtype=float)
            if v.shape != (n,) or not np.all(np.isfinite(v)):
                raise ValueError(f"{self.robot}: {name} must be {n} finite numbers, got {v!r}")
            object.__setattr__(self, name, v)
        if not (self.v_g > 0 and np.all(self.sense_resistance > 0) and np.all(self.sigma > 0)
                and np.all(self.kappa > 0)):
            raise ValueError(f"{self.robot}: V_g, R_i, sigma_i and kappa_i must all be positive")
        k_adc = self.v_g / self.sense_resistance * self.sigma
        object.__setattr__(self, "k_adc", k_adc)
        object.__setattr__(self, "k_dac", self.kappa / k_adc)
        object.__setattr__(self, "G_inv", np.linalg.inv(self.G))
        object.__setattr__(self, "R_inv", np.linalg.inv(self.R))
        for name in ("G", "R", "G_inv", "R_inv", "encoder_offset", "sense_resistance", "sigma", "kappa",
                     "k_adc", "k_dac"):
            a = np.array(getattr(self, name), dtype=float)
            a.flags.writeable = False
            object.__setattr__(self, name, a)

    # --- construction -------------------------------------------------------------
    @classmethod
    def from_model(cls, model, *, sigma: np.ndarray | None = None, consistent_encoders: bool = True) -> "Conversions":
        """Constants from a :class:`rcci.models.RobotModel`.

        ``sigma`` overrides the torque sensitivities (e.g. values fitted by ``calib``).
        ``consistent_encoders`` uses ``encoder_ratio_consistent`` when the data file has it
        (PUMA: r65 = 127.32 g65 instead of the printed -713.01, see models/puma260.toml);
        False uses R as printed.
        """
        conv = model.conversion
        R = conv.encoder_ratio.values
        if consistent_encoders and conv.encoder_ratio_consistent is not None:
            R = conv.encoder_ratio_consistent.values
        return cls(
            robot=model.name,
            G=np.array(conv.gear_ratio.values, dtype=float),
            R=np.array(R, dtype=float),
            encoder_offset=np.array(conv.encoder_offset.values, dtype=float),
            v_g=float(conv.adc_volts_per_count.value),
            sense_resistance=np.array(conv.sense_resistance.values, dtype=float),
            sigma=np.array(model.motors.torque_sensitivity.values if sigma is None else sigma, dtype=float),
            kappa=np.array(conv.kappa.values, dtype=float),
        )

    @classmethod
    def for_robot(cls, name: str = "puma260", **kw) -> "Conversions":
        """Constants of a named robot (``"puma260"``, ``"microbo"``) from its data file."""
        from rcci.models import load_robot
        return cls.from_model(load_robot(name), **kw)

    @property
    def n(self) -> int:
        """Number of joints."""
        return int(self.G.shape[0])

    # --- positions (4.28, 4.30) ---------------------------------------------------
    def counts_to_angles(self, e: np.ndarray) -> np.ndarray:
        """Joint values Theta (rad / m) from encoder counts e: Theta = R^-1 (e - e0)."""
        e = _rows(e, self.n, "encoder counts")
        return (e - self.encoder_offset) @ self.R_inv.T

    def angles_to_counts(self, q: np.ndarray) -> np.ndarray:
        """Encoder counts (float, not rounded) for joint values Theta: e = R Theta + e0."""
        q = _rows(q, self.n, "joint values")
        return q @ self.R.T + self.encoder_offset

    def angles_to_counts_int(self, q: np.ndarray) -> np.ndarray:
        """Encoder counts rounded to the nearest integer (int64), as ``chg`` POS values need."""
        return np.rint(self.angles_to_counts(q)).astype(np.int64)

    def command_positions(self, chg, q: np.ndarray) -> None:
        """POS commands for every joint of ``chg`` (an ``rci.chg.Chg``): the angles ``q`` (rad;
        m on prismatic joints) in whole encoder counts. The one place a program turns a joint
        vector into position commands."""
        motion = chg.motion
        for i, c in enumerate(self.angles_to_counts_int(q).tolist()):
            motion[i].issue(POS, c)

    def rounding_step(self) -> np.ndarray:
        """Most (rad / m, per joint) by which rounding positions to whole counts can lengthen a step.

        A POS step between two rounded commands differs from the unrounded step by at most one
        count on every motor (half a count at each end); through Theta = R^-1 e that is
        sum_m |R^-1[j, m]| on joint j (the wrist's coupled motors add up). A generator that plans
        steps at most ``v_max * T - rounding_step()`` never trips RCI's R_REQVEL check.
        """
        return np.abs(self.R_inv).sum(axis=1)

    def joint_to_motor_angles(self, q: np.ndarray) -> np.ndarray:
        """Motor shaft angles Theta_s = G Theta (rad)."""
        return _rows(q, self.n, "joint values") @ self.G.T

    def motor_to_joint_angles(self, qs: np.ndarray) -> np.ndarray:
        """Joint values Theta = G^-1 Theta_s."""
        return _rows(qs, self.n, "motor angles") @ self.G_inv.T

    # --- torques (4.29) -----------------------------------------------------------
    def motor_to_joint_torques(self, ts: np.ndarray) -> np.ndarray:
        """Joint torques t_j = G^T t_s (N*m / N) from motor shaft torques t_s (N*m)."""
        return _rows(ts, self.n, "motor torques") @ self.G

    def joint_to_motor_torques(self, tj: np.ndarray) -> np.ndarray:
        """Motor shaft torques t_s = G^-T t_j."""
        return _rows(tj, self.n, "joint torques") @ self.G_inv

    # --- ADC (4.31, 4.32) ----------------------------------------------------------
    def adc_to_motor_torques(self, v_adc: np.ndarray) -> np.ndarray:
        """Motor shaft torques t_s = K_adc v_adc (N*m) from ADC counts."""
        return _rows(v_adc, self.n, "ADC counts") * self.k_adc

    def motor_torques_to_adc(self, ts: np.ndarray) -> np.ndarray:
        """ADC counts (float, unquantised) that motor torques t_s produce."""
        return _rows(ts, self.n, "motor torques") / self.k_adc

    def adc_to_currents(self, v_adc: np.ndarray) -> np.ndarray:
        """Motor currents (A) from ADC counts: i = V_g v_adc / R_i (Appendix C)."""
        return _rows(v_adc, self.n, "ADC counts") * (self.v_g / self.sense_resistance)

    def currents_to_adc(self, i: np.ndarray) -> np.ndarray:
        """ADC counts (float) for motor currents i (A)."""
        return _rows(i, self.n, "currents") * (self.sense_resistance / self.v_g)

    def adc_to_joint_torques(self, v_adc: np.ndarray) -> np.ndarray:
        """Joint torques t_j = G^T K_adc v_adc (4.36)."""
        return self.motor_to_joint_torques(self.adc_to_motor_torques(v_adc))

    def joint_torques_to_adc(self, tj: np.ndarray) -> np.ndarray:
        """ADC counts (float) that joint torques t_j produce: K_adc^-1 G^-T t_j."""
        return self.motor_torques_to_adc(self.joint_to_motor_torques(tj))

    # --- DAC (4.33-4.35) -----------------------------------------------------------
    def motor_torques_to_dac(self, ts: np.ndarray) -> np.ndarray:
        """DAC values (float, unquantised) v_dac = K_dac t_s."""
        return _rows(ts, self.n, "motor torques") * self.k_dac

    def dac_to_motor_torques(self, v_dac: np.ndarray) -> np.ndarray:
        """Motor shaft torques t_s = K_dac^-1 v_dac that DAC values command."""
        return _rows(v_dac, self.n, "DAC values") / self.k_dac

    def dac_to_currents(self, v_dac: np.ndarray) -> np.ndarray:
        """Motor currents (A) that DAC values command."""
        return self.dac_to_motor_torques(v_dac) / self.sigma

    def joint_torques_to_dac(self, tj: np.ndarray) -> np.ndarray:
        """DAC values v_dac = K_dac G^-T t_j (4.35), float."""
        return self.motor_torques_to_dac(self.joint_to_motor_torques(tj))

    def dac_to_joint_torques(self, v_dac: np.ndarray) -> np.ndarray:
        """Joint torques t_j = G^T K_dac^-1 v_dac that DAC values command."""
        return self.motor_to_joint_torques(self.dac_to_motor_torques(v_dac))

    def tortodac(self, tj: np.ndarray) -> np.ndarray:
        """Joint torques to DAC values rounded and clipped to the 12-bit range (int64).

        The thesis's ``tortodac`` (section 2.2.2) without friction; raises ValueError for
        NaN or infinite torques (a DAC value must never be made up).
        """
        v = self.joint_torques_to_dac(tj)
        if not np.all(np.isfinite(v)):
            raise ValueError(f"tortodac: non-finite torque in {np.asarray(tj)!r}")
        return np.clip(np.rint(v), DAC_MIN, DAC_MAX).astype(np.int64)

    # --- friction at the ADC/DAC level, net torques (4.37, 4.38) -----------------------
    def friction_to_adc(self, f: np.ndarray) -> np.ndarray:
        """f_adc = K_adc^-1 G^-T f: joint friction torques as ADC counts."""
        return self.joint_torques_to_adc(f)

    def friction_to_dac(self, f: np.ndarray) -> np.ndarray:
        """f_dac = K_dac G^-T f: joint friction torques as DAC values."""
        return self.joint_torques_to_dac(f)

    def net_torques(self, v_adc: np.ndarray, f_adc: np.ndarray, t_g: np.ndarray) -> np.ndarray:
        """Net (external) joint torques t_a = G^T K_adc (v_adc - f_adc) - t_g (4.37)."""
        return self.adc_to_joint_torques(_rows(v_adc, self.n, "ADC counts") - _rows(f_adc, self.n, "f_adc")) \
            - _rows(t_g, self.n, "gravity torques")

    def dac_for_net_torques(self, t_a: np.ndarray, t_g: np.ndarray, f_dac: np.ndarray) -> np.ndarray:
        """DAC values (float) giving net joint torques t_a: K_dac G^-T (t_a + t_g) + f_dac (4.38)."""
        return self.joint_torques_to_dac(_rows(t_a, self.n, "net torques") + _rows(t_g, self.n, "gravity torques")) \
            + _rows(f_dac, self.n, "f_dac")
