"""The URDF check: a robot's URDF must exist, parse, and agree with its data file on joints,
limits, link frames and inertials (the URDF is what Pinocchio and the viewers read)."""
from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from .exceptions import ModelError
from .robot import RobotModel

_LIMIT_TOL = 1e-6      # URDF vs data file: rad or m (URDFs are written with >= 7 digits)
_INERTIAL_TOL = 1e-9   # URDF vs data file: kg, m, kg*m^2


def _floats(text: str | None, n: int, path: Path, field: str) -> np.ndarray:
    try:
        xs = [float(t) for t in (text or "").split()]
    except ValueError:
        raise ModelError(path, field, f"not numbers: {text!r}") from None
    if len(xs) != n:
        raise ModelError(path, field, f"expected {n} numbers, got {text!r}")
    return np.array(xs)


def check_urdf(model: RobotModel) -> None:
    """The URDF must exist, parse, and agree with the data file on joints, limits, inertials."""
    path = model.urdf_path
    if not path.is_file():
        raise ModelError(model.path, "robot.urdf", f"URDF {path} does not exist")
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise ModelError(path, "<file>", f"not valid XML: {exc}") from None
    if root.tag != "robot":
        raise ModelError(path, "<file>", f"root element is <{root.tag}>, expected <robot>")
    joints = {j.get("name"): j for j in root.findall("joint")}
    links = {lk.get("name"): lk for lk in root.findall("link")}
    if "base_link" not in links:
        raise ModelError(path, "link base_link", "missing (DH frame 0)")
    movable = [n for n, j in joints.items() if j.get("type") not in ("fixed",)]
    if len(movable) != model.n_joints:
        raise ModelError(path, "joints", f"{len(movable)} movable joints, data file has {model.n_joints}")
    for j in model.joints:
        el = joints.get(j.name)
        if el is None:
            raise ModelError(path, f"joint {j.name}", "missing")
        if el.get("type") != j.kind:
            raise ModelError(path, f"joint {j.name}", f"type {el.get('type')!r}, data file says {j.kind!r}")
        lim = el.find("limit")
        if lim is None:
            raise ModelError(path, f"joint {j.name}.limit", "missing")
        for attr, want, src in (("lower", j.lower, f"joints.{j.index}.lower"),
                                ("upper", j.upper, f"joints.{j.index}.upper"),
                                ("velocity", j.max_velocity, f"joints.{j.index}.max_velocity")):
            got = _floats(lim.get(attr), 1, path, f"joint {j.name}.limit.{attr}")[0]
            if abs(got - want) > _LIMIT_TOL:
                raise ModelError(path, f"joint {j.name}.limit.{attr}",
                                 f"{got!r} disagrees with the data file {model.path.name} {src} = {want!r} (SI)")
    _check_urdf_frames(model, root)
    for li in model.links:
        lname = f"link{li.index}"
        el = links.get(lname)
        if el is None:
            raise ModelError(path, f"link {lname}", "missing (DH frame)")
        inertial = el.find("inertial")
        if inertial is None:
            raise ModelError(path, f"link {lname}.inertial", "missing")
        mass_el, inertia_el, origin = inertial.find("mass"), inertial.find("inertia"), inertial.find("origin")
        if mass_el is None or inertia_el is None:
            raise ModelError(path, f"link {lname}.inertial", "needs <mass> and <inertia>")
        mass = _floats(mass_el.get("value"), 1, path, f"link {lname}.inertial.mass")[0]
        xyz = _floats(origin.get("xyz", "0 0 0") if origin is not None else "0 0 0", 3, path,
                      f"link {lname}.inertial.origin")
        rpy = _floats(origin.get("rpy", "0 0 0") if origin is not None else "0 0 0", 3, path,
                      f"link {lname}.inertial.origin")
        if np.any(rpy != 0):
            raise ModelError(path, f"link {lname}.inertial.origin", "rpy must be 0 (inertia given in DH-frame axes)")
        names = ("ixx", "iyy", "izz", "ixy", "ixz", "iyz")
        vals = [_floats(inertia_el.get(k), 1, path, f"link {lname}.inertial.inertia.{k}")[0] for k in names]
        want = li.inertia
        want_vals = [want[0, 0], want[1, 1], want[2, 2], want[0, 1], want[0, 2], want[1, 2]]
        if abs(mass - li.mass) > _INERTIAL_TOL:
            raise ModelError(path, f"link {lname}.inertial.mass", f"{mass!r} disagrees with links.{li.index}.mass = {li.mass!r}")
        if np.max(np.abs(xyz - li.com)) > _INERTIAL_TOL:
            raise ModelError(path, f"link {lname}.inertial.origin", f"{xyz} disagrees with links.{li.index}.com = {li.com}")
        if max(abs(a - b) for a, b in zip(vals, want_vals)) > _INERTIAL_TOL:
            raise ModelError(path, f"link {lname}.inertial.inertia", f"{vals} disagrees with links.{li.index}.inertia")


