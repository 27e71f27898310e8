"""The collision world of one arm: its link shapes and the environment's surfaces as a Pinocchio GeometryModel (coal).

``CollisionWorld(robot, env=["plane:z=-0.3", ...])`` builds the Pinocchio model from the
robot's shipped URDF (as simula does), puts each capsule of models/collision/<robot>.toml
on the joint that carries its link frame, and turns simula's ``--env`` words
(``rci.simula.environment.parse_environment``) into obstacles fixed in the base frame: a
plane (solid below z) is a coal Halfspace, a box bounded on one side only is the halfspace
beyond that face, any other box a coal Box (unbounded sides cut at ``FAR`` m). ``tool:``
and ``conveyor:`` words carry no obstacle.

Checked pairs: every two link shapes on different bodies, except the file's allowed pairs;
every capsule on a moving body against every obstacle (bodies fixed to the base, such as
the pedestal standing on the table, are the set-up, not something a motion changes).

Units: m, rad (m for a prismatic joint); poses 4x4 in the robot's base frame (DH frame 0).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import coal
import numpy as np
import pinocchio as pin

from ..exceptions import CollisionFileError
from .geometry import Capsule, LinkBox, CollisionGeometry, geometry_path, load_geometry, segment_length

#: m: how far an unbounded side of a box is cut (beyond any arm's reach; coal's Box is finite)
FAR = 10.0


@dataclass(frozen=True)
class ShapePose:
    """A link's collision shape in the base frame (for a viewer). ``kind`` "capsule": ``pose``
    4x4 (m) has its z axis along the segment and its origin at the segment's middle, ``size``
    is (segment length, radius) in m; ``kind`` "box": ``pose`` is the box's centre and axes,
    ``size`` its full edge lengths (m)."""

    name: str
    frame: str
    kind: str
    pose: np.ndarray
    size: tuple[float, ...]


def _segment_placement(a: np.ndarray, b: np.ndarray) -> pin.SE3:
    """The placement (in the capsule's frame) of a z-aligned capsule centred between a and b."""
    axis = b - a
    n = float(np.linalg.norm(axis))
    z = axis / n if n > 1e-12 else np.array([0.0, 0.0, 1.0])
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    return pin.SE3(np.column_stack([x, np.cross(z, x), z]), 0.5 * (a + b))


def obstacles(words: list[str] | tuple[str, ...]) -> list[tuple[str, coal.CollisionGeometry, pin.SE3]]:
    """(name, coal shape, base-frame placement) of each obstacle among simula's environment words."""
    from rci.simula.environment import parse_environment

    out = []
    for word in words:
        env = parse_environment([word])          # ValueError names a bad word
        for k, box in enumerate(env.boxes):
            name = f"env:{word}" if len(env.boxes) == 1 else f"env:{word}#{k}"
            out.append((name, *_box_shape(box.lo, box.hi)))
    return out


def _box_shape(lo: np.ndarray, hi: np.ndarray) -> tuple[coal.CollisionGeometry, pin.SE3]:
    """A coal shape for the solid block [lo, hi] (m, base frame; +-inf for an open side)."""
    finite = [(axis, side) for axis in range(3) for side, v in ((0, lo[axis]), (1, hi[axis])) if math.isfinite(v)]
    if len(finite) == 1:                        # one face: the halfspace n.x <= d behind it
        axis, side = finite[0]
        n = np.zeros(3)
        n[axis] = 1.0 if side == 1 else -1.0
        d = hi[axis] if side == 1 else -lo[axis]
        return coal.Halfspace(n, float(d)), pin.SE3.Identity()
    lo_c, hi_c = np.maximum(lo, -FAR), np.minimum(hi, FAR)
    return coal.Box(*(hi_c - lo_c)), pin.SE3(np.eye(3), 0.5 * (lo_c + hi_c))


class CollisionWorld:
    """One arm's link shapes and its environment's obstacles, with the pairs to check.

    ``distances(q)`` gives every checked pair's distance (m); ``nearest(q)`` the closest pair;
    ``capsule_poses(q)`` where each capsule is (for a viewer); ``lever`` the per-joint bound
    on how far any capsule point moves per unit of that joint (m/rad, 1 for a prismatic joint).
    """

    def __init__(self, robot: str, env: list[str] | tuple[str, ...] = (),
                 geometry: CollisionGeometry | str | None = None) -> None:
        from rcci.models import load_robot

        if geometry is None or isinstance(geometry, str):
            geometry = load_geometry(geometry or geometry_path(robot))
        if geometry.robot != robot:
            raise CollisionFileError(f"{geometry.path}: collision.robot: {geometry.robot!r} is not {robot!r}")
        self.robot = robot
        self.geometry = geometry
        self.env = tuple(env)
        self.model = pin.buildModelFromUrdf(str(load_robot(robot).urdf_path))
        self.data = self.model.createData()
        self.gmodel = pin.GeometryModel()
        self.shapes: list[Capsule | LinkBox] = list(geometry.capsules) + list(geometry.boxes)
        self._joint: list[int] = []
        for c in self.shapes:
            if not self.model.existFrame(c.frame):
                key = f"capsules/boxes {c.name!r} frame"
                raise CollisionFileError(f"{geometry.path}: {key}: {c.frame!r} is not a link of {robot}'s URDF")
            fid = self.model.getFrameId(c.frame)
            frame = self.model.frames[fid]
            if isinstance(c, Capsule):
                placement = frame.placement * _segment_placement(c.a, c.b)
                shape = coal.Capsule(c.radius, segment_length(c))
            else:
                placement = frame.placement * pin.SE3(np.eye(3), c.center)
                shape = coal.Box(*c.size)
            self.gmodel.addGeometryObject(pin.GeometryObject(c.name, frame.parentJoint, fid, placement, shape))
            self._joint.append(frame.parentJoint)
        self.n_shapes = len(self.shapes)
        self.obstacle_names: list[str] = []
        for name, shape, placement in obstacles(self.env):
            self.gmodel.addGeometryObject(pin.GeometryObject(name, 0, 0, placement, shape))
            self.obstacle_names.append(name)
        self.pairs: list[tuple[str, str]] = []
        for i in range(self.n_shapes):
            for j in range(i + 1, self.n_shapes):
                if self._checked(i, j):
                    self._add_pair(i, j)
            if self._joint[i] != 0:
                for k in range(len(self.obstacle_names)):
                    self._add_pair(i, self.n_shapes + k)
        self.gdata = pin.GeometryData(self.gmodel)
        self.lever = self._levers()

    # -- pairs ------------------------------------------------------------------------------
    def _checked(self, i: int, j: int) -> bool:
        ci, cj = self.shapes[i], self.shapes[j]
        if self._joint[i] == self._joint[j]:
            return False                                  # one rigid body
        names_i, names_j = {ci.name, ci.frame}, {cj.name, cj.frame}
        return not any(frozenset((a, b)) in self.geometry.allowed for a in names_i for b in names_j)

    def _add_pair(self, i: int, j: int) -> None:
        self.gmodel.addCollisionPair(pin.CollisionPair(i, j))
        self.pairs.append((self.gmodel.geometryObjects[i].name, self.gmodel.geometryObjects[j].name))

    def describe(self, name: str) -> str:
        """A geometry object's name as a user reads it: a capsule with its link, or the environment word."""
        for c in self.shapes:
            if c.name == name:
                return f"{c.name} (on {c.frame})"
        return name

    # -- distances ----------------------------------------------------------------------------
    def nearest(self, q: np.ndarray) -> tuple[float, int]:
        """(distance m, pair index) of the closest checked pair at joints ``q`` (negative: overlapping)."""
        k = pin.computeDistances(self.model, self.data, self.gmodel, self.gdata, np.asarray(q, dtype=float))
        return float(self.gdata.distanceResults[k].min_distance), int(k)

    def distances(self, q: np.ndarray) -> np.ndarray:
        """Every checked pair's distance (m) at joints ``q``, in the order of ``pairs``."""
        pin.computeDistances(self.model, self.data, self.gmodel, self.gdata, np.asarray(q, dtype=float))
        return np.array([r.min_distance for r in self.gdata.distanceResults])

    def shape_poses(self, q: np.ndarray) -> list[ShapePose]:
        """Each link shape's base-frame pose and size at joints ``q`` (for a viewer to draw)."""
        pin.forwardKinematics(self.model, self.data, np.asarray(q, dtype=float))
        pin.updateGeometryPlacements(self.model, self.data, self.gmodel, self.gdata)
        out = []
        for i, c in enumerate(self.shapes):
            pose = self.gdata.oMg[i].homogeneous.copy()
            if isinstance(c, Capsule):
                out.append(ShapePose(c.name, c.frame, "capsule", pose, (segment_length(c), c.radius)))
            else:
                out.append(ShapePose(c.name, c.frame, "box", pose, tuple(float(x) for x in c.size)))
        return out

    # -- how fast the shapes can move -----------------------------------------------------------
    def _levers(self) -> np.ndarray:
        """Per joint: a bound (m per rad, or 1 for a prismatic joint) on how far any capsule point
        moves per unit of that joint, over every configuration (triangle inequality along the chain:
        the joint offsets out to the capsule, the prismatic strokes between, the capsule's far end)."""
        m = self.model
        lever = np.zeros(m.nq)
        for i, c in enumerate(self.shapes):
            jid = self._joint[i]
            if jid == 0:
                continue
            local = self.gmodel.geometryObjects[i].placement
            if isinstance(c, Capsule):
                extent = 0.5 * segment_length(c) + c.radius
            else:
                extent = 0.5 * float(np.linalg.norm(c.size))
            reach = float(np.linalg.norm(local.translation)) + extent
            k = jid
            while k > 0:                           # from the capsule's body towards the base
                idx = m.joints[k].idx_q
                if m.joints[k].shortname().startswith("JointModelP"):
                    lever[idx] = 1.0
                else:
                    lever[idx] = max(lever[idx], reach)
                stroke = 0.0
                if m.joints[k].shortname().startswith("JointModelP"):
                    stroke = max(abs(m.lowerPositionLimit[idx]), abs(m.upperPositionLimit[idx]))
                reach += float(np.linalg.norm(m.jointPlacements[k].translation)) + stroke
                k = m.parents[k]
        return lever

    def displacement(self, dq: np.ndarray) -> float:
        """A bound (m) on how far any capsule point moves when the joints move by ``dq`` along a line."""
        return float(np.abs(np.asarray(dq, dtype=float)) @ self.lever)


@lru_cache(maxsize=8)
def _world_of(robot: str) -> CollisionWorld:
    return CollisionWorld(robot)


def shape_poses(robot: str, q: np.ndarray) -> list[ShapePose]:
    """Each link shape of ``robot``'s shipped geometry at joints ``q`` (rad, m), base frame: what a viewer draws."""
    return _world_of(robot).shape_poses(q)
