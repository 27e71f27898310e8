"""Foxglove's well-known message schemas (JSON encoding) and the messages of a log in SI units on them.

Foxglove recognises a channel by its schema name (``foxglove.FrameTransform``,
``foxglove.JointStates``, ...) and the JSON field names of its published schemas; a channel
so named is drawn by the 3D panel (frame transforms) and plotted by the plot panel
(``/joints/measured.joints[0].position``) with no configuration. The schemas below are
written from Foxglove's schema reference (field names, types, units: rad, m, N m; times as
``{"sec", "nsec"}``); ``channels(si, stamps)`` yields, per channel, its topic, schema and one
JSON message per record (or None for a record with nothing to say on it).
"""
from __future__ import annotations

from typing import Iterator

import numpy as np

from .log_units import LogSI, quaternion

_NUMBER = {"type": "number"}
TIME = {"type": "object", "title": "time",
        "properties": {"sec": {"type": "integer", "minimum": 0},
                       "nsec": {"type": "integer", "minimum": 0, "maximum": 999_999_999}}}
VECTOR3 = {"type": "object", "title": "foxglove.Vector3",
           "properties": {"x": _NUMBER, "y": _NUMBER, "z": _NUMBER}}
QUATERNION = {"type": "object", "title": "foxglove.Quaternion",
              "properties": {"x": _NUMBER, "y": _NUMBER, "z": _NUMBER, "w": _NUMBER}}
FRAME_TRANSFORM = {
    "type": "object", "title": "foxglove.FrameTransform",
    "description": "A transform between two reference frames in 3D space",
    "properties": {"timestamp": TIME, "parent_frame_id": {"type": "string"}, "child_frame_id": {"type": "string"},
                   "translation": VECTOR3, "rotation": QUATERNION}}
FRAME_TRANSFORMS = {"type": "object", "title": "foxglove.FrameTransforms",
                    "properties": {"transforms": {"type": "array", "items": FRAME_TRANSFORM}}}
JOINT_STATE = {
    "type": "object", "title": "foxglove.JointState",
    "properties": {"name": {"type": "string"},
                   "position": _NUMBER,       # rad (revolute), m (prismatic)
                   "velocity": _NUMBER,       # rad/s, m/s
                   "acceleration": _NUMBER,   # rad/s^2, m/s^2
                   "effort": _NUMBER},        # N m, N
    "required": ["name"]}
JOINT_STATES = {"type": "object", "title": "foxglove.JointStates",
                "properties": {"timestamp": TIME, "joints": {"type": "array", "items": JOINT_STATE}}}
CURRENTS = {"type": "object", "title": "rci.motor_currents",
            "description": "motor currents, A, one per motor (thesis eq. C.1 from the ADC counts)",
            "properties": {"timestamp": TIME, "value": {"type": "array", "items": _NUMBER}}}

BASE_FRAME = "base_link"          # the URDF's frame 0 (models/urdf/<robot>.urdf)


def stamp(ns: int) -> dict:
    """A Foxglove time from nanoseconds."""
    return {"sec": int(ns // 1_000_000_000), "nsec": int(ns % 1_000_000_000)}


def frame_transform(ns: int, parent: str, child: str, p: list[float], quat: list[float]) -> dict:
    """A ``foxglove.FrameTransform`` message: ``child`` at position ``p`` (m) and rotation ``quat``
    (x, y, z, w) in ``parent``."""
    return {"timestamp": stamp(ns), "parent_frame_id": parent, "child_frame_id": child,
            "translation": dict(zip("xyz", p)), "rotation": dict(zip("xyzw", quat))}


def _pose_lists(T: np.ndarray) -> tuple[list, list]:
    """Positions and quaternions of poses ``T`` (..., 4, 4) as nested lists (one quaternion call for all)."""
    return T[..., :3, 3].tolist(), quaternion(T[..., :3, :3]).tolist()


def joint_states(ns: int, names: tuple[str, ...], **values: np.ndarray | None) -> dict | None:
    """A ``foxglove.JointStates`` message; a joint's field is left out where its value is NaN or None,
    a joint with no value at all is left out, and None is returned when no joint has one."""
    joints = []
    for j, name in enumerate(names):
        entry: dict = {"name": name}
        for field, row in values.items():
            if row is not None and np.isfinite(row[j]):
                entry[field] = float(row[j])
        if len(entry) > 1:
            joints.append(entry)
    return {"timestamp": stamp(ns), "joints": joints} if joints else None


def channels(si: LogSI, stamps: np.ndarray) -> Iterator[tuple[str, dict, list[dict | None]]]:
    """(topic, schema, messages) for each SI channel; ``stamps`` (N,) ns of each record."""
    n = len(stamps)
    names = si.joint_names
    yield "/joints/measured", JOINT_STATES, [
        joint_states(int(stamps[i]), names, position=si.q[i], velocity=si.qd[i],
                     effort=None if si.tau is None else si.tau[i]) for i in range(n)]
    yield "/joints/commanded", JOINT_STATES, [
        joint_states(int(stamps[i]), names, position=si.q_cmd[i], velocity=si.qd_cmd[i], effort=si.tau_cmd[i])
        for i in range(n)]
    # /tf as the URDF's chain (link k in link k-1), so a URDF layer and these agree on every
    # frame's parent; T6 is its own frame ("T6", in base_link), not a second parent of link6
    links = [BASE_FRAME] + [f"link{k + 1}" for k in range(si.links.shape[1])]
    local = np.concatenate([si.links[:, :1], np.linalg.inv(si.links[:, :-1]) @ si.links[:, 1:]], axis=1)
    p, quat = _pose_lists(local)                                     # link k+1 in link k (link 0: base)
    yield "/tf", FRAME_TRANSFORMS, [
        {"transforms": [frame_transform(int(stamps[i]), links[k], links[k + 1], p[i][k], quat[i][k])
                        for k in range(len(links) - 1)]} for i in range(n)]
    p, quat = _pose_lists(si.T6)
    yield "/T6", FRAME_TRANSFORM, [frame_transform(int(stamps[i]), BASE_FRAME, "T6", p[i], quat[i])
                                   for i in range(n)]
    ok = np.all(np.isfinite(si.T6_cmd.reshape(n, -1)), axis=1)
    p, quat = _pose_lists(si.T6_cmd)
    yield "/T6/commanded", FRAME_TRANSFORM, [
        frame_transform(int(stamps[i]), BASE_FRAME, "T6_commanded", p[i], quat[i]) if ok[i] else None
        for i in range(n)]
    if si.current is not None:
        yield "/motor_currents", CURRENTS, [{"timestamp": stamp(int(stamps[i])), "value": si.current[i].tolist()}
                                            for i in range(n)]
