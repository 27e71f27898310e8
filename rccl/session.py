"""An RCCL session: the trajectory generator running as an RCI control function (thesis 5.1, 5.3.4).

``rccl.open(url, robot="puma260")`` is ``rccl_open`` + ``rccl_control``: it opens an RCI
session on the robot link (``socket://host:port`` for simula, a serial device or pty for a
robot), starts the control with the trajectory generator as its control function, and
returns an ``Arm`` that carries the planning-level primitives (move, setvel, settime,
setmod, setconf, stop, waitfor) and the predefined position ``park``. Leaving the ``with``
block (or ``arm.close()``) is ``rccl_close``: it waits for the queued motions to finish,
releases the control and closes the session.

Each sample the control function reads nothing but time from ``how`` (RCCL is a position
generator; the adaptive features of 5.4 will read ``how`` too), asks the generator for the
joint angles, converts them to encoder counts (``rci.conversions``) and issues one POS
command per joint in ``chg``.
"""
from __future__ import annotations

import importlib
from typing import Any

import numpy as np

from rci import chg as chgmod
from rci import codes
from rci.conversions import Conversions
from rci.session import Session

from .exceptions import NotRunning
from .limits import Limits, load_limits
from .planner import Planner
from .position import Position, joint_position
from .trajectory import Kinematics, TrajectoryGenerator

# the predefined `park` position: the model's named pose of this name (estimate there)
PARK_POSE = "ready"


def load_kinematics(robot: str) -> Kinematics:
    """The generated kinematics module of ``robot`` (rccl.kinematics.<robot>), wrapped for RCCL."""
    return Kinematics(importlib.import_module(f"rccl.kinematics.{robot}"))


class Arm(Planner):
    """One robot under RCCL control: the planning-level primitives plus open/close.

    Attributes: ``park`` (a Position), ``rci`` (the RCI Session), ``gen`` (the trajectory
    generator, running at the control level), ``rate_hz``.
    """

    def __init__(self, url: str, robot: str = "puma260", *, rate_hz: int = 36,
                 kinematics: Kinematics | None = None, limits: Limits | None = None,
                 record: bool = False, **rci_options: Any) -> None:
        self.url = url
        self.robot = robot
        self.rate_hz = int(rate_hz)
        self._kin = kinematics or load_kinematics(robot)
        self._limits = limits or load_limits(robot)
        self.conv = Conversions.for_robot(robot)
        self.rci = Session(url, robot, rate_hz=self.rate_hz, **rci_options)
        self.gen: TrajectoryGenerator | None = None
        self.park: Position | None = None
        self._pos_cmd = [chgmod.POS] * 6
        self.control_error: BaseException | None = None
        # with record=True: one (t s, commanded q rad, measured q rad) per control cycle
        self.trace: list[tuple[float, np.ndarray, np.ndarray]] | None = [] if record else None

    # -- rccl_open / rccl_control / rccl_close --------------------------------------------
    def open(self) -> "Arm":
        """Open the RCI session and start the trajectory generator as its control function."""
        from models import load_robot

        self.rci.open()
        try:
            self.rci.control(self._cycle)
            self.rci.wait(5.0, until=lambda: self.gen is not None or self.control_error is not None)
            if self.control_error is not None:
                raise self.control_error
            if self.gen is None:
                raise NotRunning(f"{self.url}: the control did not start (no HOW received)")
        except BaseException:
            self.rci._close_quietly(power_off=False)
            raise
        Planner.__init__(self, self._kin, self._limits, self.gen, fault_check=lambda: self.rci.wait(0))
        self.park = joint_position("park", self._kin, load_robot(self.robot).poses[PARK_POSE])
        return self

    def _cycle(self) -> None:
        """The RCI control function: one trajectory sample, as POS commands in encoder counts."""
        how, chg = self.rci.how, self.rci.chg
        gen = self.gen
        if gen is None:
            if not how.state & codes.CALIB_OK:
                self.control_error = NotRunning(
                    f"{self.url}: the robot is not calibrated (how.state = {how.state:#x}); calibrate it, "
                    "or start simula with -p (ready) or -c (nest)")
                chg.end.issue()
                return
            q0 = self.conv.counts_to_angles(np.asarray(how.pos, dtype=float))
            period = 1.0 / float(how.rate_hz or self.rate_hz)
            gen = TrajectoryGenerator(self._kin, self._limits, period, q0)
            self.gen = gen
            return
        q = gen.step()
        counts = self.conv.angles_to_counts_int(q)
        motion = chg.motion
        for i in range(6):
            motion[i].issue(chgmod.POS, int(counts[i]))
        if self.trace is not None:
            self.trace.append((gen.t, q, self.conv.counts_to_angles(np.asarray(how.pos, dtype=float))))

    def close(self, power_off: bool = False, wait: bool = True) -> None:
        """rccl_close: wait for queued motions to end (``wait``), release the control and close the link."""
        try:
            if wait and self.gen is not None and self.gen.faulted is None and self.rci.in_control:
                self.rci.wait(None, until=lambda: not self.gen.busy or self.gen.faulted is not None)
        finally:
            self.rci._close_quietly(power_off)

    def __enter__(self) -> "Arm":
        return self if self.gen is not None else self.open()

    def __exit__(self, exc_type, exc, tb) -> None:
        self.close(power_off=False, wait=exc_type is None)

    def check(self) -> None:
        """Deliver RCI terminations and trajectory faults; refuse primitives once the control has ended."""
        Planner.check(self)
        if not self.rci.in_control:
            raise NotRunning(f"{self.url}: RCCL's control is not running (closed or released)")

    # -- read-out ---------------------------------------------------------------------
    @property
    def q(self) -> np.ndarray:
        """Last commanded joint angles (rad)."""
        if self.gen is None:
            raise NotRunning("RCCL is not running: use rccl.open(...)")
        return self.gen.q.copy()

    @property
    def t6(self) -> np.ndarray:
        """Last commanded T6 (base to link 6, 4x4, m)."""
        return self._kin.fk(self.q)

    def measured_q(self) -> np.ndarray:
        """Joint angles (rad) of the latest ``how`` (what the robot reports)."""
        return self.conv.counts_to_angles(np.asarray(self.rci.how.pos, dtype=float))


def open(url: str, robot: str = "puma260", **options: Any) -> Arm:  # noqa: A001 - thesis name rccl_open
    """``rccl_open`` + ``rccl_control``: an Arm with the trajectory generator running (use in ``with``)."""
    return Arm(url, robot, **options).open()
