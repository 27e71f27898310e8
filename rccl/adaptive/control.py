"""The per-sample adaptive work of RCCL (thesis 5.4, E.2, E.6), between ``how`` and ``chg``: no I/O.

``AdaptiveControl.before(gen, q, qd, v_adc)`` runs before the generator's step: it
estimates what the running motion needs (Jacobian at the measured joints, net joint
torques 4.37, tool-frame force 4.56, tool-frame deviation E.2), runs the motion's checks
(``rccl.adaptive.check.MotionCheck``: limits, monitors) and asks the generator to end the
motion on the first verdict, and lets the comply
transform absorb the deviation along the compliant axes. ``after(q_nominal)`` turns the
generator's joint angles into the command: the comply transform added (E.6) and, for the
joints chosen to force-servo the compliant directions, a DAC value (4.38) in current mode.
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

import numpy as np

from rci.conversions import DAC_MAX

from rccl.kinematics.exceptions import KinematicsError

from .comply import Compliance, select_joints, servo_dac
from .deviation import ToolMaps
from .exceptions import ForceEstimateError
from .force import ForceEstimator, JointModel, condition_1, gravity_vector
from .functional import joint_map
from .check import Estimate, Sample, estimates_of
from .limit import vet_limits
from .stiction import Dither

# estimate: keep the force-servoed joint unless another does 1.5x better, so a joint does not
# flip between current and position mode from one sample to the next near a tie
SWITCH_RATIO = 1.5
# estimate: damping of the force-servoed direction, N*s/m in the tool frame (N*m*s/rad for torques);
# it turns the contact (tool + fixture at ~2e4 N/m through a joint's inertia) from a ringing spring
# that sticks wherever static friction catches it into an approach that settles at the force asked
COMPLY_DAMPING = 100.0
# estimate: the force-servoed joint's speed (for its damping, its friction direction and the rest test
# of the static-friction correction) is taken over at least 20 ms: at 500 Hz one encoder count of
# joint 3 in one sample reads 0.07 rad/s, which would flip the rest test and kick the damping term
SPEED_WINDOW = 0.02


@dataclass
class Command:
    """One sample's command: joint angles (rad) for position-servoed joints, DAC values for the others."""

    q: np.ndarray
    current: dict[int, int] = field(default_factory=dict)    # joint -> DAC value


