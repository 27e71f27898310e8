"""simula's environment: surfaces the tool can press against and a conveyor carrying a target (no I/O).

The world around the simulated arm, as pure functions of the arm's state:

* ``Box``: a rigid block (axis-aligned in the base frame, half-open sizes allowed) the
  tool point may press into. Penetration d along the face nearest the tool gives a
  reaction force k d (plus damping c times the penetration rate, never pulling) along
  that face's outward normal, and Coulomb friction mu |F_n| against tangential sliding.
  A ``Plane`` is a box unbounded on all but one side (the floor z < height).
* ``Conveyor``: a target moving at constant velocity; its travel since t = 0 is published
  the way a conveyor encoder would be, as ADC counts on a spare channel.
* A touch-trigger probe at the tool point (``tool:...,probe=B``): bit B of ``inport1``
  is set while the tool point is inside a block by more than its trigger depth, a
  Gaussian of ``noise`` m (1 sigma; a probe's repeatability) drawn afresh each time the
  probe is free (the kinematic calibration's touches, calib record kinematics).

``Environment.joint_torques(pmodel, pdata, q, qd)`` gives the torques the world applies to
the joints, tau = J_tool^T F (J_tool the tool point's base-frame Jacobian from Pinocchio,
the simulator's own model), which ``EnvironmentArm`` adds to the arm's external torque
every servo substep. Stiffness and damping are ``estimate``s: a steel probe on an
aluminium fixture through a light wrist, compliant at about 2e4 N/m.

simula builds it from its command line: ``python -m rci.simula --env plane:z=0.12 --env
tool:z=0.05 -p --power-on`` (``parse_environment`` reads the words; docs/simula.md).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import pinocchio as pin

from .arm import N_ADC, SimulatedArm, SensorSample

# estimate: contact stiffness and damping of tool + fixture (see module docstring)
DEFAULT_STIFFNESS = 2.0e4     # N/m
DEFAULT_DAMPING = 100.0       # N*s/m
CONVEYOR_CHANNEL = 12         # ADC channel of the conveyor encoder (0-5 currents, 6-11 pots)
CONVEYOR_COUNTS_PER_M = 1.0e4  # 0.1 mm per count; wraps every 0.4096 m, like a 12-bit encoder counter
_TANGENT_EPS = 1e-4           # m/s below which sliding friction is smoothed (avoids chatter at rest)


@dataclass(frozen=True)
class Box:
    """An axis-aligned block [lo, hi] (m, base frame; +-inf for an unbounded side) the tool point cannot enter."""

    lo: np.ndarray
    hi: np.ndarray
    stiffness: float = DEFAULT_STIFFNESS
    damping: float = DEFAULT_DAMPING
    mu: float = 0.0

    def __post_init__(self) -> None:
        lo, hi = np.asarray(self.lo, float), np.asarray(self.hi, float)
        if lo.shape != (3,) or hi.shape != (3,) or np.any(np.isnan(lo)) or np.any(np.isnan(hi)) or np.any(lo >= hi):
            raise ValueError(f"box: lo {self.lo!r} must be below hi {self.hi!r} on every axis (m)")
        if not (self.stiffness > 0 and self.damping >= 0 and self.mu >= 0):
            raise ValueError(f"box: stiffness {self.stiffness} must be > 0, damping {self.damping} and mu {self.mu} >= 0")
        object.__setattr__(self, "lo", lo)
        object.__setattr__(self, "hi", hi)

    def contact(self, p: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Force (N, base frame) on a tool point at p (m) moving at v (m/s); zero outside the box."""
        if np.any(p <= self.lo) or np.any(p >= self.hi):
            return np.zeros(3)
        depth_lo, depth_hi = p - self.lo, self.hi - p          # distances to the faces
        k_lo, k_hi = int(np.argmin(depth_lo)), int(np.argmin(depth_hi))
        if depth_lo[k_lo] < depth_hi[k_hi]:
            axis, depth, sign = k_lo, depth_lo[k_lo], -1.0
        else:
            axis, depth, sign = k_hi, depth_hi[k_hi], 1.0
        normal = np.zeros(3)
        normal[axis] = sign
        rate = -float(v @ normal)                               # penetration speed
        fn = max(0.0, self.stiffness * depth + self.damping * rate)
        f = fn * normal
        if self.mu > 0 and fn > 0:
            vt = v - (v @ normal) * normal
            speed = float(np.linalg.norm(vt))
            f = f - self.mu * fn * vt / max(speed, _TANGENT_EPS)
        return f


def plane(height: float, stiffness: float = DEFAULT_STIFFNESS, damping: float = DEFAULT_DAMPING,
          mu: float = 0.0) -> Box:
    """The floor z < height (m) as a box unbounded sideways and downwards."""
    inf = np.inf
    return Box(np.array([-inf, -inf, -inf]), np.array([inf, inf, float(height)]), stiffness, damping, mu)


