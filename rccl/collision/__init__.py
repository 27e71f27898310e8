"""Collision-aware motion (issue 28, item 4): capsules on the links, environment obstacles, path and per-cycle checks.

    with rccl.open(url, robot="puma260") as arm:
        arm.collisions(env=["plane:z=-0.30"], margin=0.01)
        arm.move(p)            # PathCollision (before anything moves) if the path comes too close

Modules: ``geometry`` (the file models/collision/<robot>.toml), ``world`` (Pinocchio/coal
model of capsules and obstacles), ``path`` (the planned-path check), ``watch`` (the per-cycle
check), ``guard`` (what ``move()`` calls). docs/collision.md describes the whole.
"""
from __future__ import annotations

from .geometry import LinkBox, Capsule, CollisionGeometry, geometry_path, load_geometry
from .guard import EVERY_CYCLE, CollisionGuard
from .watch import CollisionWatch
from .world import CollisionWorld, ShapePose, shape_poses

__all__ = ["LinkBox", "Capsule", "CollisionGeometry", "geometry_path", "load_geometry", "CollisionGuard", "EVERY_CYCLE",
           "CollisionWatch", "ShapePose", "CollisionWorld", "shape_poses"]
