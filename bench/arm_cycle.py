"""The whole RCCL control function (``rccl.session.Arm._cycle``) timed per cycle without a link.

``Arm._cycle`` is what ``rccl.open`` gives RCI as the control function of every arm,
whichever generator runs: HOW's encoder counts to joint angles, the adaptive control's
``before`` (checks, estimates, compliance), the generator's ``step()``, the adaptive
control's ``after`` (the command) and the command to CHG in counts. Here an ``Arm`` is
built but never opened (its RCI session holds the ``how`` and ``chg`` records and no
link); each cycle this module writes a synthetic HOW into ``arm.rci.how`` (untimed): the
robot follows its commands, so the encoder counts are last cycle's POS commands plus
-1..1 count of noise, the motor ADC channels read the gravity torques there plus one count
of noise, power on, calibrated, the rate unchanged. Then ``arm._cycle()`` is timed with
``time.thread_time_ns`` (CPU time of the calling thread), and CHG is cleared as the
control task does once it has sent it.

Attached features (to every motion of the tour, through the Arm's own primitives):
``none``; ``force limit``: ``arm.limit("fx fy fz", ...)`` (net torques 4.37, the tool
force 4.56 through J6^-1 with its condition check 4.57, the limit vetted once per motion
against the estimate's error bar); ``monitor``: ``arm.evalfn(fn)`` with a function that
watches the net joint torques (4.37).

A second, instrumented pass over the same tour splits each cycle: the generator's step,
the adaptive control (``before`` + ``after``) and the rest (conversions, bookkeeping),
each timed inside the cycle by wrapping the three calls on the instance.
"""
from __future__ import annotations

import gc
import time
from typing import Callable

import numpy as np

from rci import codes
from rccl.adaptive.force import gravity_vector
from rccl.planner import Planner
from rccl.position import Position
from rccl.session import Arm

FEATURES = ("none", "force limit", "monitor")
# force limit: bounds (N) far above what the free-air estimate reads on this tour, so the tour runs on
FORCE_LIMIT_N = 200.0
# monitor: end the motion if a net joint torque (N*m) exceeds this (never on this tour)
MONITOR_TORQUE_NM = 50.0


def torque_watch(s) -> int | None:
    """A typical monitor function (5.4.2): termination code 1 when a net joint torque is too large."""
    return 1 if float(np.abs(s.torque).max()) > MONITOR_TORQUE_NM else None


class _UnlinkedArm(Arm):
    """An ``Arm`` whose planning level does not ask for a running RCI control (there is no link).

    Only ``check`` differs, and only at the planning level: the control function is Arm's own.
    """

    def check(self) -> None:
        Planner.check(self)


class LinklessArm:
    """An ``Arm`` started on synthetic HOW records, its planning level used without the link.

    The bench calls ``arm._cycle`` itself: that private method is the control function Arm
    hands RCI (``rci.control(self._cycle)``), and timing it as it is is the point here.

    ``robot``, ``trajectory`` ("quartic" or "ruckig"), ``mode`` ("joint" or "cartesian"),
    ``q0`` the start joint angles (rad), ``rate_hz`` the rate the HOWs report (Hz).
    """

    def __init__(self, robot: str, trajectory: str, mode: str, q0: np.ndarray, rate_hz: int, seed: int = 0) -> None:
        arm = _UnlinkedArm(f"linkless:{robot}", robot, rate_hz=rate_hz, trajectory=trajectory, signals=False)
        self.arm = arm
        self.rng = np.random.default_rng(seed)
        self.period_ns = int(round(1e9 / rate_hz))
        self._gravity = gravity_vector(arm.kinematics.module, arm.adaptive.model.gravity_coeffs)
        how = arm.rci.how
        how.state = codes.CALIB_OK | codes.POWER_ON
        how.rate_hz = rate_hz
        self._write_how(np.asarray(q0, dtype=float), arm.conv.angles_to_counts_int(q0))
        arm._cycle()                         # the start-up cycle: the generator, at rest at q0
        if arm.gen is None:
            raise RuntimeError(f"{robot}: the control function did not start on the synthetic HOW: "
                               f"{arm.control_error}")
        Planner.__init__(arm, arm.kinematics, arm.gen.limits, arm.gen)   # as Arm.open does
        arm.setmod(mode)
        arm.setvel(0.1, 1.0)

    def _write_how(self, q: np.ndarray, counts: np.ndarray) -> None:
        how = self.arm.rci.how
        how.pos = counts
        adc = self.arm.conv.joint_torques_to_adc(self.arm.kinematics.module.gravity(q, self._gravity))
        how.adcr[:6] = np.rint(adc + self.rng.normal(0.0, 1.0, 6)).astype(np.int64)
        how.cycle += 1
        how.time_ns += self.period_ns

    def next_how(self) -> None:
        """This cycle's HOW: last cycle's POS commands (counts) plus noise; CHG cleared (sent)."""
        arm = self.arm
        chg = arm.rci.chg
        counts = np.array([m.value for m in chg.motion], dtype=np.int64) + self.rng.integers(-1, 2, 6)
        chg.clear()
        self._write_how(arm.conv.counts_to_angles(counts.astype(float)), counts)

    def queue(self, positions: list[Position], feature: str) -> None:
        """The tour's positions, each motion with ``feature`` attached (the planning level, untimed)."""
        arm = self.arm
        for p in positions:
            if feature == "force limit":
                arm.limit("fx fy fz", FORCE_LIMIT_N, FORCE_LIMIT_N, FORCE_LIMIT_N)
            elif feature == "monitor":
                arm.evalfn(torque_watch)
            elif feature != "none":
                raise ValueError(f"feature {feature!r}: not one of {', '.join(FEATURES)}")
            arm.move(p)


