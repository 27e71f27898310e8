"""The touches of the kinematic calibration: a fixture of known faces and where the probe meets them.

Thesis 3.84 leaves the measurement open ("measurements may in principle be made to
determine e"). calib measures the arm the way a robot cell without a laser tracker
can: a touch-trigger probe on the flange (a switch wired to the controller's input port
``inport1``) is driven slowly against the faces of a fixture whose position in the base
frame is known (a floor and two walls of a machined corner). The joint angles at the
moment the switch closes put the probe tip on a known plane, n . p(q, e) = h: one
equation per touch in the DH errors e. Why a switch and not the motor currents: the
thesis's own conclusion (4.7) is that friction makes motor currents inadequate for
reliable Cartesian force sensing, while a switch has a repeatability of about a
micrometre; the encoders (a count is 5 to 50 micrometres of tip travel on the PUMA 260)
then set the resolution.

The probe tip is off the flange axis (a cranked stylus, ``TIP``): with the tip on the
axis, a small turn of the wrist and a shift of the wrist centre move the tip alike, and
the fit could not tell d alpha5 from d d5 or d theta5 from d a5.

``touch_plan`` chooses the touches (seeded): tip points spread over each face, the
probe tilted up to ``TILT_DEG`` from the face normal and turned about it at random, in
both wrist configurations. Every move between touches is a straight line of the tip
inside the free region (the intersection of the faces' half-spaces, which is convex),
or a joint move between the faces' hubs, 10 cm in front of each face (``Face.hub``);
``touch_plan`` checks both with the nominal model and a margin for the arm's errors.
"""
from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass, field

import numpy as np

from rcci.calib.exceptions import CalibError

TOUCH_RATE_HZ = 250            # one count of a joint's encoder per cycle at most in the slow approach
STANDOFF = 0.006               # m from the nominal face where each approach starts (arm errors < 4 mm)
OVERTRAVEL = 0.004             # m past the nominal face where an approach gives up
FAST = 0.020                   # m/s, first approach
BACKOFF = 0.0005               # m back along the line after the first contact
SLOW = 0.0015                  # m/s, the measuring approach: 6 um per cycle at 250 Hz, about one
                               # encoder count of one joint (5 to 50 um of tip travel)
LINEAR = 0.12                  # m/s, straight moves of the tip between touches
ANGULAR = 1.5                  # rad/s, turning of the probe on those moves
JOINT_SPEED = 1.5              # rad/s, joint moves between hubs (a third of the slowest joint's limit)
TILT_DEG = 25.0                # probe axis within this of the face's inward normal
CLEARANCE = 0.020              # m: joint moves between hubs keep the tip this far from every face
# the probe tip in link-6 coordinates (m): a 8 cm stylus cranked 2 cm off the flange axis
TIP = (0.02, 0.0, 0.08)
PROBE_BIT = 1                  # inport1 bit of the probe (bit 0 is the hand)
PROBE_NOISE = 2e-6             # m, simula's trigger repeatability (1 sigma)
HUB_DISTANCE = 0.10            # m: each face's hub, where the probe turns, is this far in front of it
# the configurations (arm, elbow, wrist) the touches are made in: both arms and both wrists
# (the elbow-down solutions leave the PUMA 260's estimated joint-3 range), so that the DH
# errors are seen from different sides, as a user's programs will work
CONFIGS = ((-1, 1, 1), (-1, 1, -1), (1, 1, 1), (1, 1, -1))


