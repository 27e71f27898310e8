"""Path deviation in the tool frame (thesis E.2): joint errors -> frame-6 differential (3.1) -> tool frame (1.13).

``deviation(jac6, q_measured - q_planned, t6_to_tool)`` is the differential change
(dx, dy, dz, rx, ry, rz) (m, rad) that carries the planned tool frame to the measured one,
seen in the tool frame. First order in the joint error, as the thesis computes it; the
joint errors a servo leaves are small enough for that (a 5 mm deviation at a 0.2 m lever
gives about 0.06 mm of second-order error).
"""
from __future__ import annotations

import numpy as np

from ..transform import diff_map


def deviation(jac6: np.ndarray, dq: np.ndarray, t6_to_tool: np.ndarray) -> np.ndarray:
    """Tool-frame differential (m, rad) of the joint error ``dq`` (rad) at the configuration of ``jac6``."""
    return diff_map(t6_to_tool) @ (jac6 @ dq)


def tool_to_frame6(t6_to_tool: np.ndarray) -> np.ndarray:
    """The 6x6 map taking a tool-frame differential to the same change seen in frame 6 (inverse of D)."""
    return np.linalg.inv(diff_map(t6_to_tool))
