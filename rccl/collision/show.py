"""Print an arm's collision shapes for one pose beside its URDF visuals and DH frames, and check they enclose them.

    python -m rccl.collision.show puma260            # the ready pose
    python -m rccl.collision.show stanford --pose nest

For the pose it prints every link frame's origin (base frame, m), every shape (capsule end
points and radius, or box centre and size, base frame) and the nearest checked pairs; then,
for every URDF visual, how far its farthest sample point (cylinder rims, box corners, sphere
poles) lies outside every collision shape (0 = enclosed), and the same for the kinematic
skeleton (the DH offsets from joint to joint) and the links' centres of mass.
``enclosure_gaps`` and ``skeleton_gaps`` are those checks as functions (tests/test_collision.py
uses them).
"""
from __future__ import annotations

import argparse
import math
import xml.etree.ElementTree as ET

import numpy as np
import pinocchio as pin

from .geometry import Capsule
from .world import CollisionWorld


def _rpy(r: float, p: float, y: float) -> np.ndarray:
    return pin.rpy.rpyToMatrix(r, p, y)


def visual_points(urdf_path: str) -> list[tuple[str, int, str, np.ndarray]]:
    """(link, visual index, description, sample points (k, 3) in the link's frame) of every URDF visual."""
    out = []
    for link in ET.parse(urdf_path).getroot().findall("link"):
        for n, vis in enumerate(link.findall("visual")):
            origin = vis.find("origin")
            xyz = np.array([float(v) for v in (origin.get("xyz", "0 0 0") if origin is not None else "0 0 0").split()])
            rot = _rpy(*[float(v) for v in (origin.get("rpy", "0 0 0") if origin is not None else "0 0 0").split()])
            geo = vis.find("geometry")[0]
            if geo.tag == "cylinder":
                r, h = float(geo.get("radius")), float(geo.get("length"))
                ang = np.linspace(0, 2 * math.pi, 16, endpoint=False)
                ring = np.column_stack([r * np.cos(ang), r * np.sin(ang), np.zeros(16)])
                local = np.vstack([ring + [0, 0, -h / 2], ring + [0, 0, h / 2]])
                what = f"cylinder r {r} m, length {h} m"
            elif geo.tag == "box":
                s = np.array([float(v) for v in geo.get("size").split()])
                local = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)]) * s / 2
                what = f"box {s.tolist()} m"
            elif geo.tag == "sphere":
                r = float(geo.get("radius"))
                local = np.vstack([np.eye(3), -np.eye(3)]) * r
                what = f"sphere r {r} m"
            else:
                continue
            out.append((link.get("name"), n, what, local @ rot.T + xyz))
    return out


def _outside(point: np.ndarray, world: CollisionWorld, poses) -> float:
    """How far (m) ``point`` (base frame) lies outside the nearest collision shape (<= 0: inside one)."""
    best = math.inf
    for c, sp in zip(world.shapes, poses):
        local = sp.pose[:3, :3].T @ (point - sp.pose[:3, 3])
        if isinstance(c, Capsule):
            half = sp.size[0] / 2
            z = min(max(local[2], -half), half)
            best = min(best, float(np.linalg.norm(local - [0.0, 0.0, z])) - c.radius)
        else:
            excess = np.abs(local) - np.asarray(sp.size) / 2
            best = min(best, float(np.linalg.norm(np.maximum(excess, 0.0))) + min(float(excess.max()), 0.0))
    return best


def enclosure_gaps(world: CollisionWorld, q: np.ndarray) -> list[tuple[str, int, str, float]]:
    """(link, visual index, description, worst outside distance m) for every URDF visual at joints ``q``."""
    from rcci.models import load_robot

    poses = world.shape_poses(q)
    pin.forwardKinematics(world.model, world.data, np.asarray(q, dtype=float))
    pin.updateFramePlacements(world.model, world.data)
    out = []
    for link, n, what, pts in visual_points(str(load_robot(world.robot).urdf_path)):
        m = world.data.oMf[world.model.getFrameId(link)]
        worst = max(_outside(m.rotation @ p + m.translation, world, poses) for p in pts)
        out.append((link, n, what, worst))
    return out


