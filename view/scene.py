"""The 3D view of an arm in a web browser (viser): the arm from its URDF, the environment, paths and a target frame.

``ArmView("puma260")`` serves a three.js scene over a websocket (``view.url``, e.g.
``http://127.0.0.1:8080``; viser, ``pip install 'rcci[view]'``) and draws:

* the arm from ``models/urdf/<robot>.urdf``: each link's visual geometry (boxes,
  cylinders, spheres; meshes through trimesh), or, for a link the URDF gives no visual,
  a rod from its origin to each child joint; coloured by place in the chain (grey base,
  orange arm, grey wrist) so that every link stands out against the grid;
* a ground grid at the foot of the arm, and a camera that looks at the arm;
* the environment surfaces simula knows (``--env plane:z=...``, ``box:...``, the words of
  ``rci.simula.environment.parse_environment``) as translucent blocks, clipped to the
  arm's reach where a side is unbounded;
* named paths (polylines, each a colour) and a target frame (axes), set by whoever feeds
  the view: ``rci.view_link`` (simula, a program), ``rcci.view.replay`` (replay of a log).

``set_q`` moves the arm (the angles of the URDF's actuated joints, rad or m, in the
order of the robot's joints, the same q as everywhere in the project). The view does no
waiting and keeps no clock: whoever calls it chooses the rate (30 Hz is plenty).

This module never runs inside a real-time loop: ``rci.view_link`` serves it from a
separate process, so that viser's server thread never competes with a control loop
for the interpreter lock.
"""
from __future__ import annotations

import contextlib
import io
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from rcci.models import load_robot

# the view's palette (RGB 0-255): the base dark, the arm orange, the wrist grey
BASE_COLOR = (120, 128, 142)
ARM_COLOR = (232, 116, 30)
WRIST_COLOR = (150, 154, 160)
SURFACE_COLOR = (70, 130, 200)
SURFACE_OPACITY = 0.35
COLLISION_COLOR = (60, 200, 90)      # the collision shapes (rccl.collision), drawn on request
COLLISION_OPACITY = 0.3
GRID_COLOR = (200, 200, 200)
SECTION_COLOR = (150, 150, 150)
ROD_RADIUS = 0.02          # m, the rod drawn for a link without visual geometry
REACH_MARGIN = 0.25        # m, how far past the arm's reach an unbounded surface is drawn
TARGET_AXES = 0.08         # m, length of the target frame's axes
CAMERA_DIRECTION = np.array([0.75, -1.4, 0.75])  # from what it looks at: from -y and +x, above
CAMERA_DISTANCE = 1.2      # times the size (diagonal) of what it frames
CAMERA_FOV_DEG = 45.0
WRIST_JOINTS = 3           # the last three joints are the wrist (both arms of the project)
INSTALL_HINT = "the 3D view needs viser and yourdfpy: pip install 'rcci[view]'"


def require_viser():
    """The viser module, or ImportError saying how to install the view's extra."""
    try:
        import viser
        import yourdfpy  # noqa: F401 - the URDF reader the view uses
    except ImportError as exc:
        raise ImportError(f"{INSTALL_HINT} ({exc})") from None
    return viser


# --------------------------------------------------------------------------------------------
# the URDF as a kinematic tree with visuals (no viser needed)
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Visual:
    """One piece of a link's geometry in the link's frame: ``kind`` box | cylinder | sphere | mesh | rod."""

    kind: str
    origin: np.ndarray            # (4, 4) link frame -> geometry frame
    size: tuple[float, ...]       # box (x, y, z); cylinder/rod (radius, length); sphere (radius,); mesh scale
    mesh: str | None = None       # mesh file (resolved path)


@dataclass(frozen=True)
class TreeJoint:
    name: str
    kind: str                     # revolute | continuous | prismatic | fixed
    parent: str
    child: str
    origin: np.ndarray            # (4, 4) parent link -> joint frame at q = 0
    axis: np.ndarray              # (3,) unit, in the joint frame
    index: int | None             # position in q (actuated joints), None for fixed


