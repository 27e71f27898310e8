"""Python back end: writes ``rccl/kinematics/<robot>.py`` from a robot's kernels.

Each kernel becomes two plain straight-line functions over common-subexpression-
eliminated expressions: ``_<name>_one`` (one configuration, ``math`` on floats) and
``_<name>_many`` (the same code on numpy columns, vectorised over a leading axis).
sin/cos of every joint angle (and of theta2 + theta3) are computed once at the top.
Robot constants are module-level names (``A2``, ``D3``, ``D4``, ``G``), written with
``repr`` so the file is exact and byte-for-byte reproducible. Guards are returned after
the outputs; the hand-written ``rccl.kinematics.runtime`` turns a negative guard into
the named exception. The public API of the kinematics contract lives in the runtime
(``runtime.public_api``); the end of the generated file only binds its names.
"""
from __future__ import annotations

from pathlib import Path

import sympy as sp
from sympy.printing.numpy import NumPyPrinter
from sympy.printing.pycode import PythonCodePrinter

from derive.kernel import Kernel
from derive.lowering import in_dependency_order
from derive.robots import RobotSpec, load_spec
from derive.dynamics_kernels import base_names
from rcci.models.kinematics import DYNAMICS, PUBLIC

COMMAND = "make derive  (python -m derive)"
#: the runtime's configuration record (rccl.kinematics.runtime) of each class's config signs
CONFIG_CLASSES = {("arm", "elbow", "wrist"): "ArmConfig", ("wrist",): "WristConfig",
                  ("arm", "boom", "wrist"): "BoomConfig",
                  ("shoulder", "elbow", "wrist"): "RedundantConfig",  # rccl.kinematics.redundant_ik
                  (): "NoConfig"}  # a redundant arm before its solver (rccl.kinematics.redundant)
#: the runtime module of each configuration record and its robot class (default: _rt, Robot)
RUNTIME_OF = {"RedundantConfig": ("_red", "RedundantRobot")}


class _OnePrinter(PythonCodePrinter):
    """Scalar code: math module on floats."""

    def __init__(self) -> None:
        super().__init__({"fully_qualified_modules": True})


class _ManyPrinter(NumPyPrinter):
    """Batched code: numpy ufuncs on columns; 1/x rather than x**(-1.0)."""

    def _print_Pow(self, expr, rational=False):
        return self._hprint_Pow(expr, rational=rational, sqrt="numpy.sqrt")


def _param_names(kernel: Kernel) -> dict[sp.Symbol, sp.Symbol]:
    return {s: sp.Symbol(s.name.upper()) for s in kernel.params}


def _elements(value: sp.Matrix) -> list[sp.Expr]:
    return [value[i, j] for i in range(value.rows) for j in range(value.cols)]


def _index(arg_shape: tuple[int, ...], flat: int) -> tuple[int, ...]:
    if len(arg_shape) == 0:
        return ()
    if len(arg_shape) == 1:
        return (flat,)
    return divmod(flat, arg_shape[1])


def _trig_locals(exprs: list[sp.Expr], inputs: set[sp.Symbol], taken: set[str]):
    """Replace sin/cos of joint angles (or sums of them) by locals computed once."""
    calls = set()
    for e in exprs:
        for f in e.atoms(sp.sin, sp.cos):
            arg = f.args[0]
            if arg.free_symbols <= inputs and (arg.is_Symbol or (arg.is_Add and all(a.is_Symbol for a in arg.args))):
                calls.add(f)
    assigns = []
    subs = {}
    for f in sorted(calls, key=sp.default_sort_key):
        arg = f.args[0]
        syms = sorted(arg.free_symbols, key=sp.default_sort_key)
        digits = "".join(s.name[1:] if s.name.startswith("q") and s.name[1:].isdigit() else s.name for s in syms)
        base = ("s" if isinstance(f, sp.sin) else "c") + digits
        name = base
        while name in taken:
            name = "_" + name
        taken.add(name)
        sym = sp.Symbol(name)
        subs[f] = sym
        assigns.append((sym, f))
    return [e.xreplace(subs) for e in exprs], assigns