def _rpy_matrix(rpy: np.ndarray) -> np.ndarray:
    """URDF fixed-axis roll-pitch-yaw: R = Rz(yaw) Ry(pitch) Rx(roll)."""
    (cr, cp, cy), (sr, sp, sy) = np.cos(rpy), np.sin(rpy)
    return np.array([
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ])


def _joint_motion(kind: str, axis: np.ndarray, q: float) -> np.ndarray:
    """The (4, 4) motion of a URDF joint at value q (rotation about / slide along axis)."""
    motion = np.eye(4)
    if kind == "prismatic":
        motion[:3, 3] = axis * q
    elif kind in ("revolute", "continuous"):
        k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
        motion[:3, :3] = np.eye(3) + math.sin(q) * k + (1.0 - math.cos(q)) * (k @ k)
    return motion


def _check_urdf_frames(model: RobotModel, root: ET.Element) -> None:
    """URDF links link1..linkN must be the DH frames 1..N of the data file (a few q)."""
    path = model.urdf_path
    by_child: dict[str, ET.Element] = {}
    for el in root.findall("joint"):
        child = el.find("child")
        if child is None or el.find("parent") is None:
            raise ModelError(path, f"joint {el.get('name')}", "needs <parent> and <child>")
        by_child[child.get("link", "")] = el
    index = {j.name: i for i, j in enumerate(model.joints)}
    span = model.upper - model.lower
    for q in (np.zeros(model.n_joints), model.lower + 0.31 * span, model.lower + 0.77 * span):
        dh = model.base_to_link(q)
        for k in range(model.n_joints):
            link, base_to_link, seen = f"link{k + 1}", np.eye(4), 0
            while link != "base_link":
                el = by_child.get(link)
                seen += 1
                if el is None or seen > 4 * model.n_joints + 4:
                    raise ModelError(path, f"link link{k + 1}", "not connected to base_link")
                origin = el.find("origin")
                step = np.eye(4)
                if origin is not None:
                    step[:3, :3] = _rpy_matrix(_floats(origin.get("rpy", "0 0 0"), 3, path, f"joint {el.get('name')}.origin.rpy"))
                    step[:3, 3] = _floats(origin.get("xyz", "0 0 0"), 3, path, f"joint {el.get('name')}.origin.xyz")
                axis_el = el.find("axis")
                axis = _floats(axis_el.get("xyz") if axis_el is not None else "1 0 0", 3, path, f"joint {el.get('name')}.axis")
                if not np.linalg.norm(axis) > 0:
                    raise ModelError(path, f"joint {el.get('name')}.axis", "zero axis")
                qi = float(q[index[el.get("name")]]) if el.get("name") in index else 0.0
                base_to_link = step @ _joint_motion(el.get("type", ""), axis / np.linalg.norm(axis), qi) @ base_to_link
                link = el.find("parent").get("link", "")
            diff = float(np.max(np.abs(base_to_link - dh[k])))
            if diff > 1e-9:
                raise ModelError(path, f"link link{k + 1}",
                                 f"frame differs from DH frame {k + 1} of {model.path.name} by {diff:.3g} "
                                 f"at q = {np.round(q, 4).tolist()} (URDF origins/axes disagree with the DH table)")
