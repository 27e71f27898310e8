"""The per-cycle collision check: a ``MotionCheck`` that stops a motion about to bring two bodies too close.

``CollisionWatch`` rides on one motion request (``Request.checks``, like 5.4's limits and
monitors: rccl.adaptive.check). The adaptive control level calls ``ends(sample)`` once per
sample while the motion runs; the watch computes every checked pair's distance at the
joints last commanded (``sample.q_command``) and, when a pair is inside the clearance margin
(and closer than when the motion started), raises ``PathCollision``: the control level
then freezes the generator (the arm holds at that command) and the planning level's next
primitive raises a ``TrajectoryFault`` whose ``cause`` is the PathCollision.

This is what guards a motion whose target is defined by a function (5.4.4) or a variable
transform: its path is not known when ``move()`` checks it. The arm stops with every
checked pair at least ``margin`` minus one cycle's commanded motion apart.
"""
from __future__ import annotations

import numpy as np

from ..adaptive.check import Estimate, Sample
from ..ending import MotionEnd
from .path import START_TOL, collision_error
from .world import CollisionWorld


class CollisionWatch:
    """Watch one motion (``where``, e.g. "move(p1)") for a pair closer than ``margin`` m."""

    def __init__(self, world: CollisionWorld, margin: float, where: str) -> None:
        self.world = world
        self.margin = float(margin)
        self.where = where
        self.calls = 0
        self._start: np.ndarray | None = None

    @property
    def estimates(self) -> Estimate:
        """Nothing measured: the check uses the commanded joints."""
        return Estimate.NONE

    def ends(self, s: Sample) -> MotionEnd | None:
        """None while every pair keeps its clearance; raises PathCollision (the arm holds) otherwise."""
        self.calls += 1
        q = s.q_command
        if self._start is None:
            self._start = self.world.distances(q)
        d, k = self.world.nearest(q)
        if d >= self.margin:
            return None
        d_all = self.world.distances(q)
        bad = (d_all < self.margin) & (d_all < self._start - START_TOL)
        if not bad.any():
            return None
        k = int(np.argmin(np.where(bad, d_all, np.inf)))
        raise collision_error(self.world, self.where, k, float(d_all[k]), self.margin, None, s.t, q,
                              f"at trajectory time {s.t:.3f} s (stopped by the per-cycle check; the arm holds)")
