"""The simulated arm of simula: joint state, calibration, servo and current modes, sensors (no I/O).

Physics (thesis 2.2.3 and A.7: a simulator of the gravity loading and friction of
chapter 4, eq. 4.7, which is what matters at the speeds RCI programs use):

* gravity loading from Pinocchio's ``computeGeneralizedGravity`` on the robot's URDF
  (the world model, independent of the generated kinematics the controller uses); a
  parameter file's ``[kinematics]`` errors of the DH table (thesis 3.83) move the URDF's
  joints (``apply_dh_errors``), so the simulated arm is not the nominal model;
* friction from :mod:`rci.simula.friction` (eq. 4.27 with Tables 4.2-4.6, Table 4.4
  variation, cold joints, stiction);
* a joint under POS (or holding after STOP) is servoed by its microcontroller along a
  straight line to the requested encoder count, reached at the end of the cycle, within
  the joint's velocity limit and motor current limit (a saturated servo lets the joint
  move under the saturated torque instead);
* a joint under CUR gets the motor current its DAC value commands (clipped at the current
  limit) and moves under that torque against gravity, friction, the pulley load and any
  external torque, with the link inertia (Pinocchio ``crba``) plus the motor rotor
  inertia reflected through G. ``dynamic=True`` couples the current-mode joints through
  the full mass matrix and adds Coriolis/centrifugal terms (``rnea``); the default, like
  the thesis's kinematic simulator, uses only each joint's own inertia;
* encoders count motor revolutions (e = R q + e0, eq. 4.30, R of the data file) plus a
  calibration offset: an uncalibrated arm's counters read 0 where the arm was at power
  up. Each motor encoder has an index mark once per motor revolution, where the
  calibrated count is a multiple of the counts per motor revolution;
* the ADC channels 0..n-1 carry the motor currents as the current-sense circuit of
  Appendix C reports them: the 1 kHz servo current (with its ripple) through a 15 ms
  low-pass filter, sampled, plus noise, quantised to 12 bits (eq. 4.31/4.32 with the true
  sigma); channels n..2n-1 carry joint potentiometers (coarse absolute position for
  calibration, 12 bits over each joint's range).

Everything here is deterministic for a given seed and sequence of calls.

Why this module is long: the arm's step is one piece of physics over one state (joint
angles and speeds, servo and current modes, friction, calibration, sensors); cutting it
would pass that state between modules every servo tick. Friction is in friction.py,
parameters in params.py.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import Callable

import numpy as np
import pinocchio as pin

from .. import codes
from ..chg import CUR, POS, STOP, STOPCAL, Chg
from ..conversions import ADC_MAX, ADC_MIN, DAC_MAX, DAC_MIN, Conversions
from .exceptions import ParamsError, SimulaError
from .friction import FrictionState
from .params import PulleyLoad, Truth, motor_inertia

HOLD, SERVO, CURRENT = 0, 1, 2          # internal joint modes (HOLD: servo on a fixed count)
MODE_NAMES = {HOLD: "hold", SERVO: "pos", CURRENT: "cur"}
N_ADC = 16                               # thesis A.4: 16 ADC channels
POT_SPAN = 4000                          # potentiometer counts over a joint's range (-2000..2000)
COUNT_MIN, COUNT_MAX = -2**31, 2**31 - 1  # the link's int32 encoder field (docs/protocol.md, HOW)
_EPS_V = 1e-9                            # rad/s below which a servo joint counts as halted


@dataclass(frozen=True)
class SensorSample:
    """What the robot's sensors report at one instant (one HOW)."""

    pos: np.ndarray       # encoder counters, int64
    adcr: np.ndarray      # 16 ADC channels, int64 in -2048..2047
    state: int
    status: int
    outport1: int
    inport1: int


