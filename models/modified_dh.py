"""Modified (Craig) Denavit-Hartenberg tables: conversion to the equivalent standard-DH chain.

Craig's convention writes joint i's row as (a_{i-1}, alpha_{i-1}, d_i, theta_i) with the
step from frame i-1 to frame i

    M_i = Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(theta_i) Tz(d_i)

so Craig's frame i sits on joint i's axis. The thesis (eq. 3.3) and everything downstream
use Paul's standard form A_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i), whose frame i sits
on joint i+1's axis. Regrouping the product M_1 ... M_n F (F = Tx(a_n) Tz(d_F), the flange
row, alpha_n = 0) gives the standard table with the same joint axes:

    theta_i, d_i        as in Craig's row i          (d_n gets d_F added)
    a_i, alpha_i        Craig's row i+1's a, alpha   (a_n = the flange's a, alpha_n = 0)

provided Craig's first row has a_0 = alpha_0 = 0 (the base frame is frame 0). Standard
frame i is Craig frame i moved by S_i = Tx(a_i) Rx(alpha_i) (S_n = Tz(d_F) Tx(a_F)): the
same rigid body, so link inertials given in Craig frame i are re-expressed with S_i.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class CraigRow:
    """One row of a modified-DH table: a_{i-1} (m), alpha_{i-1} (rad), d_i (m), theta_i (rad)."""

    a: float
    alpha: float
    d: float
    theta: float


def _tx_rx(a: float, alpha: float) -> np.ndarray:
    """Tx(a) Rx(alpha) as a (4, 4) transform (the two commute)."""
    ca, sa = math.cos(alpha), math.sin(alpha)
    return np.array([[1.0, 0.0, 0.0, a], [0.0, ca, -sa, 0.0], [0.0, sa, ca, 0.0], [0.0, 0.0, 0.0, 1.0]])


def standard_rows(rows: list[CraigRow], flange_a: float, flange_d: float) -> list[tuple[float, float, float, float]]:
    """The standard-DH rows (a_i, alpha_i, d_i, theta_i) equivalent to Craig ``rows`` and the
    flange row (a = ``flange_a``, alpha = 0, d = ``flange_d``); the caller checks a_0 = alpha_0 = 0."""
    n = len(rows)
    out = []
    for i, row in enumerate(rows):
        if i + 1 < n:
            a, alpha, d = rows[i + 1].a, rows[i + 1].alpha, row.d
        else:
            a, alpha, d = flange_a, 0.0, row.d + flange_d
        out.append((a, alpha, d, row.theta))
    return out


def frame_shifts(rows: list[CraigRow], flange_a: float, flange_d: float) -> np.ndarray:
    """S_1..S_n, (n, 4, 4): standard frame i expressed in Craig frame i (metres)."""
    n = len(rows)
    out = np.empty((n, 4, 4))
    for i in range(n):
        if i + 1 < n:
            out[i] = _tx_rx(rows[i + 1].a, rows[i + 1].alpha)
        else:
            out[i] = _tx_rx(flange_a, 0.0)
            out[i, 2, 3] = flange_d
    return out


def move_inertial(shift: np.ndarray, com: np.ndarray, inertia: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A centre of mass (m) and an inertia about it (kg m^2), given in Craig frame i, expressed
    in standard frame i = Craig frame i * ``shift``: com' = R^T (com - p), I' = R^T I R."""
    r, p = shift[:3, :3], shift[:3, 3]
    return r.T @ (np.asarray(com, float) - p), r.T @ np.asarray(inertia, float) @ r
