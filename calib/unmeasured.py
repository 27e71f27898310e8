"""Joints whose torque calib does not measure from their motor currents, and why: the thesis's
own exclusion, which every current-based measurement (friction, sensitivity, breakaway) and the
dynamics fit follow. The thesis measured the PUMA only, "since the mechanical gearing on the
Microbo's prismatic joints make force control and measurement using joint torques impractical"
(chapter 1; again in 4.1)."""
from __future__ import annotations

#: robot -> (joints, 1-based; the reason)
TORQUE_UNMEASURED: dict[str, tuple[tuple[int, ...], str]] = {
    "microbo": ((2, 3), "the Microbo's prismatic joints 2 and 3: \"the mechanical gearing on the Microbo's "
                        "prismatic joints make force control and measurement using joint torques impractical\" "
                        "(thesis, chapter 1)"),
}


def unmeasured_joints(robot: str) -> tuple[int, ...]:
    """Joints (1-based) of ``robot`` whose torque calib does not measure."""
    return TORQUE_UNMEASURED.get(robot, ((), ""))[0]


def why_unmeasured(robot: str, joint: int | None = None) -> str | None:
    """Why (None: ``joint``, or with None every joint, is measured)."""
    joints, why = TORQUE_UNMEASURED.get(robot, ((), ""))
    if not joints or (joint is not None and joint not in joints):
        return None
    return why
