"""An RCCL session: the trajectory generator running as an RCI control function (thesis 5.1, 5.3.4, 5.4).

``rccl.open(url, robot="puma260")`` is ``rccl_open`` + ``rccl_control``: it opens an RCI
session on the robot link (``socket://host:port`` for simula, a serial device or pty for a
robot), starts the control with the trajectory generator as its control function, and
returns an ``Arm`` that carries the planning-level primitives (move, setvel, settime,
setmod, setconf, stop, waitfor), the adaptive ones of 5.4 (limit, evalfn, add_check,
comply, lock, cond), the servo mode of the next motions (``feedforward``: position, or current
mode with gravity-only or computed-torque feed-forward, ``rccl.feedforward``) and the
predefined position ``park``, whichever generator runs
(``trajectory="quartic"``, the thesis's, or ``"ruckig"``, jerk-limited): both implement
``rccl.generator.MotionGenerator``. Leaving the ``with`` block (or ``arm.close()``) is
``rccl_close``: it waits for the queued motions to finish, releases the control and closes
the session.

Each sample the control function (one start-up and one cycle for every arm) reads ``how``:
the robot's rate (``how.rate_hz`` is the rate at which the robot executes the CHG that
answers this HOW, so a change takes effect for the generator in the same cycle as for the
robot), the encoder counts and motor-current ADC values; runs the adaptive control
(``rccl.adaptive.control``) around the generator's step, and issues POS for the
position-servoed joints and CUR for the force-servoed ones (or, for a feed-forward motion,
CUR for every joint: ``rccl.feedforward.FeedForwardControl``). The generator's limits are the
arm's less what encoder rounding adds at the running rate (``rccl.limits.for_link``), so
the counts sent never trip RCI's R_REQVEL check.
"""
from __future__ import annotations

from dataclasses import replace
from typing import Any, Callable

import numpy as np

from rci import chg as chgmod
from rci import codes
from rci.conversions import Conversions
from rci.session import Session

from .adaptive.check import MotionCheck, as_check
from .adaptive.control import AdaptiveControl, Command
from .adaptive.force import JointModel
from .adaptive.limit import Limit
from .adaptive.monitor import Monitor
from .conditional import Conditional
from .exceptions import BadRequest, MotionError, NotRunning, PowerOff
from .feedforward import FeedForward, FeedForwardControl, Gains, make as make_feedforward
from .limits import Limits, for_link, load_limits
from .motion import Request
from .planner import Planner
from .position import Position, joint_position
from .generator import MotionGenerator, check_kind
from .jerk import JerkLimitedGenerator, JerkLimits
from .kinematics import load
from .segments import Kinematics
from .trajectory import TrajectoryGenerator

# the predefined `park` position: the model's named pose of this name (estimate there)
PARK_POSE = "ready"


def load_kinematics(robot: str) -> Kinematics:
    """The generated kinematics module of ``robot`` (rccl.kinematics.<robot>), wrapped for RCCL.

    Raises ValueError (rccl.kinematics.KinematicsNotFound) naming the robots there are for an
    unknown name, or saying that the robot's kinematics have not been generated (``make derive``).
    """
    return Kinematics(load(robot))


def make_generator(kind: str, kin: Kinematics, limits: Limits, dt: float, q0: np.ndarray,
                   jerk=None) -> MotionGenerator:
    """A generator of ``kind`` ("quartic" or "ruckig") at rest at joints ``q0`` (rad), samples ``dt`` s apart."""
    if check_kind(kind) == "ruckig":
        return JerkLimitedGenerator(kin, limits, dt, q0, jerk=jerk)
    return TrajectoryGenerator(kin, limits, dt, q0)