class AdaptiveControl:
    """Limits, monitors and compliance for one arm (``kin`` the generated kinematics module).

    The per-sample work avoids what costs tens of microseconds in numpy at this size: the
    Jacobian and its inverse come from the generated kernels' fast entries into arrays
    kept from sample to sample (``jacobian6(q, out=)``, and ``joint_from_cartesian`` of the
    six unit differentials, the analytic J^-1 of 3.73/3.77, instead of an LU inverse), the
    condition check of 4.57 uses the 1-norm (``force.condition_1``, no SVD), forces are
    J^-T t_a through that inverse, and the scalar bookkeeping is done on Python floats.
    """

    def __init__(self, kin, model: JointModel) -> None:
        """``kin``: the generated kinematics module (6 joints, or 7 with a free q7: then J is
        6x7, forces are least squares, E.8 and the comply law hold q7: ``functional.joint_map``)."""
        self.kin = kin
        self.model = model
        self.estimator = ForceEstimator(kin, model)
        self.compliance = Compliance()
        self.last: Sample | None = None          # what the motion checks saw last (read-out for programs)
        self._checked = None                     # the request whose checks' estimates are in _needs
        self._needs = Estimate.NONE
        self._vetted = None                      # the request whose force limits were vetted (limit.vet_limits)
        self._jac6: np.ndarray | None = None
        self._jac6_inv: np.ndarray | None = None
        self._comply_inv: np.ndarray | None = None   # a 6x7 J's map with q7 held, for the comply law
        self._q = None
        self._qd = None
        self._tool = np.eye(4)
        self._maps = ToolMaps()
        self._q_nom_prev: np.ndarray | None = None
        self.damping = COMPLY_DAMPING
        self.dither: Dither | None = None        # static-friction correction (4.6), made at the first comply sample
        self.dither_options: dict = {}           # keyword arguments of Dither (measurements vary them)
        self.condition = np.inf                  # cond_1 of the Jacobian at the last sample that needed it
        n = model.conv.n
        self._square = n == 6                    # a 7-joint arm's J is 6x7: least squares (4.56), E.8 with q7 held
        self._J = np.empty((6, n))               # frame-6 Jacobian, reused every sample
        self._J_inv_t = np.empty((6, n))         # (J^-1)^T: row k is J^-1 e_k (J^+ e_k for 6x7, minimum norm)
        self._unit = np.eye(6)
        self._q_hist: deque = deque()            # measured q of the last samples (SPEED_WINDOW)
        self._work = np.empty((6, n))
        self._gravity_coeffs = gravity_vector(kin, model.gravity_coeffs)
        self._dac_limit = np.minimum(model.max_dac, DAC_MAX).tolist()   # the motor current limit (A.5.1)

    def _inverse(self, q: np.ndarray, jac6: np.ndarray) -> np.ndarray | None:
        """J6^-1 at q (a transposed view of a kept array), or None where J6 is singular.

        For a 6x7 Jacobian: the pseudo-inverse J^+ (7x6, the generated minimum-norm
        ``joint_from_cartesian``), so that t_a J^+ is the least-squares force of 4.56
        (the f whose J^T f is nearest t_a) and |F J^+^T| e its error bar."""
        try:
            self.kin.joint_from_cartesian(q, self._unit, frame=6, out=self._J_inv_t)
        except KinematicsError:
            return None
        except (AttributeError, TypeError):      # kinematics without the batched differential kernel
            try:
                self._J_inv_t[:] = (np.linalg.inv(jac6) if self._square else np.linalg.pinv(jac6)).T
            except np.linalg.LinAlgError:
                return None
        return self._J_inv_t.T

    def before(self, gen, q: np.ndarray, qd: np.ndarray, v_adc: np.ndarray, how=None) -> None:
        """Measure and check, before ``gen.step()``; may call ``gen.abort``.

        ``gen`` is any ``rccl.generator.MotionGenerator`` (quartic or Ruckig): only its
        ``request``, ``tool``, ``q``, ``t``, ``samples``, ``dt``, ``abort`` and the ``jac6``
        fields it reuses are touched.
        """
        self._q, self._qd, self.dt = q, qd, gen.dt
        hist = self._q_hist
        hist.append(np.array(q, dtype=float))     # a copy: a caller may reuse its array
        if len(hist) > max(1, int(round(SPEED_WINDOW / gen.dt))) + 1:
            hist.popleft()
        req = gen.request          # None: holding at rest between moves (the jerk-limited generator)
        c = self.compliance
        comply = bool(c.forces) or c.offset.any()
        functional = False if req is None else req.has_functional
        if functional is None:      # once per request: whether its position has a functional transform
            functional = req.has_functional = any(t.kind == "functional" for t in req.position.transforms())
        running = req is not None and req.status == "running" and not req.repeat
        checks = req.checks if running else ()
        if not (comply or functional or checks):
            gen.jac6 = self._jac6 = gen.jac6_inv = self._jac6_inv = None
            gen.jac6_cond = None
            return
        if checks and req is not self._checked:   # once per request: what its checks need estimated
            self._checked, self._needs = req, estimates_of(req.checks)
        needs = self._needs if checks else Estimate.NONE
        q = np.ascontiguousarray(q, dtype=float)
        jac6 = self.kin.jacobian6(q, out=self._J)
        gen.jac6 = self._jac6 = jac6
        want_force = Estimate.FORCE in needs
        jinv = None
        square = self._square
        # one inverse per sample: E.8, the comply law, 4.56; a 6x7 J's E.8 map (q7 held, functional.joint_map)
        # differs from its least-squares inverse, so the functional limiter makes its own there
        if comply or (functional and square) or want_force:
            jinv = self._inverse(q, jac6)
            self.condition = condition_1(jac6, jinv, self._work) if jinv is not None else np.inf
        self._jac6_inv = jinv
        if comply and not square:     # the comply law through E.8's map with q7 held: the rule keeps q7
            try:
                self._comply_inv = joint_map(jac6)
            except np.linalg.LinAlgError:
                self._comply_inv = None
        gen.jac6_inv = jinv if square else None
        gen.jac6_cond = self.condition if jinv is not None and square else None
        tool = gen.tool
        self._tool = tool
        maps = self._maps.of(tool)
        want_dev = comply or Estimate.DEVIATION in needs
        t_a = force = dev = None
        if want_force or Estimate.TORQUE in needs:
            t_a = self.estimator.net_torques(q, qd, v_adc, gen.dt, gen.samples)
        if want_force:
            self.estimator.check_condition(q, self.condition if jinv is not None else np.inf)
            if req is not self._vetted:          # once, where the motion starts: can the estimate support its limits?
                self._vetted = req
                vet_limits(req.checks, self.estimator.error_bar(jinv, tool, maps.f),
                           f"{self.kin.ROBOT} limit")
            force = maps.f @ (t_a @ jinv)            # F(T6->tool) J6^-T t_a (4.56, 1.22)
        if want_dev:
            # measured minus planned (nominal) path: along compliant axes this is what the comply
            # transform absorbs and what reveals a slip; along the others the command also carried
            # the comply offset still being released, which is not a deviation
            dev = maps.d @ (jac6 @ (q - gen.q))
            if comply:
                nominal = dev
                dev = nominal - c.offset * c.free
                c.absorb(nominal)
        if not checks:
            return
        s = Sample(gen.t, gen.samples, q, qd, gen.q.copy(), t_a, force, dev, how)
        self.last = s
        for check in checks:                         # in the order attached; the first verdict ends it
            end = check.ends(s)
            if end is not None:
                gen.abort(end)
                return

    def hold(self, q: np.ndarray) -> Command:
        """After a fault: every joint position servoed where it is (compliance off)."""
        self.compliance.forces.clear()
        self.compliance.joints.clear()
        self.compliance.free[:] = 1.0
        return Command(self._q.copy() if self._q is not None else q)

    def after(self, q_nominal: np.ndarray) -> Command:
        """The command for this sample from the generator's joint angles."""
        c = self.compliance
        q_nom_prev, self._q_nom_prev = self._q_nom_prev, q_nominal.copy()
        if self._jac6 is None or not (c.forces or c.offset.any()):
            return Command(q_nominal)
        jac6 = self._jac6
        maps = self._maps.of(self._tool)
        # 6x7 (7 joints): J's inverse with q7 held (functional.joint_map): compliance moves and force-servoes
        # joints 1-6 (q7's score in select_joints is 0), q7 stays where the free-parameter rule puts it
        j6inv = self._jac6_inv if self._square else self._comply_inv
        if j6inv is None:
            raise ForceEstimateError("comply: the Jacobian is singular here; no joint can be chosen")
        c.release(self.dt)
        jinv = j6inv @ maps.d_inv                     # (D J6)^-1: tool-frame differential -> joints
        q_cmd = q_nominal + jinv @ c.offset if c.offset.any() else q_nominal
        if not c.forces:
            c.joints = {}
            return Command(q_cmd)
        jt = maps.d @ jac6
        axes = sorted(c.forces)
        chosen = select_joints(jt, axes, jinv)
        if c.joints:   # hysteresis: keep the previous joint unless clearly beaten
            for i, j in list(chosen.items()):
                old = c.joints.get(i)
                if old is not None and old != j and old not in chosen.values():
                    if abs(jt[i, j] * jinv[j, i]) < SWITCH_RATIO * abs(jt[i, old] * jinv[old, i]):
                        chosen[i] = old
        c.joints = chosen
        # t_a = J_T^T q (4.52) for the force-servoed joints, damped relative to the path's own motion
        jt_rows = jt.tolist()
        dt = self.dt
        hist = self._q_hist
        qd_meas = self._qd if len(hist) < 2 else (hist[-1] - hist[0]) / ((len(hist) - 1) * dt)
        qd = qd_meas.tolist()
        first = q_nom_prev is None
        t_a = np.zeros(len(qd))
        qd_path = [0.0] * len(qd)
        for i, j in chosen.items():
            if not first:
                qd_path[j] = (float(q_nominal[j]) - float(q_nom_prev[j])) / dt
            t_a[j] = sum(jt_rows[a][j] * c.forces[a] for a in axes) \
                - self.damping * jt_rows[i][j] ** 2 * (qd[j] - qd_path[j])
        t_g = self.kin.gravity(self._q, self._gravity_coeffs)
        joints = sorted(chosen.values())
        dither = self.dither
        if dither is None or dither.dt != dt:
            dither = self.dither = Dither(self.model, dt, **self.dither_options)
        dither.tick()
        correction = {}
        for j in joints:
            f = dither.correction(j, qd[j], qd_path[j], float(t_a[j]))
            if f is not None:
                correction[j] = f
        dac = servo_dac(self.model, joints, t_a, t_g, qd_meas, qd_path, correction=correction).tolist()
        lim = self._dac_limit
        current = {j: int(round(min(max(dac[j], -lim[j]), lim[j]))) for j in joints}
        return Command(q_cmd, current)
