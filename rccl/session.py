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

from .exceptions import NotRunning, PowerOff
from .limits import Limits, for_link, load_limits
from .planner import Planner
from .position import Position, joint_position
from .segments import Kinematics
from .trajectory import TrajectoryGenerator

# the predefined `park` position: the model's named pose of this name (estimate there)
PARK_POSE = "ready"


def load_kinematics(robot: str) -> Kinematics:
    """The generated kinematics module of ``robot`` (rccl.kinematics.<robot>), wrapped for RCCL.

    Raises ValueError naming the robots there are (a data file each in models/) for an unknown
    name, or saying that the robot's kinematics have not been generated (``make derive``).
    """
    from models import available_robots

    known = available_robots()
    if not isinstance(robot, str) or robot not in known:
        raise ValueError(f"robot={robot!r}: no such robot; known: {', '.join(known)} (models/ROBOT.toml)")
    try:
        return Kinematics(importlib.import_module(f"rccl.kinematics.{robot}"))
    except ModuleNotFoundError:
        raise ValueError(f"robot={robot!r}: no generated kinematics (rccl/kinematics/{robot}.py); "
                         "run `make derive`") from None


class Arm(Planner):
    """One robot under RCCL control: the planning-level primitives plus open/close.

    Attributes: ``park`` (a Position), ``rci`` (the RCI Session), ``gen`` (the trajectory
    generator, running at the control level), ``rate_hz``. ``trajectory`` picks the generator:
    "quartic" (the thesis's, default) or "ruckig" (jerk-limited, ``rccl.jerk``).
    """

    def __init__(self, url: str, robot: str = "puma260", *, rate_hz: int = 36,
                 kinematics: Kinematics | None = None, limits: Limits | None = None,
                 record: bool = False, trajectory: str = "quartic", **rci_options: Any) -> None:
        if trajectory not in ("quartic", "ruckig"):
            raise ValueError(f"rccl.open: trajectory={trajectory!r} is not 'quartic' (the thesis's, default) "
                             "or 'ruckig' (jerk-limited, rccl.jerk)")
        self.trajectory = trajectory
        self.url = url
        self.robot = robot
        self.rate_hz = int(rate_hz)
        self._kin = kinematics or load_kinematics(robot)
        self._limits = limits or load_limits(robot)
        self._jerk = None
        if trajectory == "ruckig":   # check the limits here, before anything opens (rccl/jerk.py)
            from .jerk import JerkLimits
            self._jerk = JerkLimits.from_limits(self._limits)
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
            self.rci.close_quietly(power_off=False)
            raise
        Planner.__init__(self, self._kin, self._limits, self.gen, fault_check=lambda: self.rci.wait(0))
        self.park = joint_position("park", self._kin, load_robot(self.robot).poses[PARK_POSE])
        return self

    @property
    def kinematics(self):
        """The kinematics module RCCL plans with (rccl.kinematics.<robot>, or a calibrated one)."""
        return self._kin

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
            # plans whose rounded counts RCI's R_REQVEL check accepts
            self._limits = for_link(self._limits, self.conv.rounding_step(), period)
            if self.trajectory == "ruckig":
                from .jerk import JerkLimitedGenerator
                gen = JerkLimitedGenerator(self._kin, self._limits, period, q0, jerk=self._jerk)
            else:
                gen = TrajectoryGenerator(self._kin, self._limits, period, q0)
            self.gen = gen
            return
        if not how.power:            # the brakes hold the arm: follow them, end any motion
            gen.follow_unpowered(self.conv.counts_to_angles(np.asarray(how.pos, dtype=float)))
        q = gen.step()
        self.conv.command_positions(chg, q)
        if self.trace is not None:
            self.trace.append((gen.t, q, self.conv.counts_to_angles(np.asarray(how.pos, dtype=float))))

    # -- arm power (thesis A.4 power_on / power_off) ------------------------------------------
    @property
    def powered(self) -> bool:
        """True while the robot reports the arm's power on (``how``)."""
        return bool(self.rci.how.power)

    def power_on(self, timeout: float = 2.0) -> None:
        """Switch the arm's power on and wait until the robot reports it (at most ``timeout`` s).

        The arm starts holding where its brakes kept it. Raises PowerOff if the robot does not
        report power within ``timeout`` (e.g. an emergency stop is pressed).
        """
        self.check()
        if self.powered:
            return
        with self.rci.chg.lock:
            self.rci.chg.power_on.issue()
        if not self.rci.wait(timeout, until=lambda: self.powered):
            raise PowerOff(f"{self.url}: power_on(): the robot did not report power on within {timeout} s "
                           f"(how.state = {self.rci.how.state:#x})")

    def power_off(self, timeout: float = 2.0) -> None:
        """Switch the arm's power off (the brakes hold it) and wait until the robot reports it.

        A motion still running ends with a fault (PowerOff; ``recover()`` clears it); moves are
        refused until ``power_on()``.
        """
        self.check()
        with self.rci.chg.lock:
            self.rci.chg.power_off.issue()
        if not self.rci.wait(timeout, until=lambda: not self.powered):
            raise PowerOff(f"{self.url}: power_off(): the robot still reports power on after {timeout} s")

    def move(self, position: Position) -> Request:
        """Planner.move, refused with PowerOff while the arm's power is off (it would not turn)."""
        self.check()
        if not self.powered:
            raise PowerOff(f"move({getattr(position, 'name', position)!r}): the arm's power is off, "
                           "it would not move; call arm.power_on() first")
        return Planner.move(self, position)

    def close(self, power_off: bool = False, wait: bool = True) -> None:
        """rccl_close: wait for queued motions to end (``wait``), release the control and close the link."""
        try:
            if wait and self.gen is not None and self.gen.faulted is None and self.rci.in_control:
                self.rci.wait(None, until=lambda: not self.gen.busy or self.gen.faulted is not None)
        finally:
            self.rci.close_quietly(power_off)

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
