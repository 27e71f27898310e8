"""The per-sample adaptive work of RCCL (thesis 5.4, E.2, E.6), between ``how`` and ``chg``: no I/O.

``AdaptiveControl.before(gen, q, qd, v_adc)`` runs before the generator's step: it
estimates what the running motion needs (Jacobian at the measured joints, net joint
torques 4.37, tool-frame force 4.56, tool-frame deviation E.2), checks the motion's limit
and monitor and asks the generator to end the motion if one fires, and lets the comply
transform absorb the deviation along the compliant axes. ``after(q_nominal)`` turns the
generator's joint angles into the command: the comply transform added (E.6) and, for the
joints chosen to force-servo the compliant directions, a DAC value (4.38) in current mode.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rci.conversions import DAC_MAX

from .comply import Compliance, select_joints, servo_dac
from .deviation import ToolMaps
from .exceptions import ForceEstimateError
from .force import ForceEstimator, JointModel
from .generator import AdaptiveGenerator
from .limit import Limit
from .monitor import Monitor, Sample
from .stiction import Dither

# estimate: keep the force-servoed joint unless another does 1.5x better, so a joint does not
# flip between current and position mode from one sample to the next near a tie
SWITCH_RATIO = 1.5
# estimate: damping of the force-servoed direction, N*s/m in the tool frame (N*m*s/rad for torques);
# it turns the contact (tool + fixture at ~2e4 N/m through a joint's inertia) from a ringing spring
# that sticks wherever static friction catches it into an approach that settles at the force asked
COMPLY_DAMPING = 100.0


@dataclass
class Command:
    """One sample's command: joint angles (rad) for position-servoed joints, DAC values for the others."""

    q: np.ndarray
    current: dict[int, int] = field(default_factory=dict)    # joint -> DAC value


