"""Write a robot's URDF from its data file: ``python -m rcci.models.urdf_write puma560``.

The URDF follows the conventions of models/README.md: ``base_link`` is DH frame 0 and
``link1 .. linkN`` are DH frames 1 .. N. A DH step A_i = Rz(q_i) Tz(d_i) Tx(a_i) Rx(alpha_i)
(revolute) becomes a joint with origin Tz(d_i) Rz(theta_i) and axis z, moving a body
``link<i>_body``, and a fixed joint Tx(a_i) Rx(alpha_i) to ``link<i>`` (Pinocchio merges
the two, keeping the frame ``link<i>``); a prismatic step slides along z with origin
Rz(theta_i). Limits, velocities and inertials are the data file's; efforts are
the data file's max_effort, else
max_current x torque sensitivity x |G_ii|. Visuals are a sketch: a cylinder per joint axis
and a box along each link offset.
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from .catalogue import data_file
from .loader import Loader
from .robot import RobotModel


def _f(x: float) -> str:
    return repr(float(x))


def _visual_link(name: str, a: float, d_next: float) -> str:
    parts = [f'  <link name="{name}">']
    parts.append('    <visual><geometry><sphere radius="0.04"/></geometry><material name="cream"/></visual>')
    if abs(a) > 1e-9:
        parts.append(f'    <visual><origin xyz="{_f(-a / 2)} 0 0" rpy="0 0 0"/>'
                     f'<geometry><box size="{_f(abs(a))} 0.05 0.05"/></geometry><material name="cream"/></visual>')
    if abs(d_next) > 1e-9:
        parts.append(f'    <visual><origin xyz="0 0 {_f(d_next / 2)}" rpy="0 0 0"/>'
                     f'<geometry><cylinder radius="0.03" length="{_f(abs(d_next))}"/></geometry>'
                     '<material name="grey"/></visual>')
    return "\n".join(parts)


def urdf_text(model: RobotModel) -> str:
    """The URDF of ``model`` (its data file's DH table, limits and inertials)."""
    g = model.conversion.gear_ratio.values
    sigma = model.motors.torque_sensitivity.values
    out = ['<?xml version="1.0"?>',
           f'<!-- {model.title}: GENERATED from {model.path.name} by `python -m rcci.models.urdf_write '
           f'{model.name}`; do not edit.',
           '  base_link is DH frame 0, link1 .. linkN are DH frames 1 .. N (models/README.md).',
           '  Visual geometry is a sketch. -->',
           f'<robot name="{model.name}">',
           '  <material name="grey"><color rgba="0.6 0.6 0.62 1"/></material>',
           '  <material name="cream"><color rgba="0.93 0.9 0.8 1"/></material>',
           '  <link name="base_link">',
           '    <visual><origin xyz="0 0 0.01" rpy="0 0 0"/><geometry><box size="0.3 0.3 0.02"/></geometry>'
           '<material name="grey"/></visual>',
           '  </link>']
    parent = "base_link"
    for j in model.joints:
        i = j.index
        body = f"link{i}_body"
        effort = float(model.max_effort[i - 1]) if model.max_effort is not None else \
            float(model.max_current[i - 1] * sigma[i - 1] * abs(g[i - 1, i - 1]))
        if j.kind == "revolute":
            origin = f'xyz="0 0 {_f(j.d)}" rpy="0 0 {_f(j.theta)}"'
        else:
            origin = f'xyz="0 0 0" rpy="0 0 {_f(j.theta)}"'
        out.append(f'  <joint name="{j.name}" type="{j.kind}">')
        out.append(f'    <parent link="{parent}"/>')
        out.append(f'    <child link="{body}"/>')
        out.append(f'    <origin {origin}/>')
        out.append('    <axis xyz="0 0 1"/>')
        out.append(f'    <limit lower="{_f(j.lower)}" upper="{_f(j.upper)}" velocity="{_f(j.max_velocity)}" '
                   f'effort="{effort:.2f}"/>')
        out.append('  </joint>')
        out.append(f'  <link name="{body}"/>')
        out.append(f'  <joint name="{body}_to_link{i}" type="fixed">')
        out.append(f'    <parent link="{body}"/>')
        out.append(f'    <child link="link{i}"/>')
        out.append(f'    <origin xyz="{_f(j.a)} 0 0" rpy="{_f(j.alpha)} 0 0"/>')
        out.append('  </joint>')
        li = model.links[i - 1]
        inertia = li.inertia
        d_next = model.joints[i].d if i < model.n_joints else 0.0
        out.append(_visual_link(f"link{i}", j.a, d_next))
        out.append('    <inertial>')
        out.append(f'      <origin xyz="{" ".join(_f(x) for x in li.com)}" rpy="0 0 0"/>')
        out.append(f'      <mass value="{_f(li.mass)}"/>')
        out.append(f'      <inertia ixx="{_f(inertia[0, 0])}" iyy="{_f(inertia[1, 1])}" izz="{_f(inertia[2, 2])}" '
                   f'ixy="{_f(inertia[0, 1])}" ixz="{_f(inertia[0, 2])}" iyz="{_f(inertia[1, 2])}"/>')
        out.append('    </inertial>')
        out.append('  </link>')
        parent = f"link{i}"
    out.append('</robot>')
    return "\n".join(out) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m rcci.models.urdf_write", description=__doc__.splitlines()[0])
    ap.add_argument("robot", help="robot name or data-file path")
    args = ap.parse_args(argv)
    model = Loader(data_file(args.robot)).load(check=False)
    text = urdf_text(model)
    path = Path(model.urdf_path)
    if not path.exists() or path.read_text() != text:
        path.write_text(text)
    print(f"rcci.models.urdf_write: {path}")
    Loader(data_file(args.robot)).load()  # the written URDF passes the loader's check
    return 0


if __name__ == "__main__":
    sys.exit(main())
