"""The drive transform of a Cartesian segment (thesis E.3-E.5): Drive(lam) = Trans(lam d) Rot(k, lam theta).

Linear in [1, cos(lam theta), sin(lam theta), lam] (Rodrigues), so a segment precomputes a
(4, 16) basis once and each sample (or each checked path point) is one small product.
"""
from __future__ import annotations

import math

import numpy as np


def drive_basis(d: np.ndarray, k: np.ndarray) -> np.ndarray:
    """Drive(lam) = Trans(lam d) Rot(k, lam theta) (E.3-E.5) as [1, cos(lam theta), sin(lam theta), lam] @ basis.

    Rodrigues: Rot(k, a) = k k^T + cos a (I - k k^T) + sin a [k]x, so the drive transform is
    linear in those four numbers; returns the (4, 16) basis (four flattened 4x4 matrices).
    """
    kx, ky, kz = k.tolist()
    dx, dy, dz = d.tolist()
    xx, xy, xz, yy, yz, zz = kx * kx, kx * ky, kx * kz, ky * ky, ky * kz, kz * kz
    return np.array([
        [xx, xy, xz, 0.0, xy, yy, yz, 0.0, xz, yz, zz, 0.0, 0.0, 0.0, 0.0, 1.0],                   # k k^T (+ the 1)
        [1.0 - xx, -xy, -xz, 0.0, -xy, 1.0 - yy, -yz, 0.0, -xz, -yz, 1.0 - zz, 0.0, 0.0, 0.0, 0.0, 0.0],  # I - k k^T
        [0.0, -kz, ky, 0.0, kz, 0.0, -kx, 0.0, -ky, kx, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],              # [k]x
        [0.0, 0.0, 0.0, dx, 0.0, 0.0, 0.0, dy, 0.0, 0.0, 0.0, dz, 0.0, 0.0, 0.0, 0.0]])             # d


def drive(d: np.ndarray, k: np.ndarray, theta: float, lam: float) -> np.ndarray:
    """Drive transform Trans(lam d) Rot(k, lam theta) (E.3-E.5), 4x4."""
    a = lam * theta
    return (np.array([1.0, math.cos(a), math.sin(a), lam]) @ drive_basis(d, k)).reshape(4, 4)


def drive_coefficients(theta: float, lams: np.ndarray) -> np.ndarray:
    """Rows [1, cos(lam theta), sin(lam theta), lam] for each lam (N, 4)."""
    out = np.empty((lams.size, 4))
    out[:, 0] = 1.0
    a = lams * theta
    np.cos(a, out=out[:, 1])
    np.sin(a, out=out[:, 2])
    out[:, 3] = lams
    return out