def gravity_moves(model) -> dict[str, tuple[int, np.ndarray, float]]:
    """Which centre of mass each gravity coefficient of ``model`` moves in simula, read from
    the model file: ``name -> (link k, unit axis in DH frame k, s)`` with
    d coefficient = s g m_k d(axis coordinate of link k's centre of mass).

    * With ``[gravity_grouping]``, each coefficient's meaning (a SymPy expression in the
      masses and centre-of-mass coordinates, eq. 4.24 for the PUMA 260) names candidates: a
      coordinate the link's ``com_form`` leaves free that enters this meaning linearly and no
      other one. The heaviest such link is moved (the smallest shift; for the PUMA 260 x2,
      z3 and z6, the first moments the data file solved from Table 4.9).
    * Without it, the derivation's minimal set (derive.gravity.minimal_gravity): ``c<axis><k>``
      is g (m_k <axis>_k + ...), and m_k <axis>_k enters no other coefficient.

    A coefficient with no such coordinate (one that fixes link masses) is left out.
    """
    names = list(model.gravity_coeffs)
    grouping = model.gravity_grouping
    if grouping is None:
        return {n: (int(n[2]), np.eye(3)["xyz".index(n[1])], 1.0) for n in names
                if len(n) == 3 and n[0] == "c" and n[1] in "xyz" and n[2].isdigit()}
    import sympy as sp

    masses = {li.index: li.mass for li in model.links}
    values = {sp.Symbol(f"m{k}"): m for k, m in masses.items()} | {sp.Symbol("g"): model.gravity}
    meanings = {n: sp.sympify(grouping.meanings[n]) for n in names}
    moves: dict[str, tuple[int, np.ndarray, float]] = {}
    for name in names:
        best = None
        for k, form in enumerate(grouping.com_form, start=1):
            for axis, text in enumerate(form):
                coord = sp.Symbol(text.strip())
                if not text.strip().isidentifier() or any(
                        coord in meanings[o].free_symbols for o in names if o != name):
                    continue
                slope = sp.diff(meanings[name], coord).subs(values)
                if slope.free_symbols or slope == 0:
                    continue
                if best is None or masses[k] > masses[best[0]]:
                    best = (k, np.eye(3)[axis], float(slope) / (model.gravity * masses[k]))
        if best is not None:
            moves[name] = best
    return moves


def _tune_gravity(pmodel: pin.Model, model, coeffs: dict[str, float]) -> None:
    """Move centres of mass so that the URDF's gravity loading has the coefficients ``coeffs``:
    each changed coefficient moves the first moment ``gravity_moves`` names for it, in its
    link's DH frame (the data file solved its centres of mass from the coefficients the same
    way)."""
    g = model.gravity
    masses = {li.index: li.mass for li in model.links}
    changed = {n: v - model.gravity_coeffs[n].value for n, v in coeffs.items()
               if abs(v - model.gravity_coeffs[n].value) >= 1e-15}
    if not changed:
        return
    moves = gravity_moves(model)
    for name, delta_c in changed.items():
        if name not in moves:
            raise ParamsError(f"gravity coefficient {name} of robot {model.name} cannot be changed in simula "
                              f"(it fixes link masses, not a centre of mass)")
        link, axis, slope = moves[name]
        shift = delta_c / (slope * g * masses[link]) * axis          # in DH frame `link`
        fid = pmodel.getFrameId(f"link{link}")
        frame = pmodel.frames[fid]
        jid = frame.parentJoint
        body = pmodel.inertias[jid]
        lever = body.lever + masses[link] * (frame.placement.rotation @ shift) / body.mass
        pmodel.inertias[jid] = pin.Inertia(body.mass, lever, body.inertia)


def scale_inertials(pmodel: pin.Model, mass_scale: np.ndarray | None, inertia_scale: np.ndarray | None) -> None:
    """The parameter file's ``[inertials]``: joint k's body gets k's mass factor (centre of mass
    kept, rotational inertia about it scaled alike) and, on top, its rotational-inertia factor."""
    if mass_scale is None and inertia_scale is None:
        return
    n = pmodel.njoints - 1
    ms = np.ones(n) if mass_scale is None else np.asarray(mass_scale, float)
    js = np.ones(n) if inertia_scale is None else np.asarray(inertia_scale, float)
    for k in range(n):
        body = pmodel.inertias[k + 1]
        pmodel.inertias[k + 1] = pin.Inertia(body.mass * ms[k], body.lever, body.inertia * ms[k] * js[k])


def _dh_fixed(d: float, a: float, alpha: float) -> pin.SE3:
    """The fixed part of a DH step, Tz(d) Tx(a) Rx(alpha) (thesis eq. 3.3)."""
    return pin.SE3(pin.utils.rotate("x", alpha), np.array([a, 0.0, d]))