@dataclass(frozen=True)
class Face:
    """A plane of the fixture: points p with normal . p = offset; the free side is
    normal . p > offset (``normal`` points out of the material)."""

    name: str
    normal: tuple[float, float, float]
    offset: float
    # tip points are drawn in this box (m, base frame), then put on the plane
    region: tuple[tuple[float, float], tuple[float, float], tuple[float, float]]

    def simula_word(self) -> str:
        """The face as a simula ``--env`` block (the material on the other side)."""
        n = np.asarray(self.normal)
        axis = int(np.argmax(np.abs(n)))
        if abs(abs(n[axis]) - 1.0) > 1e-12:
            raise CalibError(f"face {self.name}: simula's blocks are axis-aligned; normal {self.normal} is not")
        bound = float(self.offset / n[axis])
        key = "xyz"[axis] + ("1" if n[axis] > 0 else "0")
        return f"box:{key}={bound!r}"

    @property
    def hub(self) -> np.ndarray:
        """Where the tip turns between groups of touches: HUB_DISTANCE in front of the
        middle of the face's region."""
        centre = np.array([0.5 * (a + b) for a, b in self.region])
        return centre + HUB_DISTANCE * np.asarray(self.normal, dtype=float)


@dataclass(frozen=True)
class Fixture:
    """The faces the probe touches, in the base frame (m)."""

    faces: tuple[Face, ...]

    def distance(self, p: np.ndarray) -> np.ndarray:
        """Signed distance (m) of points p (..., 3) from each face, positive on the free side."""
        n = np.array([f.normal for f in self.faces])
        h = np.array([f.offset for f in self.faces])
        return np.asarray(p) @ n.T - h

    def meta(self) -> list[dict]:
        return [{"name": f.name, "normal": list(f.normal), "offset": f.offset} for f in self.faces]


# The PUMA 260's calibration corner: the table top 20 cm below the shoulder, a wall 36 cm
# in front of the waist axis and one 30 cm to its right (estimates: a cell a PUMA 260 reaches
# with the probe at any tilt up to TILT_DEG).
CORNER = Fixture((
    Face("floor", (0.0, 0.0, 1.0), -0.20, ((0.10, 0.30), (-0.25, 0.05), (-0.20, -0.20))),
    Face("front", (-1.0, 0.0, 0.0), -0.36, ((0.36, 0.36), (-0.22, 0.06), (-0.14, 0.10))),
    Face("right", (0.0, 1.0, 0.0), -0.30, ((0.04, 0.28), (-0.30, -0.30), (-0.14, 0.10))),
))


def scaled_corner(scale: float, shoulder_m: float) -> Fixture:
    """CORNER scaled by ``scale`` about the shoulder and raised by ``shoulder_m`` (m): the PUMA
    260's cell for a larger arm whose base frame is on its mounting surface, not at its shoulder."""
    faces = []
    for f in CORNER.faces:
        region = tuple((a * scale + (shoulder_m if i == 2 else 0.0), b * scale + (shoulder_m if i == 2 else 0.0))
                       for i, (a, b) in enumerate(f.region))
        faces.append(Face(f.name, f.normal, f.offset * scale + f.normal[2] * shoulder_m, region))
    return Fixture(tuple(faces))


# Each arm's calibration corner, a plan parameter (calib's own per-arm data: the robot data files
# hold no cell). The PUMA 260's corner is out of a larger arm's reach with the probe held to
# TILT_DEG: the PUMA 560's base frame is on its mounting surface, 0.672 m below the shoulder
# (models/puma560.toml d1), so the PUMA 260's table 0.20 m below the frame is under its pedestal;
# the corner scaled by its upper arm's ratio (0.4318 / 0.2032 m, 2.1) about its shoulder puts
# the table 0.25 m above the mounting surface and the walls 0.76 m in front and 0.63 m to the
# right: 47 of 48 touches (one dropped: its way back leaves a range). The Stanford arm's boom
# (0.3-1.27 m) reaches the PUMA 260's corner (0.2 m below its mounting surface) in few
# configurations: 24 of 48 touches (8 per face); 2.5 times the corner about its shoulder (0.412 m,
# d1: table at -0.09 m, walls 0.9 and 0.75 m away) gives it 40 (16 + 8 + 16).
# tests/test_calib_fixtures.py counts them.
# The Microbo (a cylindrical arm: a vertical slide of 0.05-0.35 m, a radial one of 0.2-0.5 m,
# models/microbo.toml) reaches no point of the PUMA 260's table, 0.2 m below its base frame;
# its corner is a table 8 cm above the base frame with walls 0.45 m in front and 0.35 m to
# the right, inside the slides' reach: 16 touches per face in both wrist configurations.
MICROBO_CORNER = Fixture((
    Face("floor", (0.0, 0.0, 1.0), 0.08, ((0.22, 0.40), (-0.25, 0.10), (0.08, 0.08))),
    Face("front", (-1.0, 0.0, 0.0), -0.45, ((0.45, 0.45), (-0.20, 0.10), (0.14, 0.30))),
    Face("right", (0.0, 1.0, 0.0), -0.35, ((0.05, 0.35), (-0.35, -0.35), (0.14, 0.30))),
))
FIXTURES = {"puma260": lambda: CORNER, "microbo": lambda: MICROBO_CORNER,
            "puma560": lambda: scaled_corner(2.1, 0.672),
            "stanford": lambda: scaled_corner(2.5, 0.412)}