def _lower(kernel: Kernel):
    """(input unpacking, trig locals, cse temps, output exprs) of one kernel."""
    pmap = _param_names(kernel)
    outs = []
    for a in kernel.outputs:
        outs += _elements(a.value)
    outs += [g.expr for g in kernel.guards]
    n_stage = len(kernel.stages) if kernel.program else 0
    if n_stage:  # a program: its assignments first, the outputs written in their symbols
        outs = [v for _, v in kernel.stages] + outs
    outs = [sp.sympify(e).xreplace(pmap) for e in outs]
    inputs: dict[sp.Symbol, tuple[str, tuple[int, ...]]] = {}
    for a in kernel.inputs:
        for k, el in enumerate(_elements(a.value)):
            if isinstance(el, sp.Symbol):
                inputs[el] = (a.name, _index(a.shape, k))
    used = set().union(*(e.free_symbols for e in outs)) if outs else set()
    taken = {s.name for s in inputs} | {a.name for a in kernel.inputs} | {p.name for p in pmap.values()}
    outs, trig = _trig_locals(outs, set(inputs), taken)
    temps, reduced = sp.cse(outs, symbols=sp.numbered_symbols("x"), order="canonical")
    if n_stage:
        stage_defs = [(s, r) for (s, _), r in zip(kernel.stages, reduced[:n_stage])]
        temps = in_dependency_order(list(temps) + stage_defs)
        reduced = reduced[n_stage:]
    unpack = [(s, inputs[s]) for s in sorted(used & set(inputs), key=sp.default_sort_key)]
    return unpack, trig, temps, reduced


def _function(kernel: Kernel, lowered, many: bool) -> str:
    unpack, trig, temps, reduced = lowered
    printer = _ManyPrinter() if many else _OnePrinter()
    args = ", ".join(a.name for a in kernel.inputs)
    suffix = "many" if many else "one"
    lines = [f"def _{kernel.name}_{suffix}({args}):"]
    first = kernel.inputs[0].name
    doc = kernel.doc.splitlines()[0] if kernel.doc else kernel.name
    lines.append(f'    """{doc} (thesis {kernel.source or "-"}); {"batched" if many else "one configuration"}."""')
    for sym, (arg, idx) in unpack:
        where = ", ".join(str(i) for i in idx)
        if not idx:  # a scalar input
            lines.append(f"    {sym.name} = {arg}")
        elif many:
            lines.append(f"    {sym.name} = {arg}[:, {where}]")
        else:
            lines.append(f"    {sym.name} = {arg}[{where}]")
    for sym, f in trig:
        lines.append(f"    {sym.name} = {printer.doprint(f)}")
    for sym, e in temps:
        lines.append(f"    {sym.name} = {printer.doprint(e)}")
    pos = 0
    results = []
    for a in kernel.outputs:
        n = len(_elements(a.value))
        vals = reduced[pos:pos + n]
        pos += n
        shape = a.shape
        if many:
            lines.append(f"    {a.name}_ = numpy.empty(({first}.shape[0],) + {shape!r})")
            for k, v in enumerate(vals):
                idx = ", ".join(str(i) for i in _index(shape, k))
                lines.append(f"    {a.name}_[:{', ' + idx if idx else ''}] = {printer.doprint(v)}")
        else:
            texts = [printer.doprint(v) for v in vals]
            if shape == ():
                lines.append(f"    {a.name}_ = float({texts[0]})")
            elif len(shape) == 1:
                lines.append(f"    {a.name}_ = numpy.array([{', '.join(texts)}], dtype=float)")
            else:
                rows = []
                for r in range(shape[0]):
                    rows.append("[" + ", ".join(texts[r * shape[1]:(r + 1) * shape[1]]) + "]")
                body = ",\n        ".join(rows)
                lines.append(f"    {a.name}_ = numpy.array([\n        {body}], dtype=float)")
        results.append(f"{a.name}_")
    for g in kernel.guards:
        v = reduced[pos]
        pos += 1
        text = printer.doprint(v)
        if many:
            lines.append(f"    {g.name} = numpy.broadcast_to(numpy.asarray({text}, dtype=float), ({first}.shape[0],))")
        else:
            lines.append(f"    {g.name} = float({text})")
        results.append(g.name)
    lines.append(f"    return ({', '.join(results)},)")
    return "\n".join(lines)


def _kernel_table(kernels: list[Kernel]) -> str:
    # the compiled C kernels replace these where available (rccl.kinematics.backend)
    lines = ["_KERNELS = _backend.accelerate(ROBOT, {"]
    for k in kernels:
        ins = ", ".join(f"({a.name!r}, {a.shape!r})" for a in k.inputs)
        outs = ", ".join(f"({a.name!r}, {a.shape!r})" for a in k.outputs)
        guards = ", ".join(f"_rt.GuardInfo({g.name!r}, {g.error!r}, {g.message!r})" for g in k.guards)
        lines.append(
            f"    {k.name!r}: _rt.KernelFn({k.name!r}, _{k.name}_one, _{k.name}_many,\n"
            f"        inputs=({ins}{',' if len(k.inputs) == 1 else ''}),\n"
            f"        outputs=({outs}{',' if len(k.outputs) == 1 else ''}),\n"
            f"        guards=({guards}{',' if len(k.guards) == 1 else ''})),"
        )
    lines.append("})")
    return "\n".join(lines)


