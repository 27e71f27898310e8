"""The tapered pass mean (rcci.calib.work.tapered_mean): a position-dependent friction seen
through the current filter of Appendix C no longer shifts with speed."""
from __future__ import annotations

import numpy as np

from rcci.calib.work import find_passes, hann_edge_weights, tapered_mean, window_work

TAU = 0.015        # s, the current-sense filter
H = 0.001          # s, servo tick
LO, HI = -0.96, 0.96


def _pass(speed: float) -> tuple[np.ndarray, np.ndarray]:
    """One + pass at ``speed`` rad/s through [LO, HI] read every tick: angles (lagged by
    the filter's time constant, as calib pairs them) and filtered torque (N m)."""
    margin = 0.3
    t = np.arange(0.0, (HI - LO + 2 * margin) / speed, H)
    th = LO - margin + speed * t
    # Coulomb friction with a gear pattern of a few spatial harmonics (Table 4.4 style)
    tau = 0.18 * (1 + 0.1 * (0.3 * np.sin(5 * th + 1) + 0.3 * np.sin(11 * th + 2)
                             + 0.2 * np.sin(23 * th + 0.5) + 0.2 * np.sin(41 * th + 3)))
    y = np.empty_like(tau)
    acc, a = tau[0], 1 - np.exp(-H / TAU)
    for k, x in enumerate(tau):
        acc += a * (x - acc)
        y[k] = acc
    th_lagged = np.interp(t - TAU, t, th)
    return th_lagged, y


def test_hann_edges_rise_from_zero_to_one():
    th = np.linspace(LO - 0.1, HI + 0.1, 1001)
    w = hann_edge_weights(th, LO, HI, 0.3)
    assert w[0] == 0 and w[-1] == 0 and w.max() == 1.0
    assert np.all(w[(th > LO + 0.3) & (th < HI - 0.3)] == 1.0)


def test_tapered_mean_does_not_move_with_speed_but_the_plain_one_does():
    plain, tapered = [], []
    for v in (0.1, 1.0, 2.0, 4.0):
        th, y = _pass(v)
        (p,) = find_passes(th, LO, HI)
        plain.append(window_work(th, y, p, LO, HI) / (HI - LO))
        tapered.append(tapered_mean(th, y, p, LO, HI, 0.3))
    plain, tapered = np.array(plain), np.array(tapered)
    # from 0.1 to 4 rad/s the plain window mean drifts by 4e-4 of itself (0.02e-3 N m s/rad
    # of false slope on joint 5, half its Table 4.3 bound; other patterns give more); the
    # tapered one by under 1e-4, what is left being the filter's second-order smear
    assert np.ptp(plain) / 0.18 > 3e-4
    assert np.ptp(tapered) / 0.18 < 1e-4
    assert np.ptp(tapered) < 0.25 * np.ptp(plain)
