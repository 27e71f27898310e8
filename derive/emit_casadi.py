"""CasADi back end: each Kernel becomes a ``casadi.Function`` (SX) saved where ``casadi.Function.load`` reads it.

The SX graph is built from the same lowered program as the C (``derive.emit_c``): trig
calls once, shared subexpressions, the n/o/a cross product, so the CasADi expression
graph is as small as the C. Inputs and outputs keep the kernel's names and shapes
(a 4x4 transform is a 4x4 SX matrix); guards are extra scalar outputs.
Files: ``rccl/kinematics/casadi/<robot>/<kernel>.casadi``.
"""
from __future__ import annotations

from pathlib import Path

import casadi as ca
import sympy as sp

from derive.emit_c import best_program
from derive.lowering import LoweredKernel
from derive.kernel import Kernel

_FUNCS = {
    sp.sin: ca.sin, sp.cos: ca.cos, sp.tan: ca.tan, sp.atan2: ca.atan2, sp.atan: ca.atan,
    sp.asin: ca.asin, sp.acos: ca.acos, sp.Abs: ca.fabs, sp.exp: ca.exp, sp.log: ca.log,
    sp.Max: ca.fmax, sp.Min: ca.fmin,
}


def _sx_shape(shape: tuple[int, ...]) -> tuple[int, int]:
    return (1, 1) if shape == () else (shape[0], 1) if len(shape) == 1 else shape


class _ToSX:
    """SymPy -> CasADi SX translation with a memo (shared subtrees stay shared)."""

    def __init__(self, env: dict[sp.Symbol, ca.SX]):
        self.env = env
        self.memo: dict[sp.Expr, ca.SX] = {}

    def __call__(self, e: sp.Expr) -> ca.SX:
        if e in self.env:
            return self.env[e]
        if e in self.memo:
            return self.memo[e]
        if e.is_Number or e.is_NumberSymbol:  # pi: a redundant arm's range wrap (derive.inverse_redundant)
            out = ca.SX(float(e))
        elif e.is_Add:
            args = [self(a) for a in e.args]
            out = args[0]
            for a in args[1:]:
                out = out + a
        elif e.is_Mul:
            args = [self(a) for a in e.args]
            out = args[0]
            for a in args[1:]:
                out = out * a
        elif e.is_Pow:
            b, x = self(e.base), e.exp
            if x == sp.Rational(1, 2):
                out = ca.sqrt(b)
            elif x == sp.Rational(-1, 2):
                out = 1 / ca.sqrt(b)
            elif x.is_Integer and x < 0:
                out = 1 / (b ** int(-x)) if x != -1 else 1 / b
            elif x.is_Integer:
                out = b ** int(x)
            else:
                out = b ** float(x)
        elif e.func in _FUNCS:
            out = _FUNCS[e.func](*[self(a) for a in e.args])
        else:
            raise ValueError(f"CasADi emitter: unsupported expression {e!r}")
        self.memo[e] = out
        return out


def function(prog: LoweredKernel) -> ca.Function:
    """The casadi.Function of one lowered kernel."""
    k = prog.kernel
    env: dict[sp.Symbol, ca.SX] = {}
    sx_inputs = []
    name_to_sx: dict[str, ca.SX] = {}
    for i, arg in enumerate(k.inputs):
        rows, cols = _sx_shape(arg.shape)
        x = ca.SX.sym(arg.name, rows, cols)
        sx_inputs.append(x)
        for j, cname in enumerate(prog.in_names[i]):
            r, c = divmod(j, cols)
            name_to_sx[cname] = x[r, c]
    for sym, cname in prog.symbol_names.items():
        env[sym] = name_to_sx[cname]
    conv = _ToSX(env)
    for sym, value in list(prog.trig) + list(prog.temps):
        env[sym] = conv(value)
    out_values: dict[str, ca.SX] = {}
    for name, value in prog.outputs:
        v = conv(value)
        out_values[name] = v
        env[sp.Symbol(f"__{name}")] = v
    out_args = list(k.outputs) + [None] * len(k.guards)
    out_names = [a.name for a in k.outputs] + [g.name for g in k.guards]
    sx_outputs = []
    for i, arg in enumerate(out_args):
        shape = arg.shape if arg is not None else ()
        rows, cols = _sx_shape(shape)
        m = ca.SX.zeros(rows, cols)
        for j, cname in enumerate(prog.out_names[i]):
            r, c = divmod(j, cols)
            m[r, c] = out_values[cname]
        sx_outputs.append(m)
    return ca.Function(f"{k.robot}_{k.name}", sx_inputs, sx_outputs, [a.name for a in k.inputs], out_names)


def emit(kernels: list[Kernel], programs: list[tuple[LoweredKernel, str]], robot: str, out_dir: Path) -> list[Path]:
    """Back-end entry of ``python -m derive``: ``out_dir/casadi/<robot>/<kernel>.casadi``,
    one per program the C back end chose (derive.emit_c.lower_all: the kernels and ik_all)."""
    return write(robot, [p.kernel for p, _ in programs], Path(out_dir) / "casadi", programs)


def write(robot: str, kernels: list[Kernel], out_dir: Path,
          programs: list[tuple[LoweredKernel, str]] | None = None) -> list[Path]:
    """Save one ``<kernel>.casadi`` per kernel under ``out_dir/<robot>/``; return the paths.

    ``programs`` (from ``derive.emit_c.write``) avoids lowering the kernels twice.
    """
    d = out_dir / robot
    d.mkdir(parents=True, exist_ok=True)
    progs = [p for p, _ in programs] if programs is not None else [best_program(k)[0] for k in kernels]
    paths = []
    for prog in progs:
        path = d / f"{prog.kernel.name}.casadi"
        tmp = path.with_suffix(".tmp")
        function(prog).save(str(tmp))
        if path.exists() and path.read_bytes() == tmp.read_bytes():
            tmp.unlink()
        else:
            tmp.replace(path)
        paths.append(path)
    return paths