class AdaptiveControl:
    """Limits, monitors and compliance for one arm (``kin`` the generated kinematics module)."""

    def __init__(self, kin, model: JointModel) -> None:
        self.kin = kin
        self.model = model
        self.estimator = ForceEstimator(kin, model)
        self.compliance = Compliance()
        self.last: Sample | None = None          # what the monitor saw last (read-out for programs)
        self._jac6: np.ndarray | None = None
        self._jac6_inv: np.ndarray | None = None
        self._q = None
        self._qd = None
        self._tool = np.eye(4)
        self._maps = ToolMaps()
        self._q_nom_prev: np.ndarray | None = None
        self.damping = COMPLY_DAMPING
        self.dither: Dither | None = None        # static-friction correction (4.6), made at the first comply sample

    def before(self, gen: AdaptiveGenerator, q: np.ndarray, qd: np.ndarray, v_adc: np.ndarray, how=None) -> None:
        """Measure and check, before ``gen.step()``; may call ``gen.abort``."""
        self._q, self._qd, self.dt = q, qd, gen.dt
        seg = gen.seg
        req = seg.req
        hooks = req.hooks
        lim: Limit | None = hooks.get("limit")
        mon: Monitor | None = hooks.get("evalfn")
        comply = self.compliance.active or bool(np.any(self.compliance.offset))
        functional = hooks.get("has_functional")
        if functional is None:      # once per request: whether its position has a functional transform
            functional = hooks["has_functional"] = any(t.kind == "functional" for t in req.position.transforms())
        running = req.status == "running" and not req.repeat
        if not (comply or functional or (running and (lim is not None or mon is not None))):
            gen.jac6 = self._jac6 = gen.jac6_inv = self._jac6_inv = None
            return
        jac6 = self.kin.jacobian6(q)
        gen.jac6 = self._jac6 = jac6
        gen.jac6_inv = self._jac6_inv = None
        if comply or functional:      # one inverse per sample, shared by E.8 limiting and the comply law
            try:
                gen.jac6_inv = self._jac6_inv = np.linalg.inv(jac6)
            except np.linalg.LinAlgError:
                pass
        self._tool = seg.tool
        want_force = (running and ((lim is not None and lim.needs_force) or (mon is not None and "force" in mon.needs)))
        want_dev = comply or (running and ((lim is not None and lim.needs_deviation) or (mon is not None and "deviation" in mon.needs)))
        t_a = force = dev = None
        if want_force or mon is not None:
            t_a = self.estimator.net_torques(q, qd, v_adc)
        if want_force:
            force = self.estimator.tool_force(q, t_a, seg.tool, jac6, check=True)
        if want_dev:
            # measured minus planned (nominal) path: along compliant axes this is what the comply
            # transform absorbs and what reveals a slip; along the others the command also carried
            # the comply offset still being released, which is not a deviation
            dev = self._maps.of(seg.tool).d @ (jac6 @ (q - gen.q))
            if comply:
                c = self.compliance
                free = np.array([i not in c.forces for i in range(6)])
                nominal = dev
                dev = np.where(free, nominal - c.offset, nominal)
                c.absorb(nominal)
        if not running:
            return
        end = lim.check(force, dev, gen.t, gen.samples) if lim is not None else None
        if end is None and mon is not None:
            s = Sample(gen.t, gen.samples, q, qd, gen.q.copy(), t_a, force, dev, how)
            self.last = s
            end = mon(s)
        if end is not None:
            gen.abort(end)

    def hold(self, q: np.ndarray) -> Command:
        """After a fault: every joint position servoed where it is (compliance off)."""
        self.compliance.forces.clear()
        self.compliance.joints.clear()
        return Command(self._q.copy() if self._q is not None else q)

    def after(self, q_nominal: np.ndarray) -> Command:
        """The command for this sample from the generator's joint angles."""
        c = self.compliance
        q_nom_prev, self._q_nom_prev = self._q_nom_prev, q_nominal.copy()
        if self._jac6 is None or not (c.active or np.any(c.offset)):
            return Command(q_nominal)
        jac6 = self._jac6
        maps = self._maps.of(self._tool)
        j6inv = self._jac6_inv
        if j6inv is None:
            raise ForceEstimateError("comply: the Jacobian is singular here; no joint can be chosen")
        c.release(self.dt)
        q_cmd = q_nominal + j6inv @ (maps.d_inv @ c.offset) if np.any(c.offset) else q_nominal
        if not c.active:
            c.joints = {}
            return Command(q_cmd)
        jt = maps.d @ jac6
        jinv = j6inv @ maps.d_inv                     # (D J6)^-1
        forces = dict(c.forces)
        chosen = select_joints(jt, sorted(forces), jinv)
        if c.joints:   # hysteresis: keep the previous joint unless clearly beaten
            for i, j in list(chosen.items()):
                old = c.joints.get(i)
                if old is not None and old != j and old not in chosen.values():
                    if abs(jt[i, j] * jinv[j, i]) < SWITCH_RATIO * abs(jt[i, old] * jinv[old, i]):
                        chosen[i] = old
        c.joints = chosen
        t_a = c.net_torques(jt)
        qd_path = np.zeros_like(q_nominal) if q_nom_prev is None else (q_nominal - q_nom_prev) / self.dt
        for i, j in chosen.items():      # damping relative to the path's own motion of that joint
            t_a[j] -= self.damping * jt[i, j] ** 2 * (self._qd[j] - qd_path[j])
        t_g = self.kin.gravity(self._q, self.model.gravity_coeffs)
        joints = sorted(chosen.values())
        if self.dither is None or self.dither.dt != self.dt:
            self.dither = Dither(self.model, self.dt)
        dither = self.dither
        dither.tick()
        correction = {}
        for j in joints:
            f = dither.correction(j, float(self._qd[j]), float(qd_path[j]))
            if f is not None:
                correction[j] = f
        dac = servo_dac(self.model, joints, t_a, t_g, self._qd, qd_path, correction=correction)
        lim = np.minimum(self.model.max_dac, DAC_MAX)    # the motor current limit (A.5.1 would refuse more)
        current = {j: int(np.clip(np.rint(dac[j]), -lim[j], lim[j])) for j in joints}
        return Command(q_cmd, current)
