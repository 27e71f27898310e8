"""The trajectory generator with RCCL's adaptive hooks (thesis 5.4, 5.4.5, E.2): a subclass, not a rewrite.

``AdaptiveGenerator`` adds to ``rccl.trajectory.TrajectoryGenerator``:

* ``abort(end)``: end the running motion at the next sample (a limit or a monitor fired).
  The request is finished with ``hooks["ended"] = end`` (its position's ``end`` event is
  signalled, so ``waitfor`` returns) and the arm leaves its path at once: the remaining
  motion is replaced by the straight joint-space continuation of the arm's present
  position and velocity, which the ordinary quartic transition then brings to the next
  queued request, or to rest as fast as the acceleration limits allow if none is queued;
* functional transforms called once per sample across the segments in play, with the
  change per sample limited through the Jacobian (``functional.FunctionalUpdater``);
* conditional motions (5.6.1): an ended request whose ``hooks["conditional"]`` has a
  branch matching its end runs that branch next and drops the rest of the queue;
* Figure 5.4: when a segment whose destination was modified during the motion (a
  functional or variable transform) ends, the transition starts from the arm's actual
  position and velocity instead of the planned corner, fitting the actual path to the
  planned one.
"""
from __future__ import annotations

import numpy as np

from ..motion import MotionParams, Request
from ..position import joint_position
from ..queue import MotionQueue
from ..trajectory import ACC_PEAK, Segment, TrajectoryGenerator
from ..exceptions import MotionError
from .conditional import choose
from .ending import MotionEnd
from .functional import FunctionalUpdater


class HookQueue(MotionQueue):
    """The motion queue, attaching the adaptive settings made since the last ``move`` to the next request."""

    def __init__(self) -> None:
        super().__init__()
        self.pending: dict = {}

    def put(self, item) -> None:
        if self.pending:
            item.hooks.update(self.pending)
            self.pending = {}
        super().put(item)


class AdaptiveGenerator(TrajectoryGenerator):
    """TrajectoryGenerator + abort on limit/monitor, once-per-sample limited functional transforms, Fig. 5.4 exits."""

    def __init__(self, kin, limits, dt, q0, queue: MotionQueue | None = None) -> None:
        super().__init__(kin, limits, dt, q0, queue if queue is not None else HookQueue())
        self.functional = FunctionalUpdater(limits.joint_velocity, dt, qdd_max=limits.joint_acceleration)
        self.jac6: np.ndarray | None = None     # frame-6 Jacobian where the arm is; set per sample by the caller
        self.jac6_inv: np.ndarray | None = None  # its inverse, if the caller has it
        self.jac6_cond: float | None = None      # cond_1 of jac6, if the caller has it (with jac6_inv)
        self.ended: list[tuple[Request, MotionEnd]] = []
        self._abort: MotionEnd | None = None

    # -- the planning of an early exit ----------------------------------------------------
    def abort(self, end: MotionEnd) -> None:
        """End the running motion at the next ``step`` (control level), recording ``end``."""
        self._abort = end

    def step(self) -> np.ndarray:
        if self._abort is not None and self.faulted is None:
            end, self._abort = self._abort, None
            self._end_now(end)
        tr = self.trans
        q = super().step()
        if tr is not None and self.trans is not tr and tr.prev.req.status in ("done", "failed"):
            tr.prev.req.hooks.setdefault("finished_t", self.t)    # when its transition ended (s)
        return q

    def _velocity(self) -> np.ndarray:
        return (self.q - self.q_prev) / self.dt

    def _end_now(self, end: MotionEnd) -> None:
        seg, tr = self.seg, self.trans
        req = seg.req
        if tr is not None and tr.prev.req.status == "running":
            tr.prev.req.finish()
        self.trans = None
        v = self._velocity()
        tau = max(self.dt, float(np.max(ACC_PEAK * np.abs(v) / self.limits.joint_acceleration)))
        stop = joint_position("stop", self.kin, self.q + v * tau)
        stop_req = Request(stop, stop.snapshot(), MotionParams(mode="joint"), repeat=True, status="running")
        self.seg = self._continuation(stop_req, v, tau, seg)
        if not req.repeat and req.status == "running":
            req.hooks["ended"] = end
            req.hooks["finished_t"] = self.t
            self.ended.append((req, end))
            req.finish()
            branch = choose(req.hooks.get("conditional", []), end)
            if branch is not None:   # 5.6.1: the pruned tree; everything else queued is dropped
                for dropped in self.queue.clear():
                    dropped.hooks["dropped_by"] = req
                    dropped.finish(MotionError(f"{dropped.position.name}: not run, the conditional motion to "
                                               f"{branch.request.position.name} was chosen ({end})"))
                req.hooks["chosen"] = branch.request
                MotionQueue.put(self.queue, branch.request)

    def _continuation(self, req: Request, v: np.ndarray, tau: float, like: Segment) -> Segment:
        """A joint-mode segment through the present command q at velocity v, its corner tau seconds ahead."""
        s = Segment(req, self.kin)
        T = max(2.0 * tau, self.dt)
        b = self.q + v * tau
        s.mode, s.static, s.stationary = "joint", True, not np.any(v)
        s.T, s.t0, s.tau_in, s.tau_out = T, self.t + tau - T, 0.0, tau
        s.q_dest, s.x_dest, s.dq = b, self.kin.fk(b), -v * T
        s.tool, s.tool_inv, s.config = like.tool, like.tool_inv, self.kin.config_of(self.q)
        s.d, s.k, s.theta = np.zeros(3), np.array([0.0, 0.0, 1.0]), 0.0
        s.v_end, s.v_cart = v, None
        return s

    # -- hooks into the base generator ----------------------------------------------------
    def _update_functional(self) -> None:
        positions = [self.seg.req.position]
        if self.trans is not None:
            positions.append(self.trans.prev.req.position)
        jac6 = self.jac6 if self.jac6 is not None else (lambda: self.kin.module.jacobian6(self.q))
        have = self.jac6 is not None
        self.functional.update(positions, jac6, self.seg.req.snap, self.jac6_inv if have else None,
                               self.jac6_cond if have else None)

    def _begin_transition(self) -> None:
        seg = self.seg
        if not seg.static:
            # Figure 5.4: leave a modified segment from where the arm really is, at its real velocity
            self.seg = self._continuation(seg.req, self._velocity(), seg.tau_out, seg)
        super()._begin_transition()
