"""A kernel: one straight-line function from input symbols to output expressions.

This is the contract between the derivation (the SymPy scripts that produce the
expressions) and the code emitters (Python, C, CasADi back ends). The derivation says
*what* is computed; an emitter decides *how* it is written out (common subexpressions,
sin/cos sharing, operation counts).

Conventions every kernel follows:

* Inputs and outputs are SymPy matrices; their shapes are the shapes of the generated
  arrays (a column vector ``Matrix(6, 1)`` becomes a ``(6,)`` array, a ``Matrix(4, 4)``
  a ``(4, 4)`` array). Scalars are ``Matrix(1, 1)`` and become Python floats.
* Units are SI and radians; frames are named in ``doc``.
* A *guard* is a scalar output whose name starts with ``guard_``. A guard is
  non-negative when the main outputs are valid; a negative guard means the input is
  outside the kernel's domain (an unreachable pose, a singular configuration), and the
  runtime raises the error named by the guard's ``Guard.error`` with ``Guard.message``.
  Guards let generated straight-line code report domain errors without branching and
  without ever returning a silent NaN.
* ``params`` are robot constants (link lengths, gravity coefficients given as inputs
  stay inputs); they are substituted numerically by the emitter when ``numeric=True``.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import sympy as sp


@dataclass(frozen=True)
class Arg:
    """A named input or output array of a kernel."""

    name: str
    value: sp.Matrix
    doc: str = ""

    @property
    def shape(self) -> tuple[int, ...]:
        rows, cols = self.value.shape
        if rows == 1 and cols == 1:
            return ()
        if cols == 1:
            return (rows,)
        return (rows, cols)


@dataclass(frozen=True)
class Guard:
    """A scalar output that must be >= 0 for the main outputs to be valid."""

    name: str  # must start with "guard_"
    expr: sp.Expr
    error: str  # name of the exception class in rccl.kinematics.exceptions
    message: str  # what a negative value means, for the user


@dataclass(frozen=True)
class Kernel:
    """A straight-line function: ``outputs = f(inputs)`` with optional guards."""

    robot: str
    name: str
    doc: str
    inputs: tuple[Arg, ...]
    outputs: tuple[Arg, ...]
    guards: tuple[Guard, ...] = ()
    params: dict[sp.Symbol, float] = field(default_factory=dict)
    source: str = ""  # thesis equations this kernel implements, e.g. "3.16-3.18"
    #: optional structure hint for back ends (the outputs stay authoritative): intermediate
    #: symbols in order, each defined from the inputs and the symbols before it, and the
    #: main outputs written with them
    #: (e.g. a frame-4 computation, then one map of 3.79); same values as ``outputs``
    stages: tuple[tuple[sp.Symbol, sp.Expr], ...] = ()
    staged: tuple[sp.Matrix, ...] = ()
    #: True when the stages are the definition, not a hint: the outputs are written in the
    #: stage symbols (a recursion such as Newton-Euler, whose outputs written out in the
    #: inputs would be trees of 10^9 nodes); back ends then print the stages as assignments
    program: bool = False

    def __post_init__(self) -> None:
        names = [a.name for a in self.inputs] + [a.name for a in self.outputs]
        names += [g.name for g in self.guards]
        if len(names) != len(set(names)):
            raise ValueError(f"kernel {self.robot}.{self.name}: duplicate argument names {names}")
        for g in self.guards:
            if not g.name.startswith("guard_"):
                raise ValueError(f"kernel {self.robot}.{self.name}: guard {g.name!r} must start with 'guard_'")
