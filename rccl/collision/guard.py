"""Collision checking switched on for an arm: what ``move()`` calls (``arm.collisions(...)``).

A ``CollisionGuard`` holds the arm's ``CollisionWorld``, the clearance margin and which
motions get the per-cycle watch; the planning level (rccl.planner.Planner) calls
``check_plan`` on every move's checked plan before queueing it, and ``watch_for`` to attach
the per-cycle ``CollisionWatch`` to the request.
"""
from __future__ import annotations

from ..exceptions import BadRequest
from ..limits import Limits
from ..motion import Request
from ..segments import Kinematics, Plan, is_static
from .path import check_samples, path_joints
from .watch import CollisionWatch
from .world import CollisionWorld

#: which motions get the per-cycle check: those with a functional or variable transform, every one, none
EVERY_CYCLE = ("functional", "all", "none")


class CollisionGuard:
    """The world, the clearance ``margin`` (m, > 0) and the per-cycle choice (one of ``EVERY_CYCLE``)."""

    def __init__(self, world: CollisionWorld, margin: float, every_cycle: str = "functional") -> None:
        if not (isinstance(margin, (int, float)) and margin > 0):
            raise BadRequest(f"collisions: margin={margin!r} must be a clearance > 0 m (e.g. 0.01)")
        if every_cycle not in EVERY_CYCLE:
            raise BadRequest(f"collisions: every_cycle={every_cycle!r} is not one of {EVERY_CYCLE}")
        self.world = world
        self.margin = float(margin)
        self.every_cycle = every_cycle
        self.samples_checked = 0        # path samples checked by the last move (read-out)

    def check_plan(self, req: Request, plan: Plan, kin: Kinematics, limits: Limits) -> None:
        """Raise PathCollision if ``plan``'s path brings a pair inside the margin (planning level)."""
        fractions, qs = path_joints(self.world, self.margin, kin, limits, req, plan)
        self.samples_checked = len(fractions)
        check_samples(self.world, self.margin, req, plan, fractions, qs)

    def watch_for(self, req: Request) -> CollisionWatch | None:
        """The per-cycle watch this request gets, or None."""
        if self.every_cycle == "all" or (self.every_cycle == "functional" and not is_static(req)):
            return CollisionWatch(self.world, self.margin, f"move({req.position.name})")
        return None