def _rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    x, y, z = axis
    c, s = math.cos(angle), math.sin(angle)
    v = 1.0 - c
    return np.array([[c + x * x * v, x * y * v - z * s, x * z * v + y * s],
                     [y * x * v + z * s, c + y * y * v, y * z * v - x * s],
                     [z * x * v - y * s, z * y * v + x * s, c + z * z * v]])


class ArmTree:
    """A URDF's links, joints (in an order where parents come first) and visuals; ``link_poses(q)``."""

    def __init__(self, urdf_path: str | Path, joint_names: Sequence[str] | None = None) -> None:
        import yourdfpy

        path = Path(urdf_path)
        robot = yourdfpy.URDF.load(str(path), build_scene_graph=False, load_meshes=False,
                                   build_collision_scene_graph=False, load_collision_meshes=False).robot
        self.name = robot.name
        actuated = [j.name for j in robot.joints if j.type != "fixed" and j.mimic is None]
        order = list(joint_names) if joint_names is not None else actuated
        missing = sorted(set(order) - set(actuated))
        if missing:
            raise ValueError(f"{path}: no movable joints named {missing}")
        children = {j.child for j in robot.joints}
        roots = [lk.name for lk in robot.links if lk.name not in children]
        if len(roots) != 1:
            raise ValueError(f"{path}: expected one root link, found {roots}")
        self.root = roots[0]
        by_parent: dict[str, list] = {}
        for j in robot.joints:
            by_parent.setdefault(j.parent, []).append(j)
        self.joints: list[TreeJoint] = []
        stack = [self.root]
        while stack:                      # parents before children
            link = stack.pop()
            for j in by_parent.get(link, []):
                axis = np.asarray(j.axis if j.axis is not None else (1.0, 0.0, 0.0), float)
                origin = np.asarray(j.origin if j.origin is not None else np.eye(4), float)
                self.joints.append(TreeJoint(j.name, j.type, j.parent, j.child, origin,
                                             axis / np.linalg.norm(axis),
                                             order.index(j.name) if j.name in order else None))
                stack.append(j.child)
        self.n = len(order)
        self.links = [self.root] + [j.child for j in self.joints]
        self.depth = {self.root: 0}
        for j in self.joints:
            self.depth[j.child] = self.depth[j.parent] + (0 if j.kind == "fixed" else 1)
        self.visuals: dict[str, list[Visual]] = {}
        for lk in robot.links:
            self.visuals[lk.name] = [v for v in (self._visual(vis, path.parent) for vis in lk.visuals) if v]
        for link in self.links:           # no geometry at all: a rod to each child joint
            if not self.visuals.get(link):
                self.visuals[link] = [_rod(j.origin[:3, 3]) for j in self.joints
                                      if j.parent == link and np.linalg.norm(j.origin[:3, 3]) > 1e-6]

    @staticmethod
    def _visual(vis, folder: Path) -> Visual | None:
        origin = np.asarray(vis.origin if vis.origin is not None else np.eye(4), float)
        g = vis.geometry
        if g.box is not None:
            return Visual("box", origin, tuple(float(x) for x in g.box.size))
        if g.cylinder is not None:
            return Visual("cylinder", origin, (float(g.cylinder.radius), float(g.cylinder.length)))
        if g.sphere is not None:
            return Visual("sphere", origin, (float(g.sphere.radius),))
        if g.mesh is not None:
            name = g.mesh.filename
            for prefix in ("package://", "file://"):
                if name.startswith(prefix):
                    name = name[len(prefix):]
            f = Path(name) if Path(name).is_absolute() else folder / name
            if not f.is_file():   # package://pkg/meshes/x.stl: try below the URDF's folder without the package
                f = folder / Path(*Path(name).parts[1:]) if len(Path(name).parts) > 1 else f
            scale = tuple(float(x) for x in np.broadcast_to(g.mesh.scale if g.mesh.scale is not None else 1.0, 3))
            return Visual("mesh", origin, scale, str(f))
        return None

    def link_poses(self, q: Sequence[float]) -> dict[str, np.ndarray]:
        """Base -> link (4, 4) for every link at joint values ``q`` (rad or m)."""
        q = np.asarray(q, float)
        if q.shape != (self.n,):
            raise ValueError(f"{self.name}: q has shape {q.shape}, expected ({self.n},)")
        poses = {self.root: np.eye(4)}
        for j in self.joints:
            m = poses[j.parent] @ j.origin
            if j.index is not None:
                motion = np.eye(4)
                if j.kind == "prismatic":
                    motion[:3, 3] = j.axis * q[j.index]
                else:
                    motion[:3, :3] = _rotation(j.axis, q[j.index])
                m = m @ motion
            poses[j.child] = m
        return poses

    def color(self, link: str) -> tuple[int, int, int]:
        """The palette colour of a link: base, arm or wrist by its place in the chain."""
        d = self.depth[link]
        if d == 0:
            return BASE_COLOR
        return WRIST_COLOR if d > self.n - WRIST_JOINTS else ARM_COLOR