def _timed(fn: Callable, acc: list[int], clock: Callable[[], int]) -> Callable:
    """``fn`` (called with positional arguments only) wrapped to add its CPU time (ns) into ``acc[0]``."""
    def wrapper(*args):
        t0 = clock()
        r = fn(*args)
        acc[0] += clock() - t0
        return r
    return wrapper


def run(robot: str, trajectory: str, mode: str, feature: str, positions_of: Callable, q0: np.ndarray,
        rate_hz: int, cycles: int, split: bool = False) -> dict:
    """Time ``cycles`` calls of the control function on the tour ``positions_of(kin)``, us per cycle.

    ``split``: also time the step and the adaptive control inside each cycle (instrumented).
    """
    la = LinklessArm(robot, trajectory, mode, q0, rate_hz)
    arm = la.arm
    positions = positions_of(arm.kinematics)
    clock = time.thread_time_ns
    total = np.empty(cycles)
    step = np.zeros(cycles)
    adaptive = np.zeros(cycles)
    in_step, in_adaptive = [0], [0]        # this cycle's ns, summed by the wrappers
    gen, ctl = arm.gen, arm.adaptive
    if split:
        gen.step = _timed(gen.step, in_step, clock)
        ctl.before = _timed(ctl.before, in_adaptive, clock)
        ctl.after = _timed(ctl.after, in_adaptive, clock)
    cycle = arm._cycle
    # the first cycle of each motion: its before() sees a request the previous cycle's did not (the
    # motion's checks are set up there: a force limit is vetted against the estimate's error bar)
    first = np.zeros(cycles, dtype=bool)
    seen = gen.request
    gc.disable()
    try:
        for k in range(cycles):
            if len(arm.queue) < 2:
                la.queue(positions, feature)
            la.next_how()
            req = gen.request
            first[k], seen = req is not None and req is not seen, req
            in_step[0] = in_adaptive[0] = 0
            t0 = clock()
            cycle()
            total[k] = clock() - t0
            step[k], adaptive[k] = in_step[0], in_adaptive[0]
    finally:
        gc.enable()
    if arm.control_error is not None or gen.errors or gen.faulted is not None:
        raise SystemExit(f"{trajectory} {mode} {feature}: the control function failed: "
                         f"{arm.control_error or gen.faulted or gen.errors[:3]}")
    if gen.ended:    # the figures are for a tour that runs to its end
        raise SystemExit(f"{trajectory} {mode} {feature}: a motion of the tour ended early: "
                         f"{[str(end) for _, end in gen.ended[:2]]}")
    us = total / 1e3
    row = {"robot": robot, "trajectory": trajectory, "mode": mode, "feature": feature, "cycles": cycles,
           "mean": float(us.mean()), "median": float(np.median(us)), "p99": float(np.percentile(us, 99)),
           "max": float(us.max()), "firsts": int(first.sum())}
    if split:
        s_us, a_us = step / 1e3, adaptive / 1e3
        rest = us - s_us - a_us
        for name, arr in (("step", s_us), ("adaptive", a_us), ("rest", rest), ("beyond_step", us - s_us)):
            row[f"{name}_median"] = float(np.median(arr))
            row[f"{name}_p99"] = float(np.percentile(arr, 99))
        row["adaptive_other_p99"] = float(np.percentile(a_us[~first], 99))
        row["adaptive_first_median"] = float(np.median(a_us[first])) if first.any() else float("nan")
    return row


def clock_pair_ns(n: int = 20000) -> float:
    """The median cost (ns) of two back-to-back ``time.thread_time_ns`` reads: what one timed interval adds."""
    clock = time.thread_time_ns
    out = np.empty(n)
    for i in range(n):
        t0 = clock()
        out[i] = clock() - t0
    return float(np.median(out))