def fixture_for(robot: str) -> Fixture:
    """The calibration corner of ``robot`` (FIXTURES); CORNER for an arm without one of its own."""
    return FIXTURES.get(robot, lambda: CORNER)()


def simula_words(fixture: Fixture = CORNER, tip=TIP, bit: int = PROBE_BIT,
                 noise: float = PROBE_NOISE) -> list[str]:
    """simula ``--env`` words for the fixture and the probe."""
    x, y, z = tip
    return [f.simula_word() for f in fixture.faces] + [f"tool:x={x!r},y={y!r},z={z!r},probe={bit},noise={noise!r}"]


@dataclass(frozen=True)
class Touch:
    """One touch: the tip's nominal contact point on ``face`` and the orientation of
    link 6 (rotation matrix, base frame), in configuration ``config`` (arm, elbow, wrist)."""

    face: int
    point: np.ndarray
    rotation: np.ndarray
    config: tuple[int, int, int]
    via_hub: bool = True          # reached by way of the face's hub (else straight from the last touch)

    def approach(self, fixture: Fixture) -> np.ndarray:
        """Unit direction of the approach: into the face."""
        return -np.asarray(fixture.faces[self.face].normal, dtype=float)


@dataclass
class TouchPlan:
    """The touches in the order they are made, and what the log records about them."""

    name: str
    fixture: Fixture
    touches: list[Touch]
    tip: tuple[float, float, float] = TIP
    bit: int = PROBE_BIT
    rate_hz: int = TOUCH_RATE_HZ
    meta: dict = field(default_factory=dict)


def tool_transform(tip) -> np.ndarray:
    """Link 6 to the probe tip (4x4, m)."""
    T = np.eye(4)
    T[:3, 3] = tip
    return T


def pose_t6(point: np.ndarray, rotation: np.ndarray, tip) -> np.ndarray:
    """T6 (4x4) that puts the tip at ``point`` with link 6 turned to ``rotation``."""
    T = np.eye(4)
    T[:3, :3] = rotation
    T[:3, 3] = np.asarray(point) - rotation @ np.asarray(tip, dtype=float)
    return T


def _rotation(approach: np.ndarray, tilt: float, tilt_dir: float, spin: float) -> np.ndarray:
    """Link 6's rotation: z6 along ``approach`` tilted by ``tilt`` rad (towards azimuth
    ``tilt_dir``), then turned by ``spin`` about z6."""
    a = approach / np.linalg.norm(approach)
    helper = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(a, helper)
    u /= np.linalg.norm(u)
    v = np.cross(a, u)
    axis = np.cos(tilt_dir) * u + np.sin(tilt_dir) * v
    z = np.cos(tilt) * a + np.sin(tilt) * np.cross(axis, a)
    x0 = np.cross(np.array([0.0, 0.0, 1.0]) if abs(z[2]) < 0.9 else np.array([0.0, 1.0, 0.0]), z)
    x0 /= np.linalg.norm(x0)
    y0 = np.cross(z, x0)
    x = np.cos(spin) * x0 + np.sin(spin) * y0
    y = np.cross(z, x)
    return np.column_stack([x, y, z])