def _rod(to: np.ndarray) -> Visual:
    """A cylinder from a link's origin to the point ``to`` (link frame)."""
    length = float(np.linalg.norm(to))
    z = to / length
    x = np.cross([0.0, 0.0, 1.0], z)
    if np.linalg.norm(x) < 1e-9:
        x = np.array([1.0, 0.0, 0.0])
    x = x / np.linalg.norm(x)
    origin = np.eye(4)
    origin[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    origin[:3, 3] = to / 2.0
    return Visual("rod", origin, (ROD_RADIUS, length))


def _box_extent(v: Visual) -> np.ndarray:
    """Corner points of a visual's bounding box in the link frame (for the camera and the floor)."""
    if v.kind == "box":
        h = np.array(v.size) / 2
    elif v.kind in ("cylinder", "rod"):
        h = np.array([v.size[0], v.size[0], v.size[1] / 2])
    elif v.kind == "sphere":
        h = np.full(3, v.size[0])
    else:
        h = np.full(3, 0.05)
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * h
    return corners @ v.origin[:3, :3].T + v.origin[:3, 3]


def surface_blocks(specs: Sequence[str], reach: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """(lo, hi) of each block of an environment (``--env`` words), unbounded sides clipped at ``reach`` m."""
    from rci.simula.environment import parse_environment

    env = parse_environment(list(specs))
    out = []
    for b in env.boxes:
        lo = np.where(np.isfinite(b.lo), b.lo, -reach)
        hi = np.where(np.isfinite(b.hi), b.hi, reach)
        # a floor unbounded below is drawn as a slab 2 cm thick under its surface
        lo = np.where(~np.isfinite(b.lo) & np.isfinite(b.hi), b.hi - 0.02, lo)
        hi = np.where(~np.isfinite(b.hi) & np.isfinite(b.lo), b.lo + 0.02, hi)
        if np.all(hi > lo):
            out.append((lo, hi))
    return out


# --------------------------------------------------------------------------------------------
# the view
# --------------------------------------------------------------------------------------------
class ArmView:
    """A viser server showing one arm; ``set_q``, ``set_path``, ``set_target``, ``set_status``; ``close``."""

    def __init__(self, robot: str = "puma260", *, env: Sequence[str] = (), host: str = "127.0.0.1",
                 port: int = 8080, title: str = "", q: Sequence[float] | None = None, collision: bool = False) -> None:
        """``collision``: also draw the arm's collision shapes (models/collision/<robot>.toml, what
        ``rccl.collision`` checks paths against), translucent green, riding on their links."""
        viser = require_viser()
        self._tf = viser.transforms
        model = load_robot(robot)
        self.robot = model.name
        self.tree = ArmTree(model.urdf_path, [j.name for j in model.joints])
        q0 = np.asarray(q if q is not None else model.poses.get("ready", np.zeros(model.n_joints)), float)
        with contextlib.redirect_stdout(io.StringIO()):    # viser's banner: the caller prints the address
            self.server = viser.ViserServer(host=host, port=port, label=title or f"{self.robot} view", verbose=False)
        self.server.gui.configure_theme(show_logo=False, show_share_button=False, brand_color=ARM_COLOR)
        self.server.scene.set_up_direction("+z")
        # plain lights instead of viser's image-based environment: about half the drawing work, which
        # matters in a browser without a GPU (software WebGL: the tests, CI, the docs picture)
        self.server.scene.configure_environment_map(None)
        self.server.scene.add_light_hemisphere("/lights/sky", sky_color=(255, 255, 255),
                                               ground_color=(110, 105, 100), intensity=2.0)
        self._q: np.ndarray | None = None
        self._links: dict = {}
        self._paths: dict = {}
        self._target = None
        poses = self.tree.link_poses(q0)
        arm_pts = self._arm_points(poses)
        self._floor = float(arm_pts[:, 2].min())
        self.reach = (float(np.max(np.linalg.norm(arm_pts[:, :2], axis=1))) + float(np.max(np.abs(arm_pts[:, 2])))
                      + REACH_MARGIN)
        self._draw_ground()
        self._draw_arm()
        self.collision_shapes = self._draw_collision(q0, poses) if collision else 0
        blocks = surface_blocks(env, self.reach)
        for i, (lo, hi) in enumerate(blocks):
            self.server.scene.add_box(f"/env/block{i}", color=SURFACE_COLOR, dimensions=tuple(hi - lo),
                                      position=tuple((hi + lo) / 2), opacity=SURFACE_OPACITY,
                                      cast_shadow=False, receive_shadow=False)
        self._status = self.server.gui.add_markdown(f"**{self.robot}**")
        # the camera frames the arm and the blocks of finite size (a floor plane would only push it away)
        pts = [arm_pts] + [np.array([lo, hi]) for lo, hi in blocks if np.all(hi - lo < self.reach)]
        pts = np.vstack(pts)
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        center = (lo + hi) / 2
        size = float(np.linalg.norm(hi - lo))
        cam = self.server.initial_camera
        cam.look_at = tuple(center)
        cam.position = tuple(center + CAMERA_DISTANCE * size * CAMERA_DIRECTION / np.linalg.norm(CAMERA_DIRECTION))
        cam.fov = math.radians(CAMERA_FOV_DEG)
        self.set_q(q0)

    # -- set-up ----------------------------------------------------------------------------
    def _arm_points(self, poses: dict) -> np.ndarray:
        """Corners of every visual's bounding box (base frame, m) at the link poses ``poses``."""
        return np.vstack([_box_extent(v) @ poses[link][:3, :3].T + poses[link][:3, 3]
                          for link, vs in self.tree.visuals.items() if link in poses for v in vs])

    def _draw_ground(self) -> None:
        self.server.scene.add_grid("/ground", width=2.0, height=2.0, plane="xy", cell_size=0.1, section_size=0.5,
                                   cell_color=GRID_COLOR, section_color=SECTION_COLOR,
                                   position=(0.0, 0.0, self._floor - 1e-3), shadow_opacity=0.2)

    def _draw_arm(self) -> None:
        scene = self.server.scene
        for link in self.tree.links:
            node = f"/arm/{link}"
            self._links[link] = scene.add_frame(node, show_axes=False)
            color = self.tree.color(link)
            for i, v in enumerate(self.tree.visuals.get(link, [])):
                name = f"{node}/v{i}"
                wxyz = self._tf.SO3.from_matrix(v.origin[:3, :3]).wxyz
                pos = tuple(v.origin[:3, 3])
                if v.kind == "box":
                    scene.add_box(name, color=color, dimensions=v.size, wxyz=wxyz, position=pos)
                elif v.kind in ("cylinder", "rod"):
                    scene.add_cylinder(name, radius=v.size[0], height=v.size[1], color=color, wxyz=wxyz,
                                       position=pos, radial_segments=32)
                elif v.kind == "sphere":
                    scene.add_icosphere(name, radius=v.size[0], color=color, wxyz=wxyz, position=pos)
                elif v.kind == "mesh" and v.mesh:
                    import trimesh

                    mesh = trimesh.load(v.mesh, force="mesh")
                    mesh.apply_scale(v.size)
                    scene.add_mesh_simple(name, mesh.vertices, mesh.faces, color=color, wxyz=wxyz, position=pos)

    def _draw_collision(self, q0: np.ndarray, poses: dict) -> int:
        """The collision shapes under their links' nodes (so ``set_q`` moves them); how many were drawn."""
        import trimesh

        from rccl.collision import shape_poses

        scene = self.server.scene
        shapes = shape_poses(self.robot, q0)
        self.collision_placements: list[tuple[str, np.ndarray]] = []    # (link, the shape in the link's frame)
        for i, s in enumerate(shapes):
            local = np.linalg.inv(poses[s.frame]) @ s.pose         # the shape in its link's frame
            self.collision_placements.append((s.frame, local))
            name, wxyz, pos = f"/arm/{s.frame}/collision{i}", self._tf.SO3.from_matrix(local[:3, :3]).wxyz, \
                tuple(local[:3, 3])
            if s.kind == "capsule":
                mesh = trimesh.creation.capsule(height=s.size[0], radius=s.size[1], count=[16, 16])
                scene.add_mesh_simple(name, mesh.vertices, mesh.faces, color=COLLISION_COLOR,
                                      opacity=COLLISION_OPACITY, wxyz=wxyz, position=pos)
            else:
                scene.add_box(name, color=COLLISION_COLOR, dimensions=tuple(s.size), opacity=COLLISION_OPACITY,
                              wxyz=wxyz, position=pos)
        return len(shapes)

    # -- what callers change -------------------------------------------------------------------
    @property
    def url(self) -> str:
        host = self.server.get_host()
        return f"http://{'127.0.0.1' if host in ('0.0.0.0', '') else host}:{self.server.get_port()}"

    def set_q(self, q: Sequence[float]) -> None:
        """Move the arm to joint values ``q`` (rad or m); nothing is sent when they did not change."""
        q = np.asarray(q, float)
        if self._q is not None and np.array_equal(q, self._q):
            return
        poses = self.tree.link_poses(q)
        with self.server.atomic():
            for link, handle in self._links.items():
                m = poses[link]
                handle.wxyz = self._tf.SO3.from_matrix(m[:3, :3]).wxyz
                handle.position = m[:3, 3]
        self._q = q.copy()

    def set_path(self, name: str, polylines: Sequence[tuple[Sequence, Sequence[int]]], width: float = 5.0) -> None:
        """Draw polylines ``[(points (N, 3) m, (r, g, b)), ...]`` as one named path (replacing it); [] removes it."""
        segs, cols = [], []
        for points, color in polylines:
            p = np.asarray(points, float).reshape(-1, 3)
            if len(p) < 2:
                continue
            segs.append(np.stack([p[:-1], p[1:]], axis=1))
            cols.append(np.broadcast_to(np.asarray(color, np.uint8), (len(p) - 1, 2, 3)))
        old = self._paths.pop(name, None)
        if old is not None:
            old.remove()
        if segs:
            self._paths[name] = self.server.scene.add_line_segments(
                f"/path/{name}", np.concatenate(segs), np.concatenate(cols), thickness=width,
                thickness_units="screen")

    def set_target(self, base_to_target: np.ndarray | None) -> None:
        """Show the target frame (4x4, base frame, m) as axes; None hides it."""
        if base_to_target is None:
            if self._target is not None:
                self._target.visible = False
            return
        m = np.asarray(base_to_target, float)
        if self._target is None:
            self._target = self.server.scene.add_frame("/target", axes_length=TARGET_AXES,
                                                       axes_radius=TARGET_AXES / 15)
        self._target.wxyz = self._tf.SO3.from_matrix(m[:3, :3]).wxyz
        self._target.position = m[:3, 3]
        self._target.visible = True

    def set_status(self, text: str) -> None:
        """The line of text in the view's panel (Markdown)."""
        self._status.content = text

    def clients(self) -> int:
        """How many browsers are connected."""
        return len(self.server.get_clients())

    def close(self) -> None:
        with contextlib.redirect_stdout(io.StringIO()):    # "(viser) Server stopped"
            self.server.stop()