def apply_dh_errors(pmodel: pin.Model, model, errors: np.ndarray) -> None:
    """Give the URDF model ``pmodel`` the DH table of ``model`` plus ``errors`` (n, 4):
    per joint (d theta rad, d d m, d a m, d alpha rad), exactly, not to first order.

    With C_i = Tz(d_i) Tx(a_i) Rx(alpha_i), the true step is
    A_i' = Rz(theta_i + q_i + d theta_i) C_i' = Rz(d theta_i) A_i (C_i^-1 C_i'):
    d theta_i turns joint i's placement about its own axis (z_{i-1}, which the URDF's joint
    frame shares), and E_i = C_i^-1 C_i' is appended to DH frame i (the URDF frame
    ``link<i>``), so everything after it (joint i+1, the tool point on link 6) moves.
    Link inertials stay where they are on their bodies. Revolute joints only.
    """
    errors = np.asarray(errors, dtype=float)
    data = pmodel.createData()
    pin.computeJointJacobians(pmodel, data, pin.neutral(pmodel))
    for i, joint in enumerate(model.joints):
        e = errors[i]
        if not np.any(e):
            continue
        if joint.kind != "revolute":
            raise ParamsError(f"{model.name}: [kinematics] errors of the prismatic joint {i + 1} "
                              "are not supported by simula")
        jid = pmodel.getJointId(f"joint{i + 1}")
        fid = pmodel.getFrameId(f"link{i + 1}")
        if jid >= pmodel.njoints or fid >= len(pmodel.frames) or pmodel.frames[fid].parentJoint != jid:
            raise SimulaError(f"{model.urdf_path}: no joint{i + 1} carrying frame link{i + 1}: "
                              "cannot apply [kinematics] errors")
        if e[0]:
            axis = pin.getJointJacobian(pmodel, data, jid, pin.LOCAL)[3:, pmodel.joints[jid].idx_v]
            pmodel.jointPlacements[jid] = pmodel.jointPlacements[jid] * pin.SE3(pin.exp3(axis * e[0]), np.zeros(3))
        E = _dh_fixed(joint.d, joint.a, joint.alpha).inverse() * _dh_fixed(joint.d + e[1], joint.a + e[2],
                                                                          joint.alpha + e[3])
        F = pmodel.frames[fid].placement
        shift = F * E * F.inverse()              # E seen from joint i's own frame
        for k in range(1, pmodel.njoints):
            if pmodel.parents[k] == jid:
                pmodel.jointPlacements[k] = shift * pmodel.jointPlacements[k]
        for frame in pmodel.frames:
            if frame.parentJoint == jid and frame.name in (f"link{i + 1}", f"link{i + 1}_frame"):
                frame.placement = shift * frame.placement