def arm_configs(kin) -> tuple[tuple[int, ...], ...]:
    """The configurations touches are made in on the arm of ``kin``: CONFIGS on an arm with
    arm, elbow and wrist solutions; both wrists on one whose inverse kinematics has a wrist
    choice only (the Microbo: a cylindrical arm, thesis 3.4)."""
    signs = [dataclasses.astuple(c) for c in kin.CONFIGS]
    if all(len(c) == 3 for c in signs):
        return CONFIGS
    return tuple(tuple(int(x) for x in c) for c in signs)


def _config(kin, signs):
    return kin.Config(*signs)


def _solve(kin, T: np.ndarray, config, q_ref: np.ndarray | None, lower: np.ndarray,
           upper: np.ndarray, margin: float) -> np.ndarray | None:
    """Nominal IK of T in ``config`` within the joint ranges (with ``margin`` rad) and
    away from the wrist singularity; None when there is none."""
    try:
        q = in_range(kin.ik(T, config, q_ref), lower, upper)
    except ValueError:
        return None
    if np.any(q < lower + margin) or np.any(q > upper - margin) or abs(np.sin(q[4])) < 0.25:
        return None
    return q


LINE_RATE_SHARE = 0.5   # a straight line's joint rates stay under this share of each joint's limit


def cartesian_line(kin, A: np.ndarray, B: np.ndarray, config, q_start: np.ndarray, rate_hz: float,
                   tip, linear: float = LINEAR, angular: float = ANGULAR, steady: bool = False) -> np.ndarray:
    """Joint setpoints (N, 6) moving the tip on a straight line from pose A to pose B (T6,
    4x4), link 6 turning about one axis, with a smooth (cosine) speed profile, or with
    ``steady`` at constant speed after a 50 ms start (the approaches); nominal IK. A line
    whose joint rates would pass LINE_RATE_SHARE of the arm's velocity limits (near the
    wrist's singularity: the PUMA 560's joint 6 asked 4.08 rad/s of its 4) is run slower."""
    vmax = _line_rates(kin.ROBOT)
    out = _line(kin, A, B, config, q_start, rate_hz, tip, linear, angular, steady)
    for _ in range(4):
        over = float((np.abs(np.diff(out, axis=0)) * rate_hz / vmax).max(initial=0.0))
        if over <= 1.0:
            break
        linear, angular = linear / (1.2 * over), angular / (1.2 * over)
        out = _line(kin, A, B, config, q_start, rate_hz, tip, linear, angular, steady)
    return out


@functools.lru_cache(maxsize=None)
def _line_rates(robot: str) -> np.ndarray:
    """LINE_RATE_SHARE of each joint's velocity limit (rad/s, m/s) for ``robot``."""
    from rcci.models import load_robot

    return LINE_RATE_SHARE * np.asarray(load_robot(robot).max_velocity, float)


def _line(kin, A: np.ndarray, B: np.ndarray, config, q_start: np.ndarray, rate_hz: float,
          tip, linear: float, angular: float, steady: bool) -> np.ndarray:
    """cartesian_line at the speeds given."""
    tool = tool_transform(tip)
    PA, PB = A @ tool, B @ tool
    rv = rotation_vector(PA[:3, :3].T @ PB[:3, :3])
    angle = float(np.linalg.norm(rv))
    axis = rv / angle if angle > 0.0 else np.array([0.0, 0.0, 1.0])
    dist = float(np.linalg.norm(PB[:3, 3] - PA[:3, 3]))
    if steady:
        ramp = 0.05                                         # s to reach the speed
        duration = max(dist / linear, angle / angular, 2.0 / rate_hz) + ramp
        t = np.arange(int(np.ceil(duration * rate_hz)) + 1) / rate_hz
        s = np.where(t < ramp, 0.5 * t * t / ramp, t - 0.5 * ramp) / (duration - 0.5 * ramp)
        s = np.clip(s, 0.0, 1.0)
    else:
        duration = max(dist / linear, angle / angular, 2.0 / rate_hz) * np.pi / 2  # cosine profile peak
        n = int(np.ceil(duration * rate_hz)) + 1
        s = 0.5 - 0.5 * np.cos(np.pi * np.arange(n) / (n - 1))
    n = len(s)
    out = np.empty((n, 6))
    q = q_start
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    for k, sk in enumerate(s):
        a = sk * angle
        Rk = PA[:3, :3] @ (np.eye(3) + np.sin(a) * K + (1 - np.cos(a)) * K @ K)
        P = np.eye(4)
        P[:3, :3] = Rk
        P[:3, 3] = PA[:3, 3] + sk * (PB[:3, 3] - PA[:3, 3])
        q = out[k] = kin.ik(P @ np.linalg.inv(tool), config, q)
    return out