class Arm(Planner):
    """One robot under RCCL control: the planning-level and adaptive primitives plus open/close.

    Attributes: ``park`` (a Position), ``rci`` (the RCI Session), ``gen`` (the trajectory
    generator, a ``rccl.generator.MotionGenerator``, running at the control level),
    ``adaptive`` (the per-sample adaptive control), ``rate_hz`` (the rate the generator runs
    at). ``trajectory`` picks the generator: "quartic" (the thesis's, default) or "ruckig"
    (jerk-limited, ``rccl.jerk``). With ``record=True``: ``trace`` holds (t s, nominal q
    rad, measured q rad) per cycle, ``adaptive_trace`` (t, nominal q, commanded q, measured
    q, {joint: DAC}), ``adc_trace`` (how.adcr) and ``clock_trace`` (the robot's clock, s) too.
    """

    def __init__(self, url: str, robot: str = "puma260", *, rate_hz: int = 36,
                 kinematics: Kinematics | None = None, limits: Limits | None = None,
                 record: bool = False, trajectory: str = "quartic", **rci_options: Any) -> None:
        self.trajectory = check_kind(trajectory)
        self.url = url
        self.robot = robot
        self.rate_hz = int(rate_hz)
        self._kin = kinematics or load_kinematics(robot)
        self._arm_limits = limits or load_limits(robot)    # the model's; the generator's follow the rate
        self._limits = self._arm_limits
        self._jerk = None
        if trajectory == "ruckig":   # check the limits here, before anything opens (rccl/jerk.py)
            self._jerk = JerkLimits.from_limits(self._limits)
        self.conv = Conversions.for_robot(robot)
        self.adaptive = AdaptiveControl(self._kin.module, JointModel.for_robot(robot, self.conv))
        self.ff_control = FeedForwardControl(self.adaptive.model)   # current-mode feed-forward (rccl.feedforward)
        self._ff: FeedForward | None = None      # the servo mode of the motion running (None: position)
        self.rci = Session(url, robot, rate_hz=self.rate_hz, **rci_options)
        self.gen: MotionGenerator | None = None
        self.park: Position | None = None
        self.control_error: BaseException | None = None
        self.last_command: Command | None = None
        self._q_meas: np.ndarray | None = None
        self._last_dt = 1.0 / self.rate_hz      # the period over which the last two HOWs' positions differ
        self._fault_hold: Command | None = None
        self.rate_changes: list[tuple[float, int]] = []   # (trajectory time s, new rate Hz) as the generator saw them
        self.trace: list[tuple[float, np.ndarray, np.ndarray]] | None = [] if record else None
        self.adaptive_trace: list[tuple] | None = [] if record else None
        self.adc_trace: list[np.ndarray] | None = [] if record else None
        self.clock_trace: list[float] | None = [] if record else None     # how.time_ns per cycle, in s

    # -- rccl_open / rccl_control / rccl_close --------------------------------------------
    def open(self) -> "Arm":
        """Open the RCI session and start the trajectory generator as its control function."""
        from rcci.models import load_robot

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

    def _link_limits(self, rate: float) -> Limits:
        """The arm's limits less what rounding to encoder counts adds to a step at ``rate`` Hz."""
        return for_link(self._arm_limits, self.conv.rounding_step(), 1.0 / float(rate))

    def _start(self, how, chg, q_meas: np.ndarray) -> None:
        """The first cycle (one start-up for every arm and generator): the generator, at rest at ``q_meas``."""
        if not how.state & codes.CALIB_OK:
            self.control_error = NotRunning(
                f"{self.url}: the robot is not calibrated (how.state = {how.state:#x}); calibrate it, "
                "or start simula with -p (ready) or -c (nest)")
            chg.end.issue()
            return
        rate = int(how.rate_hz or self.rate_hz)
        self._limits = self._link_limits(rate)
        self.rate_hz = rate
        self._q_meas = q_meas
        self._last_dt = 1.0 / rate
        self.gen = make_generator(self.trajectory, self._kin, self._limits, 1.0 / rate, q_meas, jerk=self._jerk)

    def _change_rate(self, gen: MotionGenerator, rate: int) -> None:
        """The robot executes this cycle's CHG at ``rate`` Hz: the generator steps by its period from now on."""
        limits = self._link_limits(rate)
        gen.set_period(1.0 / rate, limits)
        self._limits = self.limits = limits      # the planning level checks new paths with them too
        self.rate_hz = rate
        self.rate_changes.append((gen.t, rate))

    def _cycle(self) -> None:
        """The RCI control function: measure, check, one generator sample, the command in counts/DAC."""
        how, chg = self.rci.how, self.rci.chg
        gen = self.gen
        q_meas = self.conv.counts_to_angles(np.asarray(how.pos, dtype=float))
        if gen is None:
            self._start(how, chg, q_meas)
            return
        qd = (q_meas - self._q_meas) / self._last_dt
        self._q_meas = q_meas
        rate = how.rate_hz
        if rate and rate != self.rate_hz:
            self._change_rate(gen, int(rate))
        self._last_dt = gen.dt
        if not how.power:            # the brakes hold the arm: follow them, end any motion
            gen.follow_unpowered(q_meas)
        try:
            self.adaptive.before(gen, q_meas, qd, np.asarray(how.adcr[: len(q_meas)], dtype=float), how)
        except MotionError as exc:       # a monitor's error, a force estimate refused: stop the arm, tell the planner
            if gen.faulted is None:
                gen.freeze(exc)
        q_nom = gen.step()
        cmd = None
        if gen.faulted is None:
            try:
                cmd = self.adaptive.after(q_nom)
                ff = self._servo_mode(gen)
                if ff is not None and how.power:
                    cmd = self.ff_control.command(ff, gen.t, cmd.q, q_meas, qd)
                else:
                    self.ff_control.observe(gen.t, cmd.q)
            except (MotionError, ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
                gen.freeze(exc)
        if cmd is None:     # stopped by a fault: every joint position-servoed (compliance, feed-forward off)
            self.ff_control.reset()
            if self._fault_hold is None:
                forced = self.last_command is not None and bool(self.last_command.current)
                held = self.adaptive.hold(q_meas)     # where it was measured, after force servoing
                self._fault_hold = held if forced else Command(gen.q.copy())   # else the frozen command
            cmd = self._fault_hold
        else:
            self._fault_hold = None
        self.last_command = cmd
        if cmd.current:
            counts = self.conv.angles_to_counts_int(cmd.q)
            motion = chg.motion
            for i in range(len(motion)):
                if i in cmd.current:
                    motion[i].issue(chgmod.CUR, cmd.current[i])
                else:
                    motion[i].issue(chgmod.POS, int(counts[i]))
        else:
            self.conv.command_positions(chg, cmd.q)
        if self.trace is not None:
            self.trace.append((gen.t, q_nom, q_meas))
            self.adaptive_trace.append((gen.t, q_nom, cmd.q, q_meas, dict(cmd.current)))
            self.adc_trace.append(np.array(how.adcr, dtype=np.int64))
            self.clock_trace.append(how.time_ns * 1e-9)

    def _servo_mode(self, gen: MotionGenerator) -> FeedForward | None:
        """The feed-forward of the motion in progress (kept while the arm rests between motions)."""
        req = gen.request
        if req is not None:
            ff = req.params.feedforward
            self._ff = ff if ff is not None and ff.current else None
        return self._ff

    # -- feed-forward (rccl.feedforward), per motion like setvel --------------------------------
    def feedforward(self, mode: str = "computed", theta=None, gains: Gains | None = None,
                    rotor=None) -> FeedForward:
        """The servo mode of the motions moved after this call: "position" (POS, default), "gravity"
        (CUR: t_g + friction + PD) or "computed" (CUR: D qdd + c + t_g + friction of the planned motion + PD).

        ``theta``: a base-parameter vector (``kinematics.BASE_PARAMETERS`` order, a mapping of
        those names, or the path of the parameter file ``calib fit dynamics`` wrote: the identified
        model) instead of the data file's inertials; ``rotor``: the motor rotors at the joints
        (kg*m^2, (n,) or (n, n)) with the data file's inertials. ``gains``: ``rccl.feedforward.Gains``
        (natural frequency Hz, damping ratio). Refused while compliance is on (both would set the
        joints' currents). docs/adaptive.md, "Feed-forward".
        """
        ff = make_feedforward(self._kin.module, mode, theta, gains, rotor)
        if ff.current:
            ff.gains.check_rate(self.rate_hz, f"feedforward({mode!r})")
            if self.adaptive.compliance.forces:
                axes = sorted(self.adaptive.compliance.forces)
                raise BadRequest(f"feedforward({mode!r}): compliance is on (axes {axes}); a joint cannot be "
                                 "force-servoed and torque-fed at once: lock() them first")
        self.params.feedforward = ff if ff.current else None
        return ff

    def _refuse_with_feedforward(self, what: str) -> None:
        ff = self.params.feedforward
        if ff is not None and ff.current:
            raise BadRequest(f"{what}: the next motions run feed-forward in current mode ({ff.mode!r}); {what} "
                             "would set the same joints' currents: call arm.feedforward('position') first")

    # -- 5.4 primitives (planning level), the same for every generator ------------------------
    def limit(self, spec: str, *values: float) -> Limit:
        """Force/torque or deviation limits (tool frame, SI) for the next motion only (5.4.1)."""
        return self.add_check(Limit.parse(spec, *values))

    def evalfn(self, fn: Callable, needs: tuple[str, ...] = ()) -> Monitor:
        """Run ``fn(sample)`` every sample of the next motion; a true return value ends it (5.4.2)."""
        return self.add_check(Monitor(fn, tuple(needs)))

    def add_check(self, check: MotionCheck) -> MotionCheck:
        """Attach any motion check (``rccl.adaptive.check.MotionCheck``) to the next motion only.

        ``limit`` and ``evalfn`` are the thesis's two; several checks on one motion are all
        run, in the order given, and the first to answer ends it.
        """
        as_check(check, "add_check()")
        if self.gen is None:
            raise NotRunning("RCCL is not running: use rccl.open(...)")
        self.gen.queue.pending.append(check)
        return check

    def comply(self, spec: str, *values: float) -> None:
        """Make tool-frame force/torque components compliant with these values (N, N*m) from now on (5.4.3)."""
        self._refuse_with_feedforward(f"comply({spec!r})")
        if self._ff is not None and self.gen is not None and self.gen.busy:
            raise BadRequest(f"comply({spec!r}): a motion in feed-forward current mode ({self._ff.mode!r}) is "
                             "running; wait for it, then call arm.feedforward('position')")
        self.adaptive.compliance.comply(spec, *values)

    def lock(self, spec: str) -> None:
        """Take components out of compliance (5.4.3)."""
        self.adaptive.compliance.lock(spec)

    def cond(self, when, position: Position) -> Request:
        """A conditional motion (5.6.1): if the last moved request ends by ``when``, go to ``position`` instead.

        ``when`` is "limit", "monitor", a component ("fz", "dz"), a monitor name or code, or a
        function of the MotionEnd. The branch uses the current motion parameters. Returns the
        conditional request (``waitfor`` works on it once it runs).
        """
        from .adaptive.exceptions import SpecError

        if self.last is None:
            raise SpecError("cond: no motion to attach a conditional motion to (call move first)")
        if not isinstance(position, Position):
            raise SpecError(f"cond: {position!r} is not a position")
        if self.last.is_conditional:
            raise SpecError("cond: a conditional motion cannot have conditional motions of its own (5.6.1)")
        req = Request(position, position.snapshot(), replace(self.params), next(self._serial))
        req.is_conditional = True
        if not self.last.attach_conditional(Conditional(when, req), on_attach=position.end.expect):
            raise SpecError(f"cond: the motion to {self.last.position.name} has already ended")
        return req

    # -- collision checking (issue 28; rccl.collision, docs/collision.md) -----------------------
    def collisions(self, env: list[str] | tuple[str, ...] = (), margin: float = 0.01,
                   every_cycle: str = "functional", geometry: str | None = None):
        """Check every later move for collisions; returns the ``rccl.collision.CollisionGuard``.

        ``env``: simula's ``--env`` words (``plane:z=-0.3``, ``box:x0=..,z1=..``) as obstacles
        fixed in the base frame; ``margin``: the clearance (m) every checked pair must keep;
        ``every_cycle``: "functional" (motions with a functional or variable transform also
        get a per-cycle check), "all" or "none"; ``geometry``: another geometry file than
        models/collision/<robot>.toml. A move whose planned path comes closer raises
        ``PathCollision`` before it is queued; a per-cycle check stops the arm (it holds) and
        the next primitive raises a TrajectoryFault whose ``cause`` is the PathCollision.
        ``arm.collisions_off()`` ends the checking.
        """
        from .collision import CollisionGuard, CollisionWorld
        from .exceptions import BadRequest, CollisionFileError

        if self.gen is None:
            raise NotRunning("RCCL is not running: use rccl.open(...)")
        if isinstance(env, str):
            raise BadRequest(f"collisions(env={env!r}): give a list of environment words, e.g. [{env!r}]")
        try:
            world = CollisionWorld(self.robot, tuple(env), geometry)
        except CollisionFileError:
            raise
        except ValueError as exc:          # a bad environment word (rci.simula.environment names it)
            raise BadRequest(f"collisions(env={list(env)!r}): {exc}") from None
        self.collision_guard = CollisionGuard(world, margin, every_cycle)
        return self.collision_guard

    def collisions_off(self) -> None:
        """Stop checking later moves for collisions (motions already queued keep their per-cycle checks)."""
        self.collision_guard = None

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
        self._vet_feedforward(getattr(position, "name", position))
        return Planner.move(self, position)

    def _vet_feedforward(self, name) -> None:
        """Refuse, before it is queued, a feed-forward motion with compliance or a force/torque check."""
        from .adaptive.check import Estimate, estimates_of

        ff = self.params.feedforward
        if ff is None or not ff.current:
            return
        if self.adaptive.compliance.forces:
            raise BadRequest(f"move({name!r}): compliance is on and the motion runs feed-forward ({ff.mode!r}); "
                             "a joint cannot be force-servoed and torque-fed at once")
        needs = estimates_of(self.gen.queue.pending) if self.gen is not None else Estimate.NONE
        if Estimate.FORCE in needs or Estimate.TORQUE in needs:
            raise BadRequest(f"move({name!r}): a force/torque check under feed-forward ({ff.mode!r}): the force "
                             "estimate (4.37) takes the motor currents for gravity + friction + contact, and "
                             "these currents also carry the feed-forward's inertial and PD torques, which it "
                             "would read as a contact force; use a deviation limit, or position mode")

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
    """``rccl_open`` + ``rccl_control``: an Arm with the trajectory generator running (use in ``with``).

    Options: ``rate_hz`` (4..1000), ``trajectory`` ("quartic" or "ruckig"), ``record``,
    ``kinematics``, ``limits``, and the RCI Session's (``timeout``, ``on_error``, ...).
    """
    return Arm(url, robot, **options).open()
