"""The trajectory generator with RCCL's adaptive hooks (thesis 5.4, 5.4.5, 5.6.1, E.2): a subclass, not a rewrite.

``AdaptiveGenerator`` adds to ``rccl.trajectory.TrajectoryGenerator`` (which already ends a
motion early on ``abort(end)`` or a request's ``watch``):

* functional transforms called once per sample across the segments in play, with the
  change per sample limited through the Jacobian (``functional.FunctionalUpdater``);
* conditional motions (5.6.1): a request ended early whose ``conditional`` has a
  branch matching its end runs that branch next and drops the rest of the queue;
* Figure 5.4: when a segment whose destination was modified during the motion (a
  functional or variable transform) ends, the transition starts from the arm's actual
  position and velocity instead of the planned corner, fitting the actual path to the
  planned one.
"""
from __future__ import annotations

import numpy as np

from ..ending import MotionEnd
from ..exceptions import MotionError
from .check import MotionCheck, as_check
from ..motion import Request
from ..queue import MotionQueue
from ..trajectory import TrajectoryGenerator
from ..conditional import choose
from .functional import FunctionalUpdater


class HookQueue(MotionQueue):
    """The motion queue, attaching the motion checks made since the last ``move`` to the next request (5.4.1, 5.4.2)."""

    def __init__(self) -> None:
        super().__init__()
        self.pending: list[MotionCheck] = []

    def put(self, item) -> None:
        if self.pending:
            item.checks.extend(as_check(c, "a check for the next motion") for c in self.pending)
            self.pending = []
        super().put(item)


class AdaptiveGenerator(TrajectoryGenerator):
    """TrajectoryGenerator + conditional motions, once-per-sample limited functional transforms, Fig. 5.4 exits."""

    def __init__(self, kin, limits, dt, q0, queue: MotionQueue | None = None) -> None:
        super().__init__(kin, limits, dt, q0, queue if queue is not None else HookQueue())
        self.functional = FunctionalUpdater(limits.joint_velocity, dt, qdd_max=limits.joint_acceleration)
        self.jac6: np.ndarray | None = None     # frame-6 Jacobian where the arm is; set per sample by the caller
        self.jac6_inv: np.ndarray | None = None  # its inverse, if the caller has it
        self.jac6_cond: float | None = None      # cond_1 of jac6, if the caller has it (with jac6_inv)

    # -- 5.6.1: what follows a motion ended early ------------------------------------------
    def _ended_early(self, req: Request, end: MotionEnd) -> None:
        branch = choose(req.conditionals(), end)    # Request.attach_conditional: none lost at the end
        if branch is not None:   # 5.6.1: the pruned tree; everything else queued is dropped
            for dropped in self.queue.clear():
                dropped.dropped_by = req
                dropped.finish(MotionError(f"{dropped.position.name}: not run, the conditional motion to "
                                           f"{branch.request.position.name} was chosen ({end})"))
            req.chosen = branch.request
            MotionQueue.put(self.queue, branch.request)

    # -- hooks into the base generator ----------------------------------------------------
    def _update_functional(self) -> None:
        positions = [self.seg.req.position]
        if self.trans is not None:
            positions.append(self.trans.prev.req.position)
        jac6 = self.jac6 if self.jac6 is not None else (lambda: self.kin.module.jacobian6(self.q))
        have = self.jac6 is not None
        self.functional.update(positions, jac6, self.seg.req.snap, self.jac6_inv if have else None,
                               self.jac6_cond if have else None)

    def _begin_transition(self, req: Request | None = None, now: float | None = None) -> None:
        seg = self.seg
        if not seg.static:
            # Figure 5.4: leave a modified segment from where the arm really is, at its real velocity
            self.seg = self._continuation(seg.req, self._velocity(), seg.tau_out, seg)
        super()._begin_transition(req, now)