def rotation_vector(R: np.ndarray) -> np.ndarray:
    """The rotation vector (axis times angle, rad) of a rotation matrix, also near pi."""
    w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    s, c = 0.5 * np.linalg.norm(w), 0.5 * (np.trace(R) - 1.0)
    angle = float(np.arctan2(s, c))
    if s > 1e-6:
        return angle / (2.0 * s) * w
    if c > 0:                                   # near identity: first order
        return 0.5 * w
    # near pi: the axis from the symmetric part, R = 2 k k^T - I
    k = np.sqrt(np.clip((np.diag(R) + 1.0) / 2.0, 0.0, None))
    i = int(np.argmax(k))
    k[np.arange(3) != i] = (R[i, np.arange(3) != i] + R[np.arange(3) != i, i]) / (4.0 * k[i])
    if np.dot(k, w) < 0:
        k = -k
    return angle * k / np.linalg.norm(k)


JOINT_RATE_SHARE = 0.8   # a joint move's peak rate stays under this share of each joint's limit


def joint_line(qa: np.ndarray, qb: np.ndarray, rate_hz: float, speed: float = JOINT_SPEED,
               robot: str | None = None) -> np.ndarray:
    """Joint setpoints (N, 6) from qa to qb, every joint arriving together (cosine profile),
    each joint's peak rate ``speed`` at most, and with ``robot`` JOINT_RATE_SHARE of its limit
    at most (the Stanford arm's joint 2 is limited to JOINT_SPEED itself)."""
    cap = np.full(len(qa), speed) if robot is None else \
        np.minimum(speed, JOINT_RATE_SHARE / LINE_RATE_SHARE * _line_rates(robot))
    duration = max(float(np.max(np.abs(qb - qa) / cap)), 2.0 / rate_hz) * np.pi / 2
    n = int(np.ceil(duration * rate_hz)) + 1
    s = 0.5 - 0.5 * np.cos(np.pi * np.arange(n) / (n - 1))
    return qa + s[:, None] * (qb - qa)


def touch_plan(n_per_face: int = 16, seed: int = 1985, fixture: Fixture | None = None,
               tip=TIP, robot: str = "puma260", name: str = "kinematics") -> TouchPlan:
    """``n_per_face`` touches on each face of ``fixture`` (default the arm's, ``fixture_for``),
    shared among CONFIGS (a configuration that reaches few points of a face leaves its share
    to the others), grouped by face and configuration (so that the arm changes configuration
    at a hub only)."""
    from rcci.models import load_robot
    from rccl.kinematics import load

    fixture = fixture_for(robot) if fixture is None else fixture
    kin = load(robot)
    configs = arm_configs(kin)
    model = load_robot(robot)
    lower, upper = np.asarray(model.lower), np.asarray(model.upper)
    rng = np.random.default_rng(seed)
    margin = np.radians(5.0)
    touches: list[Touch] = []
    for fi, face in enumerate(fixture.faces):
        on_face = 0
        unasked = []
        for c, config in enumerate(configs):
            want = (n_per_face - on_face) // (len(configs) - c)
            if want == 0:
                unasked.append(config)
            group = _draw_group(kin, rng, fi, fixture, config, want, tip, lower, upper, margin)
            on_face += len(group)
            touches += _nearest_first(group, face.hub)
        # a few touches per face leave the first configurations no share (1 // 4 == 0): when the
        # ones tried reach no point, the face gets its touches from those not yet asked
        for config in unasked if on_face == 0 else ():
            group = _draw_group(kin, rng, fi, fixture, config, n_per_face - on_face, tip, lower, upper, margin)
            on_face += len(group)
            touches += _nearest_first(group, face.hub)
        if on_face == 0:
            raise CalibError(f"touch plan: no point of face {face.name} is reachable in any configuration")
    touches = _route(kin, touches, fixture, tip, lower, upper, margin)
    meta = {"experiment": "kinematics", "fixture": fixture.meta(), "tip": list(tip),
            "probe_bit": PROBE_BIT, "plan_seed": seed, "touches": len(touches),
            "slow_speed": SLOW, "simula_env": simula_words(fixture, tip)}
    return TouchPlan(name, fixture, touches, tuple(tip), PROBE_BIT, TOUCH_RATE_HZ, meta)