class SimulatedArm:
    """The simulated robot arm (n joints) with its controller's joint-level behaviour."""

    def __init__(self, model, truth: Truth, *, seed: int = 0, start: str = "uncalibrated",
                 dynamic: bool = False, load: PulleyLoad | None = None) -> None:
        self.model = model
        self.truth = truth
        self.n = n = model.n_joints
        self.dynamic = dynamic
        self.conv = Conversions.from_model(model, sigma=truth.sigma)   # the arm's true constants
        R = self.conv.R
        if np.any(np.abs(np.triu(R, 1)) > 0):
            raise SimulaError(f"{model.name}: encoder matrix R must be lower triangular for simula")
        self.pm = pin.buildModelFromUrdf(str(model.urdf_path))
        if self.pm.nq != n:
            raise SimulaError(f"{model.urdf_path}: URDF has {self.pm.nq} joints, data file {n}")
        self.pm.gravity.linear = np.array([0.0, 0.0, -model.gravity])
        _tune_gravity(self.pm, model, truth.gravity_coeffs)
        if truth.dh_errors is not None:
            apply_dh_errors(self.pm, model, truth.dh_errors)
        scale_inertials(self.pm, truth.mass_scale, truth.inertia_scale)
        self.pd = self.pm.createData()
        seq = np.random.SeedSequence(seed)
        s_fric, s_noise, s_start = seq.spawn(3)
        self.rng = np.random.default_rng(s_noise)
        self.friction = FrictionState(truth, np.random.default_rng(s_fric))
        # the data file's rotor inertias (x [inertials] rotor_scale) reflected: G^T diag(J_m) G
        self.rotor = model.rotor_matrix(motor_inertia(model, truth))
        self.lower, self.upper = np.array(model.lower), np.array(model.upper)
        self.vmax = np.array(model.max_velocity)
        self.imax = np.array(model.max_current)
        self.counts_per_rev = np.array(model.conversion.encoder_counts_per_motor_rev.values, dtype=float)
        self.load = load
        self.ext = np.zeros(n)                  # external joint torques applied by a test (N*m / N)
        self._zeros = np.zeros(n)
        self._zeros.flags.writeable = False

        if start == "ready":
            q0 = np.array(model.poses["ready"], dtype=float)
        elif start == "nest":
            q0 = np.array(model.poses["nest"], dtype=float)
        elif start == "uncalibrated":
            # an arm left somewhere near its nest: a few degrees (or mm) off, seeded
            span = np.where(np.array(model.kinds) == "revolute", np.radians(3.0), 0.003)
            q0 = np.array(model.poses["nest"], dtype=float) + np.random.default_rng(s_start).uniform(-span, span)
            q0 = np.clip(q0, self.lower, self.upper)
        else:
            raise SimulaError(f"unknown start state {start!r} (ready, nest, uncalibrated)")
        self.q = q0
        self.qd = np.zeros(n)
        self.t = 0.0
        calibrated = start != "uncalibrated"
        e = self.conv.angles_to_counts(self.q)
        self.cal_offset = np.zeros(n) if calibrated else -e        # counters read 0 at power up
        self.calibrated = np.full(n, calibrated)
        self.zindex = np.zeros(n, dtype=bool)
        self.found = np.zeros(n, dtype=bool)                       # index mark found, waiting for STOPCAL
        self.mode = np.full(n, HOLD)
        self.target = e.copy()                                     # servo target, true counts (no cal offset)
        self.deadline = np.zeros(n)
        self.dac = np.zeros(n, dtype=np.int64)
        self.power = False
        self.hold_f = self.friction.sample_hold(np.arange(n))
        self.moving = np.zeros(n, dtype=bool)
        self.current = np.zeros(n)          # instantaneous motor current (A)
        self.filtered = np.zeros(n)         # after the Appendix C filter (A)
        self._ripple_err = np.zeros(n)      # last servo tick's current quantisation error (A)
        self.motor_torque = np.zeros(n)     # t_s (N*m)
        self.status = codes.ST_OK
        self.status_text = ""
        self.setparams: dict[tuple[int, int], int] = {}
        self.hand = 0
        self.outport1 = 0
        self.pendant = 0
        self.limit_hits = 0
        self._alpha_h, self._alpha = -1.0, 1.0

    # attributes that describe the robot or the world, not the arm's evolving state: a rewind
    # (``restore_state``) keeps them (``ext`` and ``load`` are set by the test channel)
    _NOT_STATE = frozenset({"model", "truth", "n", "dynamic", "conv", "pm", "pd", "rng", "friction", "rotor",
                            "lower", "upper", "vmax", "imax", "counts_per_rev", "load", "ext", "_zeros",
                            "environment", "_env_data"})

    # --- helpers -------------------------------------------------------------------
    def counters(self) -> np.ndarray:
        """Encoder counters as the controller reads them (int64), saturated to the link's int32 range.

        A counter beyond that range (a STOPCAL near the limit, then motion) is held at the
        limit and reported (status ``ST_ENCODER_RANGE``) instead of wrapping silently.
        """
        c = np.rint(self.conv.angles_to_counts(self.q) + self.cal_offset).astype(np.int64)
        out = (c < COUNT_MIN) | (c > COUNT_MAX)
        if out.any():
            j = int(np.argmax(out))
            self.flag(codes.ST_ENCODER_RANGE, f"joint {j + 1}: encoder count {int(c[j])} outside the link's "
                                              f"32-bit range, saturated")
            c = np.clip(c, COUNT_MIN, COUNT_MAX)
        return c

    def save_state(self) -> tuple:
        """Everything that evolves as the arm moves (joint state, modes, filter, friction
        warmth, random generators), for :meth:`restore_state`: the server rewinds a step
        it made ahead of time when a release arrives during that period."""
        mine = {k: (v.copy() if isinstance(v, np.ndarray) else copy.copy(v))
                for k, v in vars(self).items() if k not in self._NOT_STATE}
        return (mine, self.friction.warmth.copy(), self.rng.bit_generator.state,
                self.friction.rng.bit_generator.state)

    def restore_state(self, saved: tuple) -> None:
        mine, warmth, rng, fric_rng = saved
        for k, v in mine.items():
            setattr(self, k, v.copy() if isinstance(v, np.ndarray) else copy.copy(v))
        self.friction.warmth = warmth.copy()
        self.rng.bit_generator.state = rng
        self.friction.rng.bit_generator.state = fric_rng

    def gravity(self, q: np.ndarray | None = None) -> np.ndarray:
        """Gravity loading t_g(q): torques the joints exert to hold the arm (N*m / N)."""
        return pin.computeGeneralizedGravity(self.pm, self.pd, self.q if q is None else np.asarray(q, float)).copy()

    def flag(self, status: int, text: str) -> None:
        """Report ``status`` (a how.status value) in the next HOW; the first flag of a cycle wins."""
        if self.status == codes.ST_OK:
            self.status, self.status_text = status, text

    def _hold_here(self, joints) -> None:
        e = self.conv.angles_to_counts(self.q)
        for i in joints:
            if not self.found[i]:
                self.mode[i] = HOLD
                self.target[i] = e[i]
            self.qd[i] = 0.0

    @property
    def state(self) -> int:
        s = codes.TP_OK
        if self.calibrated.all():
            s |= codes.CALIB_OK
        if self.calibrated.all() or (self.found | self.calibrated).all():
            s |= codes.ZINDEX_OK
        if self.power:
            s |= codes.POWER_ON
        if self.zindex.any():
            s |= codes.ZINDEX_ACTIVE
        return s

    # --- commands --------------------------------------------------------------------
    def apply(self, chg: Chg, period: float) -> None:
        """Execute the arm's part of one CHG in the protocol's order (docs/protocol.md), for a
        period of ``period`` s. The rate command and ``end`` are the server's (it reads them
        from ``chg``: ``chg.rate_change()``, ``chg.end``): they change the clock, not the arm."""
        n = self.n
        if chg.nj != n:
            self.flag(codes.ST_BAD_COMMAND, f"CHG for {chg.nj} joints, robot has {n}")
            return
        if chg.power_off.com:
            self.power = False
            self._hold_here(range(n))
        if chg.stop.com:
            self._hold_here(range(n))
        if chg.power_on.com and not self.power:
            self.power = True
            self._hold_here(range(n))
            self.hold_f = self.friction.sample_hold(np.arange(n))
        for i, c in enumerate(chg.setparam):
            if c.com:
                self.setparams[(i, (int(c.value) >> 24) & 0xFF)] = int(c.value) & 0xFFFFFF
        if chg.setparamALL.com:
            for i in range(n):
                self.setparams[(i, (int(chg.setparamALL.value) >> 24) & 0xFF)] = int(chg.setparamALL.value) & 0xFFFFFF
        if chg.zindex.com:
            bits = int(chg.zindex.value)
            for i in range(n):
                if bits >> i & 1:
                    self.zindex[i] = True
                    self.found[i] = False
                    self.calibrated[i] = False
        for i, c in enumerate(chg.motion):
            if c.com:
                self._motion(i, int(c.com), int(c.value), period)
        if chg.hand.com:
            if int(chg.hand.value) not in (1, 2):
                self.flag(codes.ST_BAD_COMMAND, f"hand value {chg.hand.value} is neither OPEN (1) nor CLOSE (2)")
            else:
                self.hand = int(chg.hand.value)
        if chg.outport1.com:
            self.outport1 = int(chg.outport1.value) & 0xFFFF
        if chg.pendant.com:
            self.pendant = int(chg.pendant.value)
        if chg.adco.com and not 0 <= int(chg.adco.value) < N_ADC:
            self.flag(codes.ST_BAD_COMMAND, f"adco channel {chg.adco.value} is not 0..{N_ADC - 1}")

    def _motion(self, i: int, com: int, value: int, period: float) -> None:
        if com == STOP:
            self._hold_here([i])
            return
        if com == STOPCAL:
            e = self.conv.angles_to_counts(self.q)[i]
            self.cal_offset[i] = value - e
            if self.found[i]:
                self.calibrated[i] = True
                self.zindex[i] = False
                self.found[i] = False
            self._hold_here([i])
            return
        if com not in (POS, CUR):
            self.flag(codes.ST_BAD_COMMAND, f"joint {i + 1}: unknown motion command {com}")
            return
        if self.found[i]:
            return      # frozen on its index mark until STOPCAL (A.4 zindex)
        if not (self.calibrated[i] or self.zindex[i]):
            self.flag(codes.ST_NOT_CALIBRATED, f"joint {i + 1} is not calibrated: motion refused (run zindex/STOPCAL)")
            return
        if com == POS:
            target = value - self.cal_offset[i]
            if self.mode[i] != CURRENT and np.rint(self.target[i] + self.cal_offset[i]) == value:
                # a joint servo sees its error in whole counts: a joint held between counts (where
                # a hold or a current-mode stretch left it) whose counter already reads the value
                # commanded has nothing to correct, and stays where it is
                target = self.target[i]
            self.mode[i] = SERVO
            self.target[i] = target
            self.deadline[i] = self.t + period
        else:
            if not DAC_MIN <= value <= DAC_MAX:
                self.flag(codes.ST_BAD_COMMAND, f"joint {i + 1}: CUR value {value} outside {DAC_MIN}..{DAC_MAX}")
                return
            self.mode[i] = CURRENT
            self.dac[i] = value

    def set_external_torque(self, joint: int, torque: float) -> None:
        """External torque on joint ``joint`` (0-based), positive in the joint's positive sense."""
        if not 0 <= joint < self.n or not np.isfinite(torque):
            raise ValueError(f"external torque: joint {joint + 1} / value {torque!r} invalid")
        self.ext[joint] = float(torque)

    def hold_all(self) -> None:
        """Stop every joint where it is (END of a control, watchdog, session lost)."""
        self._hold_here(range(self.n))

    def hold_current_mode(self) -> bool:
        """Put every joint in current mode under the position servo where it is; True if any was.

        A robot that got no chg for a cycle keeps its position targets (a target is a place
        to stop at) but not a motor current (a current keeps accelerating the joint).
        """
        cur = np.flatnonzero(self.mode == CURRENT)
        if len(cur):
            self._hold_here(cur)
        return bool(len(cur))

    # --- physics ---------------------------------------------------------------------
    def quiescent(self) -> bool:
        """True when nothing can move: power off, or every joint held still on its target
        with no external torque (the arm between two programs)."""
        if not self.power:
            return True
        if np.any(self.mode == CURRENT) or np.any(self.qd != 0.0) or np.any(self.ext != 0.0):
            return False
        return bool(np.all(np.abs(self.conv.angles_to_counts(self.q) - self.target) < 1e-6))

    def coast(self, dt: float) -> None:
        """Advance a quiescent arm by ``dt`` s: time passes and the joints cool; the held
        currents and the filter keep their last values."""
        self.friction.warm(np.zeros(self.n, dtype=bool), dt)
        self.t += dt

    def step(self, dt: float, stop: Callable[[], bool] | None = None) -> bool:
        """Advance the arm by ``dt`` seconds in servo-rate substeps (about 1 ms).

        ``stop`` is asked before every substep after the first; when it says True the step
        ends there and False is returned (the arm is then part of the way: the caller undoes
        it with ``restore_state``). True when the whole step was made.
        """
        nsub = max(1, int(round(dt * self.truth.disturbances.servo_rate_hz)))
        h = dt / nsub
        for k in range(nsub):
            if k and stop is not None and stop():
                return False
            self._substep(h)
        return True

    def _load_torque(self) -> tuple[np.ndarray, np.ndarray]:
        """(external load torque, extra Coulomb friction) from the pulley, joint level."""
        if self.load is None:
            return self._zeros, self._zeros
        tau = np.zeros(self.n)
        fc = np.zeros(self.n)
        if self.load is not None and self.load.mass > 0:
            j = self.load.joint - 1
            tau[j] = -self.load.sign * self.load.mass * self.model.gravity * self.load.radius
            fc[j] = self.truth.disturbances.pulley_friction
        return tau, fc

    def _friction_at(self, q: np.ndarray, vel: np.ndarray, pulley_fc: np.ndarray) -> np.ndarray:
        return self.friction.kinetic(q, vel) + pulley_fc * np.sign(vel)

    def _substep(self, h: float) -> None:
        n, conv, d = self.n, self.conv, self.truth.disturbances
        q, qd = self.q, self.qd
        if not self.power:
            qd[:] = 0.0
            self.moving[:] = False
            self.current[:] = 0.0
            self.motor_torque[:] = 0.0
            self._filter(h)
            self.friction.warm(self.moving, h)
            self.t += h
            return
        servo = self.mode != CURRENT
        # joint-space servo targets: forward substitution through the lower-triangular R,
        # so a wrist servo holds its motor count while the joints before it move
        R, e0 = conv.R, conv.encoder_offset
        if servo.all():
            qt = conv.R_inv @ (self.target - e0)
        else:
            qt = q.copy()
            for i in range(n):
                if servo[i]:
                    qt[i] = (self.target[i] - e0[i] - R[i, :i] @ qt[:i]) / R[i, i]
        t_left = np.maximum(self.deadline - self.t, h)
        v = np.where(servo, np.clip((qt - q) / t_left, -self.vmax, self.vmax), 0.0)
        v[np.abs(v) < _EPS_V] = 0.0
        halted = servo & (v == 0.0) & self.moving
        if halted.any():
            self.hold_f[halted] = self.friction.sample_hold(np.flatnonzero(halted))
        tg = self.gravity(q)
        load_tau, pulley_fc = self._load_torque()
        f_servo = np.where(v != 0.0, self._friction_at(q, v, pulley_fc), self.hold_f)
        need = tg + f_servo - self.ext - load_tau                  # joint torque a servo must supply
        # motor torques: CUR joints from their DAC, servo joints solved from t_j = G^T t_s
        GT = conv.G.T
        lim = self.imax * self.truth.sigma
        ts = np.zeros(n)
        driven = ~servo
        ts[driven] = np.clip((self.dac / conv.k_dac)[driven], -lim[driven], lim[driven])
        if not driven.any():
            ts = conv.G_inv.T @ need                               # all servo: t_s = G^-T t_j
            sat = np.abs(ts) > lim
            if sat.any():
                driven = sat
                ts = np.clip(ts, -lim, lim)
        for _ in range(2 if driven.any() else 0):
            s = np.flatnonzero(~driven)
            c = np.flatnonzero(driven)
            if len(s):
                ts[s] = np.linalg.solve(GT[np.ix_(s, s)], need[s] - GT[np.ix_(s, c)] @ ts[c])
            sat = (~driven) & (np.abs(ts) > lim)
            if not sat.any():
                break
            ts[sat] = np.clip(ts[sat], -lim[sat], lim[sat])
            driven = driven | sat
        tj = GT @ ts
        # torque-driven joints (current mode, or a saturated servo): stick-slip dynamics
        new_qd = np.where(driven, qd, v)
        if driven.any():
            new_qd[driven] = self._stick_slip(q, qd, tj - tg + self.ext + load_tau, tg, driven, pulley_fc, h)
        e_before = conv.R @ q + e0 if self.zindex.any() else None
        self.qd = qd = new_qd
        self.q = q = q + qd * h
        # mechanical stops
        out = (q < self.lower) | (q > self.upper)
        if out.any():
            self.q = q = np.clip(q, self.lower, self.upper)
            self.limit_hits += 1
            for i in np.flatnonzero(out):
                self.flag(codes.ST_JOINT_LIMIT, f"joint {i + 1} hit its mechanical stop")
            self._hold_here(np.flatnonzero(out))
            qd = self.qd
        self._zindex(e_before)
        self.motor_torque = ts
        self.current = ts / self.truth.sigma
        self.moving = np.abs(self.qd) > 0.0
        self._filter(h, ripple=np.where(servo & ~driven, d.ripple_pos, d.ripple_cur))
        self.friction.warm(np.abs(self.qd) > 1e-4, h)
        self.t += h

    def _stick_slip(self, q: np.ndarray, qd: np.ndarray, u: np.ndarray, tg: np.ndarray,
                    driven: np.ndarray, pulley_fc: np.ndarray, h: float) -> np.ndarray:
        """New velocities of the torque-driven joints (``driven``) after h seconds.

        ``u`` is the net joint torque before friction (motor - gravity + external + load).
        The joints that move obey M qdd = u - f(qd) - c(q, qd), with servo-held joints and
        stuck joints fixed (qdd = 0); a stuck joint breaks away when the friction needed to
        keep it still exceeds its static friction, and then moves the way that friction
        would have had to resist (Karnopp's model). A moving joint whose velocity would
        change sign under friction stops and sticks instead. Kinematic mode uses only each
        joint's own inertia and no Coriolis/centrifugal terms; ``dynamic`` the full mass
        matrix and ``rnea`` (with every joint driven and no friction: Pinocchio's ``aba``).
        """
        n = self.n
        fsp, fsn = self.friction.breakaway()
        fsp, fsn = fsp + pulley_fc, fsn + pulley_fc
        M = self._inertia(q)
        if self.dynamic:
            c = pin.rnea(self.pm, self.pd, q, qd, np.zeros(n)) - tg       # Coriolis and centrifugal
        else:
            M = np.diag(np.diag(M))
            c = np.zeros(n)
        direction = np.where(driven, np.sign(qd), 0.0)
        stuck = driven & (qd == 0.0)
        acc = np.zeros(n)
        for _ in range(n + 1):
            go = driven & (direction != 0.0)
            acc[:] = 0.0
            if go.any():
                idx = np.flatnonzero(go)
                f = self._friction_at(q, np.where(qd != 0.0, qd, direction * 1e-12), pulley_fc)
                acc[idx] = np.linalg.solve(M[np.ix_(idx, idx)], (u - f - c)[idx])
            # friction a still joint must supply to stay still: f = u - c - (M acc)
            hold = u - c - M @ acc
            release = stuck & (direction == 0.0) & ((hold > fsp) | (hold < -fsn))
            if not release.any():
                break
            direction[release] = np.sign(hold[release])
        trial = qd + acc * h
        # friction cannot reverse a motion: crossing zero (or starting against the breakaway
        # direction) means the joint sticks; frictionless joints move freely
        has_friction = (fsp > 0) | (fsn > 0) | (self.truth.coulomb_pos > 0) | (self.truth.coulomb_neg > 0)
        reversed_ = has_friction & (direction != 0.0) & (np.sign(trial) != direction)
        trial = np.where(reversed_ | (direction == 0.0), 0.0, trial)
        return trial[driven]

    def _inertia(self, q: np.ndarray) -> np.ndarray:
        M = pin.crba(self.pm, self.pd, q)
        M = np.triu(M) + np.triu(M, 1).T
        return M + self.rotor

    def _zindex(self, e_before: np.ndarray | None) -> None:
        """Freeze zindex joints whose encoder passed an index mark (a multiple of counts/rev)."""
        if e_before is None or not self.zindex.any():
            return
        e_after = self.conv.angles_to_counts(self.q)
        N = self.counts_per_rev
        for i in np.flatnonzero(self.zindex & ~self.found):
            a, b = np.floor(e_before[i] / N[i]), np.floor(e_after[i] / N[i])
            if a == b:
                continue
            mark = max(a, b) * N[i]
            R, e0 = self.conv.R, self.conv.encoder_offset
            q = self.q.copy()
            q[i] = (mark - e0[i] - R[i, :i] @ q[:i]) / R[i, i]
            self.q = q
            self.qd[i] = 0.0
            self.found[i] = True
            self.mode[i] = HOLD
            self.target[i] = mark

    def _filter(self, h: float, ripple: np.ndarray | None = None) -> None:
        """The current-sense low-pass of Appendix C, fed with the 1 kHz servo current."""
        d = self.truth.disturbances
        x = self.current
        if ripple is not None and self.power:
            # The PID's output is coarsely quantised (Appendix C) and its integral term
            # feeds each tick's quantisation error back into the next, so the fluctuation
            # is the difference of successive errors (first-order noise shaping): large
            # from tick to tick (peaks of twice ``amp``, "as high as the average current",
            # 4.5.1) but with no power at low frequency, so the joint gets on average the
            # current it needs and the 15 ms filter averages the ripple out, as the
            # thesis's repeatable work measurements (4.5.3) show it did.
            amp = ripple * np.abs(x) + d.ripple_floor
            err = amp * self.rng.uniform(-1.0, 1.0, self.n)
            x = x + err - self._ripple_err
            self._ripple_err = err
        if h != self._alpha_h:
            self._alpha = 1.0 - np.exp(-h / d.filter_tau) if d.filter_tau > 0 else 1.0
            self._alpha_h = h
        alpha = self._alpha
        self.filtered = self.filtered + alpha * (x - self.filtered)

    # --- sensors -----------------------------------------------------------------------
    def sample(self) -> SensorSample:
        """Read the sensors (encoders, ADC) and take the pending status (cleared after)."""
        d = self.truth.disturbances
        adc = np.zeros(N_ADC, dtype=np.int64)
        n = self.n
        cur = self.conv.currents_to_adc(self.filtered) + d.adc_noise * self.rng.standard_normal(n)
        adc[:n] = np.clip(np.rint(cur), ADC_MIN, ADC_MAX)
        if 2 * n <= N_ADC:
            frac = (self.q - self.lower) / (self.upper - self.lower)
            pot = frac * POT_SPAN - POT_SPAN / 2 + d.pot_noise * self.rng.standard_normal(n)
            adc[n:2 * n] = np.clip(np.rint(pot), ADC_MIN, ADC_MAX)
        pos = self.counters()                 # before the status: a saturated counter flags one
        status = self.status
        self.status, self.status_text = codes.ST_OK, ""
        return SensorSample(pos=pos, adcr=adc, state=self.state, status=status,
                      outport1=self.outport1, inport1=1 if self.hand == 2 else 0)

    def snapshot(self) -> dict:
        """A JSON-friendly description of the state (for the control channel and -v)."""
        return {
            "t": round(self.t, 6),
            "q_deg": [round(float(x), 4) for x in np.degrees(self.q)],
            "q": [float(x) for x in self.q],
            "qd": [float(x) for x in self.qd],
            "mode": [MODE_NAMES[int(m)] for m in self.mode],
            "calibrated": [bool(x) for x in self.calibrated],
            "zindex": [bool(x) for x in self.zindex],
            "index_found": [bool(x) for x in self.found],
            "power": self.power,
            "counters": [int(x) for x in self.counters()],
            "current_A": [float(x) for x in self.filtered],
            "external_torque": [float(x) for x in self.ext],
            "warmth": [float(x) for x in self.friction.warmth],
            "load": None if self.load is None else vars(self.load),
        }