def _coefficient_names(kernels: list[Kernel]) -> tuple[str, ...]:
    """The gravity coefficients' names, as the gravity kernel takes them."""
    k = next(k for k in kernels if k.name == "gravity")
    c = next(a for a in k.inputs if a.name == "c")
    return tuple(str(s) for s in c.value)


def module_source(kernels: list[Kernel], spec: RobotSpec) -> str:
    params = {}
    for k in kernels:
        for s, v in k.params.items():
            params[s.name.upper()] = float(v)
    consts = "\n".join(f"{n} = {v!r}" for n, v in sorted(params.items()))
    kinds = tuple(spec.kinds)
    config = CONFIG_CLASSES[spec.config_fields]
    rt, robot_class = RUNTIME_OF.get(config, ("_rt", "Robot"))
    extra_import = "" if rt == "_rt" else "from rccl.kinematics import redundant_ik as _red\n"
    head = f'''"""Kinematics of the {spec.name}: GENERATED by `{COMMAND}` from derive/; do not edit.

Forward and inverse kinematics, the link-4 and frame-6 Jacobians with their four
computations, the gravity vector and the whole dynamics (eq. 4.6: inverse dynamics, D, c, C,
base regressor), derived with SymPy from the DH table of
{spec.model_path.split("/")[-1]} (J. Lloyd 1985, chapters 3 and 4). SI units, radians; every
function accepts one configuration or a batch along a leading axis. Contract:
rcci.models.kinematics; runtime helpers: rccl.kinematics.runtime.
"""
# fmt: off
# ruff: noqa
from __future__ import annotations

import math

import numpy

from rccl.kinematics import backend as _backend
from rccl.kinematics import runtime as _rt
{extra_import}
ROBOT = {spec.name!r}
#: model constants used (m, m/s^2), from {spec.model_path.split("/")[-1]}
{consts}
JOINT_KINDS = {kinds!r}
#: joint ranges (rad; m for prismatic joints), from the model file
LOWER = numpy.array({list(spec.lower)!r})
UPPER = numpy.array({list(spec.upper)!r})
GRAVITY_COEFFS = {_coefficient_names(kernels)!r}
Config = {rt}.{config}
CONFIGS = Config.all()
'''
    funcs = []
    for k in kernels:
        lowered = _lower(k)
        funcs.append(_function(k, lowered, many=False))
        funcs.append(_function(k, lowered, many=True))
    names = list(PUBLIC)
    binds = "(" + ", ".join(names[:8]) + ",\n " + ", ".join(names[8:]) + ") = _API"
    api = f'''
_ROBOT = {rt}.{robot_class}(ROBOT, _KERNELS, JOINT_KINDS, LOWER, UPPER, Config, GRAVITY_COEFFS)
_API = _rt.public_api(_ROBOT)  # the contract's functions: compiled fast entries, runtime checks behind
{binds}
''' + _dynamics_api(kernels)
    return head + "\n\n" + "\n\n\n".join(funcs) + "\n\n\n" + _kernel_table(kernels) + "\n" + api


def _dynamics_api(kernels: list[Kernel]) -> str:
    """The dynamics functions (rcci.models.kinematics.DYNAMICS): compiled fast entries over the
    runtime's checks, as the contract's functions."""
    present = [n for n in DYNAMICS if any(k.name == n for k in kernels)]
    if not present:
        return ""
    lines = ["", "#: the base parameters of the dynamics (derive.dynamics_base), base_regressor's columns",
             f"BASE_PARAMETERS = {base_names(kernels)!r}", "", "",
             "def _dynamics_entry(kname, doc):",
             "    def run(*args, out=None):",
             "        return _ROBOT.call(kname, *args, out=out)[0]",
             "    run.__name__, run.__doc__ = kname, doc",
             "    return _backend.public(ROBOT, kname, run, _ROBOT.kernels)", "", ""]
    for n in present:
        args, result = DYNAMICS[n]
        lines.append(f"{n} = _dynamics_entry({n!r}, {f'{n}({args}) -> {result} (thesis eq. 4.6)'!r})")
    return "\n".join(lines) + "\n"


def emit(kernels: list[Kernel], programs: list, robot: str, out_dir: Path) -> list[Path]:
    """Write ``out_dir/<robot>.py``; returns the files written. ``programs`` (the compiled
    back ends' lowering) is not used: this back end prints the kernels' expressions itself."""
    spec = load_spec(robot)
    path = Path(out_dir) / f"{robot}.py"
    text = module_source(kernels, spec)
    if not path.exists() or path.read_text() != text:
        path.write_text(text)
    return [path]
