"""Path deviation in the tool frame (thesis E.2): joint errors -> frame-6 differential (3.1) -> tool frame (1.13).

``deviation(jac6, q_measured - q_planned, t6_to_tool)`` is the differential change
(dx, dy, dz, rx, ry, rz) (m, rad) that carries the planned tool frame to the measured one,
seen in the tool frame. First order in the joint error, as the thesis computes it; the
joint errors a servo leaves are small enough for that (a 5 mm deviation at a 0.2 m lever
gives about 0.06 mm of second-order error).
"""
from __future__ import annotations

import numpy as np


def diff_map_fast(t6_to_tool: np.ndarray) -> np.ndarray:
    """D of 1.13 (the same matrix as ``rccl.transform.diff_map``), built without np.cross: row block
    [R^T, (skew(p) R)^T] over [0, R^T]."""
    r = t6_to_tool[:3, :3]
    px, py, pz = t6_to_tool[:3, 3]
    skew = np.array([[0.0, -pz, py], [pz, 0.0, -px], [-py, px, 0.0]])
    d = np.zeros((6, 6))
    d[:3, :3] = r.T
    d[3:, 3:] = r.T
    d[:3, 3:] = (skew @ r).T
    return d


def diff_map_inverse(t6_to_tool: np.ndarray) -> np.ndarray:
    """D^-1: the map taking a tool-frame differential to the same change seen in frame 6 (closed form)."""
    r = t6_to_tool[:3, :3]
    px, py, pz = t6_to_tool[:3, 3]
    skew = np.array([[0.0, -pz, py], [pz, 0.0, -px], [-py, px, 0.0]])
    d = np.zeros((6, 6))
    d[:3, :3] = r
    d[3:, 3:] = r
    d[:3, 3:] = skew @ r
    return d


class ToolMaps:
    """D, D^-1 and F = D^-T (1.22) of the current tool transform, recomputed only when the tool matrix
    object changes (transforms are replaced, never mutated, so identity is enough)."""

    __slots__ = ("_key", "d", "d_inv", "f")

    def __init__(self) -> None:
        self._key = None
        self.d = self.d_inv = self.f = np.eye(6)

    def of(self, t6_to_tool: np.ndarray) -> "ToolMaps":
        if self._key is not t6_to_tool:
            self._key = t6_to_tool
            self.d = diff_map_fast(t6_to_tool)
            self.d_inv = diff_map_inverse(t6_to_tool)
            self.f = np.ascontiguousarray(self.d_inv.T)
        return self


def deviation(jac6: np.ndarray, dq: np.ndarray, t6_to_tool: np.ndarray) -> np.ndarray:
    """Tool-frame differential (m, rad) of the joint error ``dq`` (rad) at the configuration of ``jac6``."""
    return diff_map_fast(t6_to_tool) @ (jac6 @ dq)


def tool_to_frame6(t6_to_tool: np.ndarray) -> np.ndarray:
    """The 6x6 map taking a tool-frame differential to the same change seen in frame 6 (inverse of D)."""
    return diff_map_inverse(t6_to_tool)
