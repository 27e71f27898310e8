"""An RCCL session with adaptive path control (thesis 5.4): ``rccl.adaptive.open(url)`` -> ``AdaptiveArm``.

``AdaptiveArm`` is ``rccl.session.Arm`` (all of move, setvel, ..., waitfor) plus the
primitives of 5.4::

    arm.limit("fz dz", 10.0, 0.005)   # the next motion ends if |fz| > 10 N or |dz| > 5 mm (tool frame)
    arm.evalfn(monitor)               # monitor(sample) runs every sample of the next motion
    arm.add_check(my_check)           # any rccl.adaptive.check.MotionCheck, for the next motion
    arm.comply("fz", -8.0)            # from now on push 8 N along -z of the tool, complying
    arm.lock("fz")                    # stop complying along z
    arm.cond("fz", p_up)              # 5.6.1: if the last move ends on its fz limit, go to p_up instead
    req = arm.move(p); arm.waitfor(req); req.ended   # why it ended (None: it completed)

Its control function reads ``how`` (encoder counts and motor-current ADC values), runs
``AdaptiveControl`` around the ``AdaptiveGenerator``'s step, and issues POS for the
position-servoed joints and CUR for the force-servoed ones.
"""
from __future__ import annotations

from typing import Any, Callable

import numpy as np

from rci import chg as chgmod
from rci import codes

from ..exceptions import MotionError, NotRunning
from ..session import Arm
from .check import MotionCheck, as_check
from .control import AdaptiveControl
from .force import JointModel
from .generator import AdaptiveGenerator
from .limit import Limit
from .monitor import Monitor


