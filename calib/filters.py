"""Digital filters of the dynamics identification, in numpy: a zero-phase Butterworth low-pass
and a first-order lag, along the first axis of any array (time first).

The Butterworth low-pass of order 2k is k second-order sections (bilinear transform with the
cut-off prewarped; section i has Q = 1 / (2 cos((2i + 1) pi / 4k))), run forward and then
backward over the signal (zero phase, the magnitude squared). Each end is padded with the
signal's odd reflection over ``PAD_S`` seconds, long enough for the sections' start-up to die
out before the signal begins (at 4 Hz the slowest section settles in about 0.2 s).
"""
from __future__ import annotations

import numpy as np

PAD_S = 1.0


def butterworth_sections(order: int, cutoff_hz: float, rate_hz: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """(b, a) of each second-order section of the low-pass (``order`` even), a[0] = 1."""
    if order % 2 or order <= 0:
        raise ValueError(f"butterworth_sections: order {order} must be even and positive")
    if not 0 < cutoff_hz < rate_hz / 2:
        raise ValueError(f"butterworth_sections: cut-off {cutoff_hz} Hz must lie below half the rate {rate_hz} Hz")
    k = order // 2
    w0 = 2 * np.pi * cutoff_hz / rate_hz
    out = []
    for i in range(k):
        q = 1.0 / (2 * np.cos((2 * i + 1) * np.pi / (4 * k)))
        alpha = np.sin(w0) / (2 * q)
        c = np.cos(w0)
        b = np.array([(1 - c) / 2, 1 - c, (1 - c) / 2])
        a = np.array([1 + alpha, -2 * c, 1 - alpha])
        out.append((b / a[0], a / a[0]))
    return out


def _section(x: np.ndarray, b: np.ndarray, a: np.ndarray) -> np.ndarray:
    """One section (direct form II transposed) along axis 0, started at rest at x[0]'s level."""
    y = np.empty_like(x)
    gain = b.sum() / a.sum()
    z1 = (b[1] + b[2] - (a[1] + a[2]) * gain) * x[0]
    z2 = (b[2] - a[2] * gain) * x[0]
    for n in range(len(x)):
        yn = b[0] * x[n] + z1
        z1 = b[1] * x[n] - a[1] * yn + z2
        z2 = b[2] * x[n] - a[2] * yn
        y[n] = yn
    return y


def zero_phase_lowpass(x: np.ndarray, order: int, cutoff_hz: float, rate_hz: float) -> np.ndarray:
    """``x`` (N, ...) through the Butterworth low-pass forward and backward (module docstring)."""
    x = np.asarray(x, float)
    pad = min(len(x) - 1, int(round(PAD_S * rate_hz)))
    head = 2 * x[:1] - x[pad:0:-1]
    tail = 2 * x[-1:] - x[-2:-pad - 2:-1]
    y = np.concatenate([head, x, tail])
    sections = butterworth_sections(order, cutoff_hz, rate_hz)
    for b, a in sections:
        y = _section(y, b, a)
    y = y[::-1]
    for b, a in sections:
        y = _section(y, b, a)
    return y[::-1][pad:pad + len(x)]


def first_order_lag(x: np.ndarray, alpha: float, start: np.ndarray) -> np.ndarray:
    """y[n] = alpha y[n-1] + (1 - alpha) x[n] along axis 0, y[-1] = ``start``."""
    x = np.asarray(x, float)
    y = np.empty_like(x)
    prev = np.asarray(start, float).reshape(x.shape[1:])
    for n in range(len(x)):
        prev = alpha * prev + (1 - alpha) * x[n]
        y[n] = prev
    return y
