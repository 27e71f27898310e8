"""The drive-train conversions a fit needs (thesis 4.28-4.36): counts to angles, ADC to torque.

calib keeps the torque sensitivity sigma separate from the rest of K_adc (4.32,
k_adc = V_g sigma / R_i) because Table 4.1 is what the first fit measures: the ADC
reading times V_g / R_i is the motor current (A), and only sigma turns it into torque.
The constants come from the runtime's own conversion module (rci.conversions) when a
robot is named, so calib and the controller can never disagree about them.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np


FILTER_TAU = 0.015      # s, current-sense low-pass (Appendix C)
SERVO_PERIOD = 0.001    # s, joint microcontroller period (Appendix C: 1000 Hz)
# Half a millisecond matters: on joint 2 every 1 ms of unaccounted lag reads as 6e-3
# N m s/rad of viscous friction (gravity's torque shifted along the path by v x lag).


@dataclass(frozen=True)
class Drive:
    """Linear maps between raw readings and joint quantities (SI units).

    R: encoder counts per radian (n,n), lower triangular (coupled wrist), e = R theta + e0
      (n the robot's joints: 6, or 7 for the Panda; the arrays below are sized alike).
    G: motor shaft angle per joint angle (n,n), theta_s = G theta.
    amps_per_adc: V_g / R_i per channel (A per ADC count).
    sigma: torque sensitivity per motor (N m / A), Table 4.1.
    current_lag: delay (s) of the ADC readings behind the joint angle they describe:
      the time constant of the Appendix C filter (15 ms) plus half the joint servo's
      period (the 1 kHz PID computes each tick's current from the position at the tick's
      start and holds it for the tick, a zero-order hold that lags by half a tick).
    """

    R: np.ndarray
    G: np.ndarray
    amps_per_adc: np.ndarray
    sigma: np.ndarray
    encoder_offset: np.ndarray | None = None     # (n,) counts; None: zero
    current_lag: float = FILTER_TAU + SERVO_PERIOD / 2

    def current_angles(self, t: np.ndarray, counts: np.ndarray) -> np.ndarray:
        """Joint angles (rad), (N,n), where the joints were when the ADC readings of the
        same records were formed: ``current_lag`` s earlier.

        The current-sense filter of Appendix C is a first-order low-pass of 15 ms; for a
        slowly varying current its output lags the input by the time constant.  Pairing
        each reading with the angle at the time it describes keeps the lag from turning a
        position-dependent torque (gravity on joints 2 and 3) into a speed-dependent one,
        which the friction fit would read as viscous friction.
        """
        theta = self.joint_angles(counts)
        if self.current_lag == 0.0:
            return theta
        t = np.asarray(t, dtype=float)
        back = t - self.current_lag
        return np.column_stack([np.interp(back, t, theta[:, j]) for j in range(theta.shape[1])])

    def joint_angles(self, counts: np.ndarray) -> np.ndarray:
        """Joint angles (rad), (N,n), from encoder counts (N,n) (4.30)."""
        e = np.asarray(counts, dtype=float)
        if self.encoder_offset is not None:
            e = e - self.encoder_offset
        return np.linalg.solve(self.R, e.T).T

    def motor_angles(self, theta: np.ndarray) -> np.ndarray:
        """Motor shaft angles (rad), (N,n), from joint angles (4.28)."""
        return np.asarray(theta, dtype=float) @ self.G.T

    def motor_currents(self, adc: np.ndarray) -> np.ndarray:
        """Motor currents (A), (N,n), from ADC readings (Appendix C, 4.32)."""
        return np.asarray(adc, dtype=float) * self.amps_per_adc

    def joint_torques(self, adc: np.ndarray) -> np.ndarray:
        """Joint torques (N m), (N,n): t_j = G^T K_adc v_adc (4.31, 4.36)."""
        motor_torque = self.motor_currents(adc) * self.sigma
        return motor_torque @ self.G

    def with_sigma(self, sigma: np.ndarray) -> "Drive":
        """The same drive with other torque sensitivities (e.g. fitted ones)."""
        return replace(self, sigma=np.asarray(sigma, dtype=float))