def _draw_group(kin, rng, fi: int, fixture: Fixture, config, want: int, tip, lower, upper,
                margin) -> list[Touch]:
    """Up to ``want`` reachable touches of face ``fi`` in ``config``, from 1500 random draws at most."""
    face = fixture.faces[fi]
    group: list[Touch] = []
    for _ in range(1500):
        if len(group) >= want:
            break
        p = np.array([rng.uniform(*r) for r in face.region])
        R = _rotation(-np.asarray(face.normal, float), np.radians(rng.uniform(0, TILT_DEG)),
                      rng.uniform(0, 2 * np.pi), rng.uniform(-np.pi, np.pi))
        t = Touch(fi, p, R, config)
        if _reachable(kin, t, fixture, tip, lower, upper, margin):
            group.append(t)
    return group


def _reachable(kin, t: Touch, fixture: Fixture, tip, lower, upper, margin) -> bool:
    """The touch's approach line and its lines to the hub have nominal IK in its configuration."""
    config = _config(kin, t.config)
    d = t.approach(fixture)
    hub = fixture.faces[t.face].hub
    ends = [t.point - STANDOFF * d, t.point + OVERTRAVEL * d, hub]
    q = None
    for p in ends:
        q = _solve(kin, pose_t6(p, t.rotation, tip), config, q, lower, upper, margin)
        if q is None:
            return False
    # every point of the line from the hub to the standoff
    for s in np.linspace(0.0, 1.0, 12):
        p = (1 - s) * hub + s * ends[0]
        if _solve(kin, pose_t6(p, t.rotation, tip), config, q, lower, upper, margin) is None:
            return False
    return True


def _gap(kin, qa: np.ndarray, qb: np.ndarray, fixture: Fixture, tool: np.ndarray) -> float:
    """Least distance (m, nominal model) of the tip from the faces on the joint line qa -> qb."""
    Q = qa + np.linspace(0.0, 1.0, 61)[:, None] * (qb - qa)
    return float(min(fixture.distance((kin.fk(q) @ tool)[:3, 3]).min() for q in Q))


# joints 2 and 3 of the upright arm (the wrist high above the shoulder, far from every face)
UPRIGHT = (np.pi / 2, -np.pi / 2)


# joint moves between hubs, tried in this order until one keeps the tip clear: each stage
# moves a set of joints to their goal ("up" raises joints 2 and 3 to UPRIGHT, "down"
# lowers them to the goal)
ROUTES = (((0, 1, 2, 3, 4, 5),),
          ("up", (0, 3, 4, 5), "down"),
          ((3, 4, 5), "up", (0,), "down"),
          ("up", (0,), (3, 4, 5), "down"),
          ("up", (3, 4, 5), (0,), "down"))


