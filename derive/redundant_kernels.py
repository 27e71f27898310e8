"""The redundant inverse's kernels and its generated module (``rccl/kinematics/<robot>_ik.py``
and ``_c/<robot>_ik.c``): `python -m derive.redundant_kernels --robot panda`.

Kernels (derive.kernel conventions; T is frame 7, the flange, in the base frame, m):

* ``fk``: T of q (7,), the product A1..A7 of the standard-DH table derive sees;
* ``ik``: q (7,) of T, the free value q7 (rad) and the config signs (shoulder, elbow,
  wrist), with the guards of derive.inverse_redundant;
* ``ik_all``: every configuration at once (derive.lowering.all_configurations_kernels:
  rows in Config.all() order, guards per row);
* ``config_indicators``: the values whose signs are q's configuration.

The runtime (rccl.kinematics.redundant_ik) wraps them into ``ik(T, config, q_ref=None,
q7=...)``, ``ik_all(T, q7, q_ref=None)`` and ``config_of(q)``. Until derive's 7-joint
support (the panda branch) emits the arm's whole module, this is a module of its own.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import sympy as sp

from derive import emit_c
from derive.dh import DHLink, DHRobot, _angle, _length, a_matrix
from derive.emit_python import _function, _kernel_table, _lower
from derive.inverse import POSE_INPUT
from derive.inverse_redundant import CONFIG_FIELDS, FREE, Q7, RedundantIK, redundant_ik
from derive.kernel import Arg, Guard, Kernel

ROOT = Path(__file__).resolve().parent.parent
OUT_DIR = ROOT / "rccl" / "kinematics"
COMMAND = "python -m derive.redundant_kernels"
PI = sp.Float(sp.pi.evalf(20), 20)


def table(name: str) -> tuple[DHRobot, dict[sp.Symbol, float]]:
    """The standard-DH table of a 7-joint model file (``rcci.models.load_robot``), as
    derive.dh.dh_from_model builds the 6-joint ones: zero lengths 0, whole-degree angles
    exact, every other value a symbol whose number is substituted at emission."""
    from rcci.models import load_robot

    model = load_robot(name)
    if model.n_joints != 7 or any(j.kind != "revolute" for j in model.joints):
        raise ValueError(f"{model.path}: the redundant inverse needs 7 revolute joints, "
                         f"the file has {model.n_joints} ({', '.join(j.kind for j in model.joints)})")
    params: dict[sp.Symbol, float] = {}
    links = []
    for j, q in zip(model.joints, Q7):
        if j.theta != 0.0:
            raise ValueError(f"{model.path}: joints.{j.index}.theta: offset {j.theta} on the joint "
                             "variable is not supported by the derivation")
        links.append(DHLink(_length(j.d, f"d{j.index}", params), q,
                            _angle(j.alpha, f"alpha{j.index}", params), _length(j.a, f"a{j.index}", params)))
    return DHRobot(model.name, tuple(links), tuple(params)), params


def build(ik: RedundantIK, params: dict[sp.Symbol, float], robot: str) -> list[Kernel]:
    """fk, ik, config_indicators and ik_all of one redundant arm (``robot`` names the module)."""
    q = sp.Matrix(Q7)
    qarg = Arg("q", q, "joint variables (rad)")
    t = sp.eye(4)
    for link in ik.robot.links:
        t = t * a_matrix(link)

    def kernel(name, doc, inputs, outputs, guards=(), source=""):
        # pi (from atan2 of constant coefficients) as a number: the C printer takes no symbol pi
        outputs = [Arg(o.name, o.value.xreplace({sp.pi: PI}), o.doc) for o in outputs]
        guards = [Guard(g.name, g.expr.xreplace({sp.pi: PI}), g.error, g.message) for g in guards]
        used = set().union(*(o.value.free_symbols for o in outputs), *(g.expr.free_symbols for g in guards))
        return Kernel(robot, name, doc, tuple(inputs), tuple(outputs), tuple(guards),
                      {s: v for s, v in params.items() if s in used}, source)

    ks = [
        kernel("fk", "T: frame 7 (the flange) in the base frame (4x4 homogeneous transform, m)",
               [qarg], [Arg("T", t, "base_to_flange")], source="3.16-3.18"),
        kernel("ik", "joint variables for pose T and free value q7 in one configuration (signs +-1: "
               + ", ".join(CONFIG_FIELDS) + ")",
               [Arg("T", POSE_INPUT, "base_to_flange"), Arg("q7", sp.Matrix([FREE]), "joint 7 (rad)"),
                Arg("config", sp.Matrix(ik.config), "configuration signs")],
               [Arg("q", sp.Matrix(ik.joints), "joint variables")],
               [Guard(*g) for g in ik.guards], source="3.19-3.21"),
        kernel("config_indicators", "values whose signs are the configuration of q ("
               + ", ".join(CONFIG_FIELDS) + ")", [qarg],
               [Arg("indicator", sp.Matrix(ik.indicators), "sign = configuration")], source="3.21"),
    ]
    from derive.lowering import all_configurations_kernels

    return ks + all_configurations_kernels(ks)  # ik_all: every config of ik (the Python module's)


def module_source(kernels: list[Kernel], name: str, lower, upper) -> str:
    """The generated Python module: straight-line kernels, the compiled ones swapped in,
    bound to the runtime's redundant arm."""
    consts = {}
    for k in kernels:
        for s, v in k.params.items():
            consts[s.name.upper()] = float(v)
    head = f'''"""Closed-form inverse kinematics of the {name} with q7 free: GENERATED by `{COMMAND} --robot {name}`
from derive/inverse_redundant.py; do not edit.

``ik(T, config, q_ref=None, q7=...)``, ``ik_all(T, q7, q_ref=None)``, ``config_of(q)`` and the
``fk`` they check against (T = frame 7, the flange, in the base frame; SI units, radians);
runtime: rccl.kinematics.redundant_ik.
"""
# fmt: off
# ruff: noqa
from __future__ import annotations

import math

import numpy

from rccl.kinematics import backend as _backend
from rccl.kinematics import redundant_ik as _red
from rccl.kinematics import runtime as _rt

ROBOT = {name + "_ik"!r}
#: model constants used (m), from {name}.toml
''' + "\n".join(f"{n} = {v!r}" for n, v in sorted(consts.items())) + f'''
#: joint ranges (rad), from the model file
LOWER = numpy.array({[float(x) for x in lower]!r})
UPPER = numpy.array({[float(x) for x in upper]!r})
Config = _red.RedundantConfig
CONFIGS = Config.all()
'''
    funcs = []
    for k in kernels:
        lowered = _lower(k)
        funcs += [_function(k, lowered, many=False), _function(k, lowered, many=True)]
    tail = '''
_ROBOT = _red.RedundantRobot(ROBOT, _KERNELS, LOWER, UPPER)
fk, ik, ik_all, config_of = _ROBOT.fk, _ROBOT.ik, _ROBOT.ik_all, _ROBOT.config_of
'''
    return head + "\n\n" + "\n\n\n".join(funcs) + "\n\n\n" + _kernel_table(kernels) + "\n" + tail


def write(name: str, out_dir: Path = OUT_DIR) -> list[Path]:
    """Derive and write ``<name>_ik.py`` and ``_c/<name>_ik.c``; returns the paths."""
    from rcci.models import load_robot

    r, params = table(name)
    kernels = build(redundant_ik(r), params, f"{name}_ik")
    model = load_robot(name)
    py = Path(out_dir) / f"{name}_ik.py"
    text = module_source(kernels, name, model.lower, model.upper)
    if not py.exists() or py.read_text() != text:
        py.write_text(text)
    c = emit_c.write_programs(f"{name}_ik", emit_c.lower_all([k for k in kernels if k.name != "ik_all"]),
                              Path(out_dir) / "_c", f"{COMMAND} --robot {name}")
    return [py, c]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog=COMMAND, description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--robot", required=True, help="a 7-joint arm under models/ (panda)")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    for p in write(args.robot):
        print(f"derive: {args.robot}: {p.relative_to(ROOT)}")
    print(f"derive: {args.robot}: redundant inverse in {time.perf_counter() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
