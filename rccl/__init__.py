"""RCCL, the Robot Control C Library of thesis chapter 5, in Python: Cartesian motion on top of RCI.

    import rccl
    from rccl import T6, EQ, TL, Trsf, makeposition
    with rccl.open("socket://127.0.0.1:7600", robot="puma260") as arm:
        t = Trsf.trsl("T", 0.15, 0.15, 0.197)
        r = Trsf.rot("B", "y", math.pi)
        p0 = makeposition("P0", t, T6, EQ, r, TL, T6)
        arm.setvel(0.1, math.radians(100))
        arm.move(p0)
        arm.move(arm.park)
        arm.waitfor(arm.park.end)

Every arm has the adaptive primitives of 5.4 too (``arm.limit``, ``arm.evalfn``, ``arm.comply``,
``arm.cond``, ...: docs/adaptive.md), whichever trajectory generator runs
(``rccl.open(url, trajectory="quartic")``, the thesis's, default; or ``"ruckig"``, jerk-limited);
both implement ``rccl.generator.MotionGenerator``.

docs/rccl.md maps every RCCL primitive of the thesis to its Python spelling.
"""
from __future__ import annotations

from .exceptions import (BadRequest, CollisionFileError, ConfigurationChange, ConstTransformError, MotionError, NotRunning,
                         PathCollision, PowerOff, PositionError, RCCLError, SingularPath, TrajectoryFault, TransformError,
                         UnreachableTarget)
from .position import EQ, TL, Position, joint_position, makeposition
from .sync import Event
from .transform import (T6, Trsf, gentr_eul, gentr_noap, gentr_rot, gentr_rpy, gentr_trsl, t6, xunit, yunit,
                        zunit)


def open(url: str, robot: str = "puma260", **options):  # noqa: A001 - thesis name rccl_open
    """``rccl_open`` + ``rccl_control``: see ``rccl.session.open``."""
    from .session import open as _open
    return _open(url, robot, **options)


__all__ = [
    "open", "makeposition", "joint_position", "Position", "EQ", "TL", "T6", "t6", "Trsf", "Event",
    "xunit", "yunit", "zunit", "gentr_trsl", "gentr_rot", "gentr_rpy", "gentr_eul", "gentr_noap", "RCCLError", "TransformError", "ConstTransformError", "PositionError",
    "MotionError", "BadRequest", "UnreachableTarget", "SingularPath", "ConfigurationChange", "TrajectoryFault",
    "NotRunning", "PowerOff", "PathCollision", "CollisionFileError",
]