def joint_route(kin, qa: np.ndarray, qb: np.ndarray, fixture: Fixture, tip, where: str) -> list[np.ndarray]:
    """Joint waypoints from qa to qb that keep the tip (nominal model) CLEARANCE from every
    face: the first of ROUTES that does (straight; by way of the upright arm, joints 2 and 3
    raised, the others turned there in some order). CalibError when none does."""
    tool = tool_transform(tip)
    for stages in ROUTES:
        route = [np.array(qa, dtype=float)]
        for stage in stages:
            q = route[-1].copy()
            if stage == "up":
                q[1:3] = UPRIGHT
            elif stage == "down":
                q[1:3] = qb[1:3]
            else:
                q[list(stage)] = qb[list(stage)]
            route.append(q)
        gap = min(_gap(kin, a, b, fixture, tool) for a, b in zip(route, route[1:]))
        if gap >= CLEARANCE:
            return route
    raise CalibError(f"touch plan: {where}: every joint route passes within {1e3 * CLEARANCE:.0f} mm "
                     f"of a face")


def _nearest_first(group: list[Touch], hub: np.ndarray) -> list[Touch]:
    """Order touches by a greedy shortest walk from the hub."""
    left = list(group)
    here = hub
    out = []
    while left:
        k = int(np.argmin([np.linalg.norm(t.point - here) for t in left]))
        here = left[k].point
        out.append(left.pop(k))
    return out




def hub_pose(kin, t: Touch, fixture: Fixture, tip) -> np.ndarray:
    """Joint angles (nominal) with the tip at the hub of t's face and t's orientation,
    each joint on its principal branch (moved by a turn into its range if need be), so
    that a joint the straight moves have wound up is unwound at the hub."""
    q = kin.ik(pose_t6(fixture.faces[t.face].hub, t.rotation, tip), kin.Config(*t.config), None)
    return in_range(q, kin.LOWER, kin.UPPER)


def in_range(q: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """q with each revolute joint moved by a turn where that brings it into [lower, upper]."""
    q = np.array(q, dtype=float)
    turn = 2 * np.pi
    q = np.where((q < lower) & (q + turn <= upper), q + turn, q)
    return np.where((q > upper) & (q - turn >= lower), q - turn, q)


def _route(kin, touches: list[Touch], fixture: Fixture, tip, lower, upper, margin) -> list[Touch]:
    """Decide how each touch is reached, as the program will move (nominal model): straight
    from the last stand-off when that line keeps every joint in range, else by way of the
    face's hub (each joint then on its principal branch). A touch that neither way reaches
    (a joint out of range, or no clear joint route between the hubs) is dropped."""
    out: list[Touch] = []
    q = None
    prev: Touch | None = None
    rate = TOUCH_RATE_HZ
    for t in touches:
        config = kin.Config(*t.config)
        standoff = pose_t6(t.point - STANDOFF * t.approach(fixture), t.rotation, tip)
        straight = prev is not None and (prev.face, prev.config) == (t.face, t.config)
        if straight:
            path = cartesian_line(kin, kin.fk(q), standoff, config, q, rate, tip)
            straight = bool(np.all(path >= lower + margin) and np.all(path <= upper - margin))
        if not straight:
            qa = None
            if prev is not None:       # the program goes back to the last face's hub first
                qa = cartesian_line(kin, kin.fk(q), pose_t6(fixture.faces[prev.face].hub, prev.rotation, tip),
                                    kin.Config(*prev.config), q, rate, tip)[-1]
            qb = hub_pose(kin, t, fixture, tip)
            if qa is not None:
                try:
                    joint_route(kin, qa, qb, fixture, tip, "")
                except CalibError:
                    continue    # no clear joint route from the last hub to this orientation: dropped
            path = cartesian_line(kin, kin.fk(qb), standoff, config, qb, rate, tip)
            if np.any(path < lower + margin) or np.any(path > upper - margin):
                continue        # not reachable without leaving a joint's range: dropped
        # the way back to the face's hub, which the program takes before a touch elsewhere and at
        # the end (a wound-up wrist can leave its range on it: the PUMA 560's joint 6 did)
        back = cartesian_line(kin, kin.fk(path[-1]), pose_t6(fixture.faces[t.face].hub, t.rotation, tip),
                              config, path[-1], rate, tip)
        if np.any(back < lower + margin) or np.any(back > upper - margin):
            continue
        t = Touch(t.face, t.point, t.rotation, t.config, via_hub=not straight)
        out.append(t)
        q = path[-1]
        prev = t
    return out