class AdaptiveArm(Arm):
    """An RCCL Arm whose generator has the adaptive features of thesis 5.4."""

    def __init__(self, url: str, robot: str = "puma260", **options: Any) -> None:
        if options.get("trajectory", "quartic") != "quartic":
            raise ValueError(f"rccl.adaptive.open: trajectory={options['trajectory']!r}: the adaptive features run "
                             "on the thesis's quartic generator only (the jerk-limited mode is rccl.open's)")
        super().__init__(url, robot, **options)
        self.adaptive = AdaptiveControl(self._kin.module, JointModel.for_robot(robot, self.conv))
        self._q_meas: np.ndarray | None = None
        self.last_command = None
        self._fault_hold = None
        # with record=True: (t, nominal q, commanded q, measured q, {joint: DAC}) per cycle
        self.adaptive_trace: list[tuple] | None = [] if self.trace is not None else None
        self.adc_trace: list[np.ndarray] | None = [] if self.trace is not None else None   # how.adcr per cycle

    # -- 5.4 primitives (planning level) ---------------------------------------------------
    def limit(self, spec: str, *values: float) -> Limit:
        """Force/torque or deviation limits (tool frame, SI) for the next motion only (5.4.1)."""
        lim = Limit.parse(spec, *values)
        self._pending().append(lim)
        return lim

    def evalfn(self, fn: Callable, needs: tuple[str, ...] = ()) -> Monitor:
        """Run ``fn(sample)`` every sample of the next motion; a true return value ends it (5.4.2)."""
        mon = Monitor(fn, tuple(needs))
        self._pending().append(mon)
        return mon

    def add_check(self, check: MotionCheck) -> MotionCheck:
        """Attach any motion check (``rccl.adaptive.check.MotionCheck``) to the next motion only.

        ``limit`` and ``evalfn`` are the thesis's two; several checks on one motion are all
        run, in the order given, and the first to answer ends it.
        """
        self._pending().append(as_check(check, "add_check()"))
        return check

    def comply(self, spec: str, *values: float) -> None:
        """Make tool-frame force/torque components compliant with these values (N, N*m) from now on (5.4.3)."""
        self.adaptive.compliance.comply(spec, *values)

    def lock(self, spec: str) -> None:
        """Take components out of compliance (5.4.3)."""
        self.adaptive.compliance.lock(spec)

    def cond(self, when, position) -> "Request":
        """A conditional motion (5.6.1): if the last moved request ends by ``when``, go to ``position`` instead.

        ``when`` is "limit", "monitor", a component ("fz", "dz"), a monitor name or code, or a
        function of the MotionEnd. The branch uses the current motion parameters. Returns the
        conditional request (``waitfor`` works on it once it runs).
        """
        from dataclasses import replace as _replace

        from ..motion import Request
        from ..position import Position
        from ..conditional import Conditional
        from .exceptions import SpecError

        if self.last is None:
            raise SpecError("cond: no motion to attach a conditional motion to (call move first)")
        if not isinstance(position, Position):
            raise SpecError(f"cond: {position!r} is not a position")
        if self.last.is_conditional:
            raise SpecError("cond: a conditional motion cannot have conditional motions of its own (5.6.1)")
        req = Request(position, position.snapshot(), _replace(self.params), next(self._serial))
        req.is_conditional = True
        if not self.last.attach_conditional(Conditional(when, req), on_attach=position.end.expect):
            raise SpecError(f"cond: the motion to {self.last.position.name} has already ended")
        return req

    def _pending(self) -> list[MotionCheck]:
        if self.gen is None:
            raise NotRunning("RCCL is not running: use rccl.adaptive.open(...)")
        return self.gen.queue.pending

    # -- the control function ----------------------------------------------------------------
    def _cycle(self) -> None:
        how, chg = self.rci.how, self.rci.chg
        gen = self.gen
        q_meas = self.conv.counts_to_angles(np.asarray(how.pos, dtype=float))
        if gen is None:
            if not how.state & codes.CALIB_OK:
                self.control_error = NotRunning(
                    f"{self.url}: the robot is not calibrated (how.state = {how.state:#x}); calibrate it, "
                    "or start simula with -p (ready) or -c (nest)")
                chg.end.issue()
                return
            period = 1.0 / float(how.rate_hz or self.rate_hz)
            self._q_meas = q_meas
            self.gen = AdaptiveGenerator(self._kin, self._limits, period, q_meas)
            return
        qd = (q_meas - self._q_meas) / gen.dt
        self._q_meas = q_meas
        try:
            self.adaptive.before(gen, q_meas, qd, np.asarray(how.adcr[:6], dtype=float), how)
        except MotionError as exc:       # a monitor's error, a force estimate refused: stop the arm, tell the planner
            if gen.faulted is None:
                gen.freeze(exc)
        q_nom = gen.step()
        cmd = None
        if gen.faulted is None:
            try:
                cmd = self.adaptive.after(q_nom)
            except (MotionError, ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
                gen.freeze(exc)
        if cmd is None:     # stopped by a fault: every joint position-servoed where it was when it happened
            if self._fault_hold is None:
                self._fault_hold = self.adaptive.hold(q_meas)
            cmd = self._fault_hold
        else:
            self._fault_hold = None
        self.last_command = cmd
        counts = self.conv.angles_to_counts_int(cmd.q)
        motion = chg.motion
        for i in range(6):
            if i in cmd.current:
                motion[i].issue(chgmod.CUR, cmd.current[i])
            else:
                motion[i].issue(chgmod.POS, int(counts[i]))
        if self.trace is not None:
            self.trace.append((gen.t, q_nom, q_meas))
            self.adaptive_trace.append((gen.t, q_nom, cmd.q, q_meas, dict(cmd.current)))
            self.adc_trace.append(np.array(how.adcr, dtype=np.int64))


def open(url: str, robot: str = "puma260", **options: Any) -> AdaptiveArm:  # noqa: A001 - thesis name rccl_open
    """``rccl_open`` + ``rccl_control`` with the adaptive features: an AdaptiveArm (use in ``with``)."""
    return AdaptiveArm(url, robot, **options).open()
