"""Synthetic runs with known truth for the calib unit tests (no simulator involved)."""
from __future__ import annotations

import numpy as np

from rcci.calib.drive import Drive
from rcci.calib.trace import Trace

DEG = np.pi / 180

# Appendix D and Table 4.1, written out here only as the synthetic truth of the tests.
G = np.zeros((6, 6))
G[np.diag_indices(6)] = [-46.72, 69.9733, -42.9867, -43.5111, 39.3846, 31.7692]
G[4, 3], G[5, 3], G[5, 4] = -9.8462, 1.0, -6.9424
R = np.zeros((6, 6))
R[np.diag_indices(6)] = [-7435.72, 11136.60, -6841.55, 5540.00, 5014.60, 4044.98]
R[4, 3], R[5, 3], R[5, 4] = -1253.65, 127.32, -713.01
AMPS = 0.00111 / np.array([0.301, 0.300, 0.302, 0.821, 0.821, 0.816])
SIGMA = np.array([0.0732, 0.0751, 0.0786, 0.0358, 0.0349, 0.0305])


def drive(sigma: np.ndarray = SIGMA, lag: float = 0.0) -> Drive:
    """The synthetic drive; the synthetic currents are unfiltered unless a test filters
    them, hence no current lag by default."""
    return Drive(R=R, G=G, amps_per_adc=AMPS, sigma=np.asarray(sigma, float), current_lag=lag)


def regressor(q: np.ndarray) -> np.ndarray:
    """Thesis 4.24 (as printed) in the columns (c12, c13, c15)."""
    s, c = np.sin, np.cos
    t1, t2, t3, t4, t5, t6 = q
    s23, c23 = s(t2 + t3), c(t2 + t3)
    Y = np.zeros((6, 3))
    w = c23 * c(t4) * s(t5) + c(t5) * s23
    Y[1] = [c(t2), s23, w]
    Y[2] = [0.0, s23, w]
    Y[3] = [0.0, 0.0, -s23 * s(t4) * s(t5)]
    Y[4] = [0.0, 0.0, c23 * s(t5) + c(t4) * c(t5) * s23]
    return Y


def sweep(q_fixed: np.ndarray, joint: int, lo: float, hi: float, speeds: list[float],
          rate: float = 36.0, margin: float = 5 * DEG) -> tuple[np.ndarray, np.ndarray]:
    """Back-and-forth constant-speed motion of one joint: (t, q) with q (N,6)."""
    segs_t, segs_q, t0 = [], [], 0.0
    for v in speeds:
        for a, b in ((lo - margin, hi + margin), (hi + margin, lo - margin)):
            n = max(int(abs(b - a) / v * rate), 2)
            th = np.linspace(a, b, n, endpoint=False)
            segs_t.append(t0 + np.arange(n) / rate)
            t0 += n / rate
            q = np.tile(q_fixed, (n, 1))
            q[:, joint] = th
            segs_q.append(q)
    return np.concatenate(segs_t), np.vstack(segs_q)


def to_trace(t: np.ndarray, q: np.ndarray, tau: np.ndarray, meta: dict, d: Drive,
             rng: np.random.Generator, adc_noise: float = 0.5, path: str = "synthetic.log") -> Trace:
    """Encode joint angles and torques as counts and ADC readings, with noise."""
    counts = np.round(q @ d.R.T)
    motor_torque = tau @ np.linalg.inv(d.G)
    adc = motor_torque / d.sigma / d.amps_per_adc + adc_noise * rng.standard_normal(tau.shape)
    return Trace(path=path, robot="puma260", rate_hz=36.0, meta=meta, t=t,
                 counts=counts, adc=adc)


def friction_torque(qd: np.ndarray, fc_plus, fc_minus, fv_plus, fv_minus) -> np.ndarray:
    """4.27 for moving joints (N m), elementwise over (N,6) joint rates."""
    return np.where(qd > 0, fc_plus + fv_plus * qd,
                    np.where(qd < 0, -fc_minus + fv_minus * qd, 0.0))


def write_rcilog(path: str, trace: Trace, robot: str = "puma260") -> str:
    """Write a synthetic Trace as a real recorder log (rci.recorder), ADC rounded to
    the 12-bit integers the controller reports."""
    from rci.how import How
    from rci.recorder import Recorder

    with Recorder(path, robot=robot, nj=6, nadc=16, rate_hz=int(trace.rate_hz),
                  meta=trace.meta) as rec:
        for k in range(len(trace.t)):
            adc = np.zeros(16, dtype=np.int64)
            adc[:6] = np.clip(np.round(trace.adc[k]), -2047, 2047)
            how = How(pos=trace.counts[k].astype(np.int64), adcr=adc, cycle=k,
                      time_ns=int(round(trace.t[k] * 1e9)), rate_hz=int(trace.rate_hz))
            rec.append(how, None)
            if k % 512 == 511:
                rec.flush()
    return path