def skeleton_gaps(world: CollisionWorld, q: np.ndarray, step: float = 0.005) -> list[tuple[str, float]]:
    """(what, worst outside distance m) for the kinematic skeleton at joints ``q``: every moving link's
    line from its joint's origin to the next joint's origin (the DH offsets a_i, d_i, sampled every
    ``step`` m) and every link's centre of mass (the URDF's inertial origins)."""
    m, d = world.model, world.data
    pin.forwardKinematics(m, d, np.asarray(q, dtype=float))
    poses = world.shape_poses(q)
    out = []
    pin.updateFramePlacements(m, d)
    for j in range(2, m.njoints):     # each moving joint's parent joint, the fixed frames between, the joint
        corners = [d.oMi[m.parents[j]].translation]
        corners += [d.oMf[i].translation for i, f in enumerate(m.frames)
                    if f.type == pin.FrameType.FIXED_JOINT and f.parentJoint == m.parents[j]]
        corners.append(d.oMi[j].translation)
        worst = -math.inf
        for a, b in zip(corners[:-1], corners[1:]):
            n = max(1, int(np.ceil(np.linalg.norm(b - a) / step)))
            worst = max(worst, *(_outside(a + (b - a) * k / n, world, poses) for k in range(n + 1)))
        out.append((f"{m.names[m.parents[j]]} -> {m.names[j]}", worst))
    for j in range(1, m.njoints):
        if m.inertias[j].mass > 0:
            out.append((f"centre of mass on {m.names[j]}",
                        _outside(d.oMi[j].act(m.inertias[j].lever), world, poses)))
    return out


def main(argv: list[str] | None = None) -> int:
    from rcci.models import load_robot

    ap = argparse.ArgumentParser(prog="python -m rccl.collision.show", description=__doc__.splitlines()[0])
    ap.add_argument("robot")
    ap.add_argument("--pose", default="ready", help="a named pose of the robot's data file (default ready)")
    a = ap.parse_args(argv)
    world = CollisionWorld(a.robot)
    q = load_robot(a.robot).poses[a.pose]
    pin.forwardKinematics(world.model, world.data, q)
    pin.updateFramePlacements(world.model, world.data)
    print(f"{a.robot} at {a.pose} (q = {np.array2string(q, precision=4)}), base frame, m")
    print("link frame origins:")
    for f in world.model.frames:
        if f.type == pin.FrameType.BODY:
            print(f"  {f.name:14s} {np.array2string(world.data.oMf[world.model.getFrameId(f.name)].translation, precision=4)}")
    print("shapes:")
    for c, sp in zip(world.shapes, world.shape_poses(q)):
        if sp.kind == "capsule":
            half = sp.pose[:3, 2] * sp.size[0] / 2
            ends = f"{np.array2string(sp.pose[:3, 3] - half, precision=4)} - {np.array2string(sp.pose[:3, 3] + half, precision=4)}"
            print(f"  {c.name:14s} on {c.frame:10s} capsule {ends} r {sp.size[1]:.4f}")
        else:
            print(f"  {c.name:14s} on {c.frame:10s} box centre {np.array2string(sp.pose[:3, 3], precision=4)} "
                  f"size {np.array2string(np.asarray(sp.size), precision=4)}")
    d = world.distances(q)
    print("nearest checked pairs:")
    for k in np.argsort(d)[:5]:
        print(f"  {world.pairs[k][0]} - {world.pairs[k][1]}: {d[k] * 1e3:.1f} mm")
    print("URDF visuals, farthest sample point outside every shape (mm; <= 0 enclosed):")
    for link, n, what, gap in enclosure_gaps(world, q):
        print(f"  {link:10s} visual {n} ({what}): {gap * 1e3:+.1f}")
    print("DH skeleton (joint to joint) and centres of mass, farthest point outside every shape (mm):")
    for what, gap in skeleton_gaps(world, q):
        print(f"  {what}: {gap * 1e3:+.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