@dataclass(frozen=True)
class Conveyor:
    """A target carried from ``start`` (m, base frame) at ``velocity`` (m/s) from simulated time 0."""

    start: np.ndarray
    velocity: np.ndarray

    def __post_init__(self) -> None:
        for name in ("start", "velocity"):
            a = np.asarray(getattr(self, name), float)
            if a.shape != (3,) or not np.all(np.isfinite(a)):
                raise ValueError(f"conveyor: {name} must be 3 finite numbers, got {getattr(self, name)!r}")
            object.__setattr__(self, name, a)

    def position(self, t: float) -> np.ndarray:
        """Target position (m, base frame) at time t (s)."""
        return self.start + self.velocity * t

    def travel(self, t: float) -> float:
        """Distance travelled (m) along the belt by time t."""
        return float(np.linalg.norm(self.velocity)) * t

    def encoder(self, t: float) -> int:
        """The travel as 12-bit two's-complement ADC counts (0.1 mm each, wrapping)."""
        c = int(np.floor(self.travel(t) * CONVEYOR_COUNTS_PER_M)) & 0xFFF
        return c - 0x1000 if c >= 0x800 else c


@dataclass(frozen=True)
class Environment:
    """Everything around the arm: blocks to press against, an optional conveyor, the tool point.

    ``tool`` is the tool point in the link-6 frame (m).
    """

    boxes: tuple[Box, ...] = ()
    conveyor: Conveyor | None = None
    tool: np.ndarray = field(default_factory=lambda: np.zeros(3))
    probe_bit: int | None = None       # inport1 bit of a touch-trigger probe at the tool point
    probe_noise: float = 0.0           # m, 1 sigma of the probe's trigger depth

    def depth(self, p: np.ndarray) -> float:
        """How deep (m) the point p lies inside the deepest block (negative: outside all)."""
        best = -np.inf
        for b in self.boxes:
            best = max(best, float(np.min(np.minimum(p - b.lo, b.hi - p))))
        return best

    def tool_point(self, pmodel: pin.Model, pdata: pin.Data, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(tool point in the base frame, its 3x6 base-frame Jacobian) by Pinocchio."""
        fid = pmodel.getFrameId("link6")
        pin.forwardKinematics(pmodel, pdata, q)
        pin.updateFramePlacements(pmodel, pdata)
        m = pdata.oMf[fid]
        p = m.translation + m.rotation @ self.tool
        jac = pin.computeFrameJacobian(pmodel, pdata, q, fid, pin.LOCAL_WORLD_ALIGNED)
        r = p - m.translation
        jp = jac[:3] + np.cross(jac[3:].T, r).T                 # v_p = v + w x r
        return p, jp

    def force(self, p: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Total reaction force (N, base frame) on a tool point at p moving at v."""
        f = np.zeros(3)
        for b in self.boxes:
            f = f + b.contact(p, v)
        return f

    def joint_torques(self, pmodel: pin.Model, pdata: pin.Data, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(joint torques the world applies, N*m; force on the tool, N base frame) at state (q, qd)."""
        if not self.boxes:
            return np.zeros(len(q)), np.zeros(3)
        # the Jacobian only when the tool point is inside a block: a free tool feels nothing
        fid = pmodel.getFrameId("link6")
        pin.forwardKinematics(pmodel, pdata, q)
        m = pin.updateFramePlacement(pmodel, pdata, fid)
        if self.depth(m.translation + m.rotation @ self.tool) <= 0.0:
            return np.zeros(len(q)), np.zeros(3)
        p, jp = self.tool_point(pmodel, pdata, q)
        f = self.force(p, jp @ qd)
        return jp.T @ f, f


def parse_environment(specs: list[str]) -> Environment:
    """An Environment from command-line words, each ``kind:key=value,...``.

    ``plane:z=0.10[,k=2e4,c=100,mu=0]``, ``box:x0=..,x1=..,y0=..,y1=..,z0=..,z1=..[,k,c,mu]``
    (omitted bounds are unbounded), ``conveyor:x=..,y=..,z=..,vx=..,vy=..,vz=..``,
    ``tool:z=0.05`` (tool point in link 6, m). ValueError names the bad word.
    """
    boxes: list[Box] = []
    conveyor = None
    tool = np.zeros(3)
    probe: tuple[int, float] | None = None
    for spec in specs:
        kind, _, rest = spec.partition(":")
        kv: dict[str, float] = {}
        for item in filter(None, rest.split(",")):
            k, eq, v = item.partition("=")
            try:
                if not eq:
                    raise ValueError
                kv[k.strip().lower()] = float(v)
            except ValueError:
                raise ValueError(f"environment {spec!r}: {item!r} is not key=number") from None
        common = dict(stiffness=kv.pop("k", DEFAULT_STIFFNESS), damping=kv.pop("c", DEFAULT_DAMPING), mu=kv.pop("mu", 0.0))
        kind = kind.strip().lower()
        if kind == "plane":
            if set(kv) != {"z"}:
                raise ValueError(f"environment {spec!r}: a plane needs z=<height m> (and optional k, c, mu)")
            boxes.append(plane(kv["z"], **common))
        elif kind == "box":
            bad = set(kv) - {"x0", "x1", "y0", "y1", "z0", "z1"}
            if bad:
                raise ValueError(f"environment {spec!r}: unknown box keys {sorted(bad)}")
            lo = np.array([kv.get(a + "0", -np.inf) for a in "xyz"])
            hi = np.array([kv.get(a + "1", np.inf) for a in "xyz"])
            boxes.append(Box(lo, hi, **common))
        elif kind == "conveyor":
            bad = set(kv) - {"x", "y", "z", "vx", "vy", "vz"}
            if bad:
                raise ValueError(f"environment {spec!r}: unknown conveyor keys {sorted(bad)}")
            conveyor = Conveyor(np.array([kv.get(a, 0.0) for a in "xyz"]), np.array([kv.get("v" + a, 0.0) for a in "xyz"]))
        elif kind == "tool":
            bad = set(kv) - {"x", "y", "z", "probe", "noise"}
            if bad:
                raise ValueError(f"environment {spec!r}: unknown tool keys {sorted(bad)}")
            tool = np.array([kv.get(a, 0.0) for a in "xyz"])
            if "probe" in kv:
                bit = kv["probe"]
                if bit != int(bit) or not 0 <= bit < 16:
                    raise ValueError(f"environment {spec!r}: probe must be an inport1 bit 0..15")
                probe = (int(bit), kv.get("noise", 0.0))
                if not (np.isfinite(probe[1]) and probe[1] >= 0):
                    raise ValueError(f"environment {spec!r}: noise must be >= 0 m")
            elif "noise" in kv:
                raise ValueError(f"environment {spec!r}: noise is the probe's; give probe=<bit> too")
        else:
            raise ValueError(f"environment {spec!r}: kind {kind!r} is not plane, box, conveyor or tool")
    return Environment(tuple(boxes), conveyor, tool, None if probe is None else probe[0],
                       0.0 if probe is None else probe[1])


class EnvironmentArm(SimulatedArm):
    """The simulated arm inside an Environment: contact torques join the external torque every substep,
    and the conveyor's encoder appears on ADC channel ``CONVEYOR_CHANNEL``."""

    def __init__(self, *args, environment: Environment, **kw) -> None:
        super().__init__(*args, **kw)
        self.environment = environment
        self.contact_force = np.zeros(3)     # last reaction force on the tool (N, base frame)
        self._env_data = self.pm.createData()
        self._probe_rng = np.random.default_rng(self.rng.integers(1 << 63)) if environment.probe_bit is not None else None
        self._trigger_depth = 0.0
        self._touching = False
        self._redraw_trigger()

    def _redraw_trigger(self) -> None:
        if self._probe_rng is not None:
            self._trigger_depth = self.environment.probe_noise * float(self._probe_rng.standard_normal())

    def probe_touching(self) -> bool:
        """The touch-trigger probe's state now (False when there is no probe)."""
        env = self.environment
        if env.probe_bit is None:
            return False
        fid = self.pm.getFrameId("link6")
        pin.forwardKinematics(self.pm, self._env_data, self.q)
        m = pin.updateFramePlacement(self.pm, self._env_data, fid)
        touching = env.depth(m.translation + m.rotation @ env.tool) > self._trigger_depth
        if self._touching and not touching:
            self._redraw_trigger()
        self._touching = touching
        return touching

    def _substep(self, h: float) -> None:
        user = self.ext
        tau, self.contact_force = self.environment.joint_torques(self.pm, self._env_data, self.q, self.qd)
        self.ext = user + tau
        try:
            super()._substep(h)
        finally:
            self.ext = user

    def sample(self) -> SensorSample:
        s = super().sample()
        conv = self.environment.conveyor
        if conv is not None and CONVEYOR_CHANNEL < N_ADC:
            s.adcr[CONVEYOR_CHANNEL] = conv.encoder(self.t)
        if self.probe_touching():
            s = replace(s, inport1=s.inport1 | (1 << self.environment.probe_bit))
        return s

    def snapshot(self) -> dict:
        d = super().snapshot()
        d["contact_force"] = [float(x) for x in self.contact_force]
        if self.environment.conveyor is not None:
            d["conveyor"] = [float(x) for x in self.environment.conveyor.position(self.t)]
        return d
