"""C back end: lowers each Kernel to straight-line optimised C and writes one extension source per robot.

Lowering (shared with the CasADi back end, see ``lower``):

1. robot constants (``Kernel.params``) are substituted numerically;
2. every distinct ``sin(x)`` / ``cos(x)`` becomes a local computed once at the top;
3. sums are factored greedily (multivariate Horner: pull out the factor shared by most
   terms, recursively), then common subexpressions are shared (``sympy.cse``);
4. for a 4x4 homogeneous-transform output one rotation column may be computed as the
   cross product of the other two (thesis 3.3: n = o x a, o = a x n, a = n x o);
5. the cheapest variant, counted by ``derive.opcount`` in the C text itself, is kept.

The printer writes no ``pow()`` (integer powers become products, half powers ``sqrt``),
no allocation, and avoids unary minus by folding signs into subtractions.

The emitted file is a complete CPython extension module (plain C API + buffer
protocol, no numpy headers): for each kernel a ``static inline`` row function, a
batched loop over N rows inside C, a NaN/inf scan of the inputs, and a ``run()`` entry
point used by ``rccl.kinematics.backend``.
"""
from __future__ import annotations

import itertools
import math
import json
from collections import Counter
from dataclasses import dataclass, replace
from pathlib import Path

import sympy as sp

from derive.kernel import Arg, Kernel
from derive import opcount

#: Functions the C printer knows, with their C spelling.
C_FUNCS = {
    sp.sin: "sin", sp.cos: "cos", sp.tan: "tan", sp.atan2: "atan2", sp.atan: "atan",
    sp.asin: "asin", sp.acos: "acos", sp.Abs: "fabs", sp.exp: "exp", sp.log: "log",
}


@dataclass
class Program:
    """A kernel lowered to a list of assignments (the form both C and CasADi print)."""

    kernel: Kernel
    in_names: list[list[str]]          # C name of every input element, per input arg
    out_names: list[list[str]]         # C name of every output element, per output arg (+ guards)
    trig: list[tuple[sp.Symbol, sp.Expr]]   # (local, sin(x) or cos(x))
    temps: list[tuple[sp.Symbol, sp.Expr]]  # common subexpressions, in order
    outputs: list[tuple[str, sp.Expr]]      # (output element name, expression)
    symbol_names: dict[sp.Symbol, str]      # input symbol -> C name
    variant: str = ""


def arg_elements(value: sp.Matrix) -> list[sp.Expr]:
    """Flatten a kernel argument matrix row-major (the layout of the numpy array)."""
    return [value[i, j] for i in range(value.shape[0]) for j in range(value.shape[1])]


def _input_symbols(kernel: Kernel) -> tuple[list[list[str]], dict[sp.Symbol, str]]:
    names: list[list[str]] = []
    sym_names: dict[sp.Symbol, str] = {}
    for i, arg in enumerate(kernel.inputs):
        row = []
        for j, el in enumerate(arg_elements(arg.value)):
            if not isinstance(el, sp.Symbol):
                raise ValueError(f"kernel {kernel.robot}.{kernel.name}: input {arg.name}[{j}] is {el}, not a symbol")
            cname = f"in{i}[{j}]"
            sym_names[el] = cname
            row.append(cname)
        names.append(row)
    return names, sym_names


def _outputs(kernel: Kernel) -> tuple[list[list[str]], list[sp.Expr]]:
    names: list[list[str]] = []
    exprs: list[sp.Expr] = []
    for i, arg in enumerate(kernel.outputs):
        els = arg_elements(arg.value)
        names.append([f"out{i}[{j}]" for j in range(len(els))])
        exprs.extend(els)
    gi = len(kernel.outputs)
    for k, g in enumerate(kernel.guards):
        names.append([f"out{gi + k}[0]"])
        exprs.append(g.expr)
    return names, exprs


def dag_xreplace(exprs: list[sp.Expr], subs: dict[sp.Expr, sp.Expr]) -> list[sp.Expr]:
    """``xreplace`` that visits each distinct subexpression once (SymPy's walks the tree)."""
    memo: dict[sp.Expr, sp.Expr] = {}

    def walk(e: sp.Expr) -> sp.Expr:
        if e in subs:
            return subs[e]
        if not e.args:
            return e
        if e in memo:
            return memo[e]
        args = [walk(a) for a in e.args]
        out = e.func(*args) if any(a is not b for a, b in zip(args, e.args)) else e
        memo[e] = out
        return out

    return [walk(sp.sympify(e)) for e in exprs]


def dag_atoms(exprs: list[sp.Expr], *types: type) -> set[sp.Expr]:
    """Subexpressions of the given types, visiting each distinct node once."""
    seen: set[sp.Expr] = set()
    found: set[sp.Expr] = set()
    stack = list(exprs)
    while stack:
        e = stack.pop()
        if e in seen:
            continue
        seen.add(e)
        if isinstance(e, types):
            found.add(e)
        stack.extend(e.args)
    return found


def _numeric(kernel: Kernel, exprs: list[sp.Expr]) -> list[sp.Expr]:
    subs = {k: sp.Float(v, 17) if not float(v).is_integer() else sp.Integer(int(v)) for k, v in kernel.params.items()}
    return dag_xreplace(exprs, subs) if subs else [sp.sympify(e) for e in exprs]


def _split(xs: list, n: int) -> tuple[list, list]:
    return xs[:n], xs[n:]


def _integral_floats(exprs: list[sp.Expr]) -> list[sp.Expr]:
    """Floats that are integers up to the rounding of 17-digit arithmetic as integers.

    a2/d4 is 1 exactly for the PUMA (a2 = d4 = 0.2032 m), but 0.2032 * (1/0.2032) comes
    out 0.99999999999999999: kept, it would cost a multiplication by 1.0.
    """
    snap = {f: sp.Integer(round(f)) for f in dag_atoms(exprs, sp.Float)
            if abs(f - round(f)) <= 1e-15 * max(1.0, abs(float(f)))}
    return dag_xreplace(exprs, snap) if snap else exprs


def _extract_trig(exprs: list[sp.Expr]) -> tuple[list[sp.Expr], list[tuple[sp.Symbol, sp.Expr]]]:
    """Replace every distinct sin(x)/cos(x) by a local symbol computed once.

    A compound argument (q2 + q3) is itself computed once, before its sin and cos.
    """
    calls = dag_atoms(exprs, sp.sin, sp.cos)
    # sort for a deterministic file: by argument text, sin before cos
    ordered = sorted(calls, key=lambda f: (sp.default_sort_key(f.args[0]), f.func.__name__ != "sin"))
    trig: list[tuple[sp.Symbol, sp.Expr]] = []
    subs: dict[sp.Expr, sp.Symbol] = {}
    arg_syms: dict[sp.Expr, sp.Symbol] = {}
    for f in ordered:
        arg = f.args[0]
        if not arg.is_Atom and arg not in arg_syms:
            arg_syms[arg] = sp.Symbol(f"x_{len(arg_syms)}")
            trig.append((arg_syms[arg], arg))
        k = len(subs)
        s = sp.Symbol(f"{'s' if f.func is sp.sin else 'c'}_{k}")
        subs[f] = s
        trig.append((s, f.func(arg_syms.get(arg, arg))))
    return dag_xreplace(exprs, subs), trig


def _factor_sum(expr: sp.Expr, rank: dict[sp.Expr, int] | None = None,
                memo: dict[sp.Expr, sp.Expr] | None = None) -> sp.Expr:
    """Greedy multivariate Horner: pull a factor shared by several terms out of each sum.

    Without ``rank`` the factor shared by most terms goes first; with it, the shared
    factor of lowest rank (e.g. the trig of the joint nearest the base) goes first.
    ``memo`` keeps shared subtrees shared (expressions are DAGs).
    """
    if expr.is_Atom:
        return expr
    if memo is None:
        memo = {}
    if expr in memo:
        return memo[expr]
    out = _factor_sum_node(expr, rank, memo)
    memo[expr] = out
    return out


def _factor_sum_node(expr: sp.Expr, rank, memo) -> sp.Expr:
    args = [_factor_sum(a, rank, memo) for a in expr.args]
    if not expr.is_Add:
        return expr.func(*args) if args != list(expr.args) else expr
    terms = list(args)
    common = _common_coefficient(terms)
    if common is not None:
        # a*x - a*y -> a*(x - y): one multiplication instead of one per term
        inner = [sp.Mul(sp.sign(c), r) for c, r in (t.as_coeff_Mul() for t in terms)]
        return sp.Mul(common, _factor_sum(sp.Add(*inner), rank, memo), evaluate=False)
    counts: Counter = Counter()
    for t in terms:
        for f in set(_factors(t)):
            counts[f] += 1
    shared = sorted(((f, n) for f, n in counts.items() if n >= 2), key=lambda kv: sp.default_sort_key(kv[0]))
    if not shared:
        return sp.Add(*terms)
    if rank:
        big = 1 << 30
        best = min(shared, key=lambda kv: (rank.get(kv[0], big), -kv[1]))[0]
    else:
        best = max(shared, key=lambda kv: kv[1])[0]
    inside = [t for t in terms if best in _factors(t)]
    rest = [t for t in terms if best not in _factors(t)]
    inner = _factor_sum(sp.Add(*[_divide_out(t, best) for t in inside]), rank, memo)
    out = sp.Mul(best, inner, evaluate=False)
    if rest:
        return sp.Add(out, _factor_sum(sp.Add(*rest), rank, memo), evaluate=False)
    return out


def _common_coefficient(terms: list[sp.Expr]) -> sp.Expr | None:
    """|c| when every term of a sum is +-c times something and c is not 1, else None."""
    coeffs = [t.as_coeff_Mul()[0] for t in terms]
    if len(terms) < 2 or any(not c.is_Number or c == 0 for c in coeffs):
        return None
    first = abs(coeffs[0])
    if first == 1 or any(abs(c) != first for c in coeffs[1:]):
        return None
    return first


def _factors(term: sp.Expr) -> list[sp.Expr]:
    """The non-numeric factors of a product (a power x**n contributes x)."""
    fs = term.args if term.is_Mul else (term,)
    out = []
    for f in fs:
        if f.is_Number:
            continue
        if f.is_Pow and f.exp.is_Integer and f.exp > 0:
            out.append(f.base)
        else:
            out.append(f)
    return out


def _divide_out(term: sp.Expr, factor: sp.Expr) -> sp.Expr:
    fs = list(term.args) if term.is_Mul else [term]
    for i, f in enumerate(fs):
        if f == factor:
            del fs[i]
            return sp.Mul(*fs)
        if f.is_Pow and f.base == factor and f.exp.is_Integer and f.exp > 0:
            fs[i] = factor ** (f.exp - 1)
            return sp.Mul(*fs)
    raise AssertionError("factor not found")


def _transform_columns(kernel: Kernel) -> list[tuple[int, int]]:
    """(output index, flat offset) of each 4x4 homogeneous-transform output."""
    found = []
    offset = 0
    for i, arg in enumerate(kernel.outputs):
        v = arg.value
        if v.shape == (4, 4) and list(v[3, :]) == [0, 0, 0, 1]:
            found.append((i, offset))
        offset += v.shape[0] * v.shape[1]
    return found


def lower(kernel: Kernel, factor: str = "count", cross: dict[int, int] | None = None,
          collapse: bool = False, cse_opt: bool = True, expand: bool = True, staged: bool = False) -> Program:
    """Lower a kernel to assignments.

    ``factor``: "" (none), "count" (most shared factor first), "base" / "tip" (trig of the
    joint nearest the base / the tool first). ``cross`` maps a transform output to the
    column (0 n, 1 o, 2 a) rebuilt by a cross product. ``collapse`` rewrites sums of
    products of sines and cosines into sines and cosines of sums (C2 C3 - S2 S3 -> C23).
    """
    in_names, sym_names = _input_symbols(kernel)
    out_names, exprs = _outputs(kernel)
    n_stage = 0
    if staged:
        # the kernel's structure hint: stage definitions first, then the main outputs in
        # terms of the stage symbols (guards unchanged)
        main = [e for m in kernel.staged for e in arg_elements(m)]
        exprs = [v for _, v in kernel.stages] + main + exprs[len(main):]
        n_stage = len(kernel.stages)
    exprs = _numeric(kernel, exprs)
    exprs = _integral_floats(exprs)
    if collapse:
        exprs = [_collapse(e) for e in exprs]
    flat_names = [n for row in out_names for n in row]
    cross = cross or {}
    # entries rebuilt from other outputs are left out of the CSE
    rebuilt: dict[int, sp.Expr] = {}
    for (oi, off) in _transform_columns(kernel):
        col = cross.get(oi)
        if col is None:
            continue
        a, b = (col + 1) % 3, (col + 2) % 3  # n = o x a, o = a x n, a = n x o
        u = [sp.Symbol(f"__{flat_names[off + 4 * r + a]}") for r in range(3)]
        w = [sp.Symbol(f"__{flat_names[off + 4 * r + b]}") for r in range(3)]
        cr = [u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]]
        for r in range(3):
            rebuilt[off + 4 * r + col] = cr[r]
    exprs, trig = _extract_trig(exprs)
    stage_exprs, exprs = exprs[:n_stage], exprs[n_stage:]
    keep = [k for k in range(len(exprs)) if k not in rebuilt]
    work = [exprs[k] for k in keep]
    if factor:
        rank = None
        if factor in ("base", "tip"):
            syms = [s for s, _ in trig if s.name[0] in "sc"]
            order = syms if factor == "base" else syms[::-1]
            rank = {s: i for i, s in enumerate(order)}
        memo: dict[sp.Expr, sp.Expr] = {}
        work = [_factor_sum(sp.expand(e) if expand and _is_poly_like(e) else e, rank, memo) for e in work]
        stage_exprs = [_factor_sum(sp.expand(e) if expand and _is_poly_like(e) else e, rank, memo)
                       for e in stage_exprs]
    # expanding and factoring multiply constants together (1/d4 * a2 = 1.0 for the PUMA)
    stage_exprs, work = _split(_integral_floats(stage_exprs + work), len(stage_exprs))
    # SymPy's "basic" CSE preprocessing (factor_terms) walks the expression *tree*: fine for
    # small kernels, hours for inverse kinematics whose DAG of 150 nodes is a tree of 10^5.
    # Stage definitions and main outputs share one CSE; a stage may use earlier stages.
    temps, reduced = sp.cse(stage_exprs + work, symbols=sp.numbered_symbols("t"),
                            optimizations="basic" if cse_opt else None)
    stage_defs = [(sym, r) for (sym, _), r in zip(kernel.stages, reduced[:n_stage])] if n_stage else []
    reduced = reduced[n_stage:]
    temps = _in_dependency_order(list(temps) + stage_defs)
    outputs: list[tuple[str, sp.Expr]] = [(flat_names[k], reduced[i]) for i, k in enumerate(keep)]
    for k in sorted(rebuilt):
        outputs.append((flat_names[k], rebuilt[k]))
    temps = _live(temps, [v for _, v in outputs])
    variant = (f"{'expand+' if expand else ''}horner[{factor}]+cse" if factor else "cse")
    variant += ", trig sums collapsed" if collapse else ""
    variant += ", staged (the kernel's structure hint)" if staged else ""
    variant += "".join(f", {'noa'[c]}=cross" for c in cross.values())
    return Program(kernel, in_names, out_names, trig, list(temps), outputs, sym_names, variant)


def _in_dependency_order(defs: list[tuple[sp.Symbol, sp.Expr]]) -> list[tuple[sp.Symbol, sp.Expr]]:
    """Order assignments so each comes after the ones it uses (stable otherwise)."""
    defined = {s for s, _ in defs}
    deps = {s: v.free_symbols & defined for s, v in defs}
    done: set[sp.Symbol] = set()
    out: list[tuple[sp.Symbol, sp.Expr]] = []
    pending = list(defs)
    while pending:
        i = next((i for i, (s, _) in enumerate(pending) if deps[s] <= done), None)
        if i is None:
            raise ValueError(f"circular definitions among {[str(s) for s, _ in pending]}")
        s, v = pending.pop(i)
        out.append((s, v))
        done.add(s)
    return out


def _live(defs: list[tuple[sp.Symbol, sp.Expr]], used: list[sp.Expr]) -> list[tuple[sp.Symbol, sp.Expr]]:
    """Drop assignments no output needs (a stage may define more than the outputs use)."""
    need: set[sp.Symbol] = set()
    for e in used:
        need |= e.free_symbols
    keep = []
    for s, v in reversed(defs):
        if s in need:
            keep.append((s, v))
            need |= v.free_symbols
    return keep[::-1]


def _collapse(e: sp.Expr) -> sp.Expr:
    """C_i C_j - S_i S_j -> C_ij and friends (SymPy's TR10i), on the expanded sum."""
    from sympy.simplify.fu import TR10i
    return TR10i(sp.expand(e)) if _is_poly_like_trig(e) else TR10i(e)


def _is_poly_like_trig(e: sp.Expr) -> bool:
    return all(isinstance(a, (sp.sin, sp.cos)) for a in sp.preorder_traversal(e) if isinstance(a, sp.Function)) and \
        not any(p.is_Pow and not (p.exp.is_Integer and p.exp > 0) for p in sp.preorder_traversal(e))


def _is_poly_like(e: sp.Expr) -> bool:
    """True when expanding is safe (no division or functions left to blow up)."""
    return not any(isinstance(a, sp.Function) for a in sp.preorder_traversal(e)) and not any(
        p.is_Pow and not (p.exp.is_Integer and p.exp > 0) for p in sp.preorder_traversal(e))


# ---------------------------------------------------------------- printing

def _num(x: sp.Expr) -> str:
    v = float(x)
    if v.is_integer() and abs(v) < 1e15:
        return f"{v:.1f}"
    return repr(v)


class CPrinter:
    """Prints SymPy expressions as C without pow() and with signs folded into subtractions."""

    def __init__(self, names: dict[sp.Symbol, str]):
        self.names = names

    def expr(self, e: sp.Expr) -> str:
        s, neg = self._signed(e)
        return f"-{self._wrap(s, e)}" if neg else s

    def _wrap(self, s: str, e: sp.Expr) -> str:
        return f"({s})" if (e.is_Add) else s

    def _signed(self, e: sp.Expr) -> tuple[str, bool]:
        """Text of |e| and whether e is negated, so callers can fold the sign."""
        if e.is_Number:
            return _num(abs(e)), bool(e < 0)
        if e.is_Symbol:
            return self.names.get(e, e.name), False
        if e.is_Mul:
            coeff, rest = e.as_coeff_Mul()
            neg = coeff < 0
            coeff = abs(coeff)
            if neg:
                flipped = _absorb_sign(rest)
                if flipped is not None:
                    return self._product(coeff, flipped), False
            return self._product(coeff, rest), bool(neg)
        if e.is_Add:
            return self._sum(e), False
        if e.is_Pow:
            return self._pow(e), False
        if e.func in C_FUNCS:
            return f"{C_FUNCS[e.func]}({', '.join(self.expr(a) for a in e.args)})", False
        if e.func is sp.Max:
            return self._fold("fmax", e.args), False
        if e.func is sp.Min:
            return self._fold("fmin", e.args), False
        raise ValueError(f"C printer: unsupported expression {e!r}")

    def _fold(self, fn: str, args) -> str:
        out = self.expr(args[0])
        for a in args[1:]:
            out = f"{fn}({out}, {self.expr(a)})"
        return out

    def _sum(self, e: sp.Expr) -> str:
        pos, neg = [], []
        for a in sorted(e.args, key=sp.default_sort_key):
            s, n = self._signed(a)
            (neg if n else pos).append(s)
        head = " + ".join(pos) if pos else f"-{neg.pop(0)}"
        return head + "".join(f" - {s}" for s in neg)

    def _factor_text(self, f: sp.Expr) -> str:
        s = self.expr(f)
        return f"({s})" if (f.is_Add or (f.is_Mul and s.startswith("-")) or s.startswith("-")) else s

    def _product(self, coeff: sp.Expr, rest: sp.Expr) -> str:
        num, den = [], []
        for f in (rest.args if rest.is_Mul else (rest,)):
            if f.is_Pow and f.exp.is_Number and f.exp < 0:
                den.append(sp.Pow(f.base, -f.exp))
            else:
                num.append(f)
        if coeff.is_Rational and coeff.q != 1 and not den:
            # a/q: one division is as cheap as multiplying by 1/q, keep exact text
            pass
        parts = [] if coeff == 1 else [_num(coeff)]
        parts += [self._factor_text(f) for f in num]
        text = "*".join(parts) if parts else "1.0"
        if den:
            d = "*".join(self._factor_text(f) for f in den)
            text = f"{text}/" + (f"({d})" if len(den) > 1 else d)
        return text

    def _pow(self, e: sp.Pow) -> str:
        b, x = e.base, e.exp
        bt = self._factor_text(b)
        if x.is_Integer and x > 0:
            return "*".join([bt] * int(x))
        if x.is_Integer and x < 0:
            return "1.0/" + ("(" + "*".join([bt] * int(-x)) + ")" if -x > 1 else bt)
        if x == sp.Rational(1, 2):
            return f"sqrt({self.expr(b)})"
        if x == sp.Rational(-1, 2):
            return f"1.0/sqrt({self.expr(b)})"
        if x == sp.Rational(3, 2):
            return f"{bt}*sqrt({self.expr(b)})"
        raise ValueError(f"C printer: power {e} has no pow()-free form")


def _absorb_sign(rest: sp.Expr) -> sp.Expr | None:
    """-rest with the sign moved into one of its sum factors: -(a - b)*c as (b - a)*c,
    saving the negation; None when no sum factor can take it without a leading minus."""
    fs = list(rest.args) if rest.is_Mul else [rest]
    for i, f in enumerate(fs):
        base, exp = f.as_base_exp()
        if not (base.is_Add and exp.is_Integer and abs(exp) == 1):
            continue
        neg = sp.Add(*[-a for a in base.args])
        if not neg.is_Add or all(a.as_coeff_Mul()[0] < 0 for a in neg.args):
            continue
        fs[i] = neg if exp == 1 else sp.Pow(neg, -1, evaluate=False)
        return sp.Mul(*fs, evaluate=False)
    return None


def kernel_body(prog: Program) -> str:
    """The C statements of one row of a kernel (between the BEGIN/END markers)."""
    names = dict(prog.symbol_names)
    for s, _ in prog.trig:
        names[s] = s.name
    for s, _ in prog.temps:
        names[s] = s.name
    for name, _ in prog.outputs:
        names[sp.Symbol(f"__{name}")] = name
    pr = CPrinter(names)
    lines = [f"    const double {s.name} = {pr.expr(f)};" for s, f in prog.trig]
    lines += [f"    const double {s.name} = {pr.expr(v)};" for s, v in prog.temps]
    n_main = len(prog.kernel.outputs)
    guard_names = {n for row in prog.out_names[n_main:] for n in row}
    lines += [f"    {name} = {pr.expr(v)};" for name, v in prog.outputs if name not in guard_names]
    if guard_names:
        lines.append("    /* guards: >= 0 where the outputs are valid */")
        lines += [f"    {name} = {pr.expr(v)};" for name, v in prog.outputs if name in guard_names]
    return "\n".join(lines)


def tree_size(exprs: list[sp.Expr]) -> int:
    """Number of nodes of the expressions written out as trees (what naive walks visit)."""
    memo: dict[sp.Expr, int] = {}

    def size(e: sp.Expr) -> int:
        if e not in memo:
            memo[e] = 1 + sum(size(a) for a in e.args)
        return memo[e]

    return sum(size(e) for e in exprs)


def dag_size(exprs: list[sp.Expr]) -> int:
    """Number of distinct subexpressions (tree size would count shared subtrees repeatedly)."""
    seen: set[sp.Expr] = set()
    stack = list(exprs)
    while stack:
        e = stack.pop()
        if e in seen:
            continue
        seen.add(e)
        stack.extend(e.args)
    return len(seen)


#: above this many distinct subexpressions, or this many tree nodes, only plain CSE is
#: tried (the rewrites that expand or factor sums cost too much on large kernels)
LARGE_KERNEL = 1500
LARGE_TREE = 20000


def best_program(kernel: Kernel) -> tuple[Program, str]:
    """Try the lowering variants and keep the one with fewest counted operations."""
    cols = [oi for oi, _ in _transform_columns(kernel)]
    cross_choices: list[dict[int, int]] = [{}]
    if len(cols) == 1:
        cross_choices += [{cols[0]: c} for c in range(3)]
    _, exprs = _outputs(kernel)
    large = dag_size(exprs) > LARGE_KERNEL or tree_size(exprs) > LARGE_TREE
    collapses = (False,) if large else (False, True)
    factors = ("",) if large else ("", "count", "base", "tip")
    stagings = (False, True) if kernel.stages else (False,)
    best_per_cross: list[tuple[tuple[int, int, int], Program]] = []
    for cross in cross_choices:
        best = None
        for collapse, factor, expand, staged in itertools.product(collapses, factors, (True, False), stagings):
            if expand and not factor:
                continue
            try:
                prog = lower(kernel, factor=factor, cross=cross, collapse=collapse, cse_opt=not large,
                             expand=expand, staged=staged)
                body = kernel_body(prog)
            except ValueError:
                if factor:
                    continue
                raise
            c = opcount.count_ops(body)
            key = (c["mul_div"] + c["add_sub"], c["trig"], c["mul_div"])
            if best is None or key < best[0]:
                best = (key, prog)
        assert best is not None
        prog = _flip_signs(best[1])
        c = opcount.count_ops(kernel_body(prog))
        best_per_cross.append(((c["mul_div"] + c["add_sub"], c["trig"], c["mul_div"]), prog))
    key, prog = min(best_per_cross, key=lambda kp: kp[0])
    if len(best_per_cross) > 1:  # say what the other choices of 3.3's rebuilt column cost
        tried = []
        for cross, (_, p) in zip(cross_choices, best_per_cross):
            c = opcount.count_ops(kernel_body(p))
            label = f"{'noa'[next(iter(cross.values()))]} rebuilt" if cross else "none rebuilt"
            tried.append(f"{label} {c['mul_div']}/{c['add_sub']}")
        prog = replace(prog, variant=prog.variant + "; columns tried (mul/add): " + ", ".join(tried))
    return prog, kernel_body(prog)


def _flip_signs(prog: Program) -> Program:
    """Store -t instead of t for temps where that removes unary minus signs (greedy)."""
    def cost(p: Program) -> tuple[int, int]:
        c = opcount.count_ops(kernel_body(p))
        return c["add_sub"] + c["mul_div"], c["neg"]

    current = cost(prog)
    for i, (sym, _) in enumerate(list(prog.temps)):
        neg = sp.Symbol(sym.name + "_n")
        sub = {sym: -neg}
        temps = [(s, v.xreplace(sub)) for s, v in prog.temps]
        temps[i] = (neg, -prog.temps[i][1])
        trial = Program(prog.kernel, prog.in_names, prog.out_names, prog.trig, temps,
                        [(n, v.xreplace(sub)) for n, v in prog.outputs], prog.symbol_names, prog.variant)
        c = cost(trial)
        if c < current:
            prog, current = trial, c
    return prog


# ---------------------------------------------------------------- module text

def _c_string(s: str) -> str:
    return json.dumps(s)


#: rows per block of the batched loops whose sines and cosines are computed a block at a time
TRIG_BLOCK = 64


def _vector_trig(prog: Program) -> tuple[list[str], list[tuple[str, str, int]], str, int] | None:
    """The kernel split for batches: (argument statements, [(local, sin|cos, argument index)],
    row body reading the trig values from ``tv[t * ts]``, number of arguments); None when a sine or cosine takes
    an argument that is not a sum of inputs (then the plain row loop is used)."""
    trig_funcs = [(sym, f) for sym, f in prog.trig if isinstance(f, (sp.sin, sp.cos))]
    if not trig_funcs:
        return None
    inputs = set(prog.symbol_names)
    xsyms = {sym for sym, f in prog.trig if not isinstance(f, (sp.sin, sp.cos))}
    for _, f in trig_funcs:
        a = f.args[0]
        if a.atoms(sp.Function) or not a.free_symbols <= inputs | xsyms:
            return None
    names = dict(prog.symbol_names)
    for sym, _ in prog.trig:
        names[sym] = sym.name
    pr = CPrinter(names)
    args: list[str] = []
    arg_index: dict[str, int] = {}
    stmts = [f"const double {sym.name} = {pr.expr(f)};" for sym, f in prog.trig if sym in xsyms]
    table = []
    for sym, f in trig_funcs:
        text = pr.expr(f.args[0])
        if text not in arg_index:
            arg_index[text] = len(args)
            args.append(text)
        table.append((sym.name, "sin" if isinstance(f, sp.sin) else "cos", arg_index[text]))
    stmts += [f"ta[{i}][r] = {a};" for i, a in enumerate(args)]
    lines = kernel_body(prog).splitlines()
    local = {name: t for t, (name, _, _) in enumerate(table)}
    row = []
    for line in lines:
        head = line.strip().split(" = ")[0].replace("const double ", "")
        if head in local:
            row.append(f"    const double {head} = tv[{local[head]} * ts];")
        else:
            row.append(line)
    return stmts, table, "\n".join(row), len(args)


def _slot(slot: dict[tuple[int, str], int], arg: int, fn: str) -> str:
    """The block row of tv that receives ``fn`` of argument ``arg``, or NULL: not needed."""
    t = slot.get((arg, fn))
    return "NULL" if t is None else f"tv[{t}]"


def _batch_vector(prog: Program, split) -> str:
    k = prog.kernel
    stmts, table, row, nargs = split
    nin, nout = len(prog.in_names), len(prog.out_names)
    params = ["const double *restrict tv", "Py_ssize_t ts"]
    params += [f"const double *restrict in{i}" for i in range(nin)]
    params += [f"double *restrict out{i}" for i in range(nout)]
    ins = "; ".join(f"const double *restrict in{i} = inb{i} + (r0 + r) * is[{i}]" for i in range(nin))
    call = ", ".join([f"&tv[0][r], {TRIG_BLOCK}"] + [f"inb{i} + (r0 + r) * is[{i}]" for i in range(nin)]
                     + [f"outb{i} + (r0 + r) * os[{i}]" for i in range(nout)])
    # one reduction per argument gives its sine and cosine together (kin_prelude.h)
    slot = {(a, fn): t for t, (_, fn, a) in enumerate(table)}
    trig = "\n".join(
        f"        vtrig_sincos(ta[{a}], {_slot(slot, a, 'sin')}, {_slot(slot, a, 'cos')}, m);"
        for a in range(nargs))
    one_trig = f"vtrig_sincos(a, sv, cv, {nargs});"
    one_call = ", ".join(["tv", "1"] + [f"in{i}" for i in range(nin)] + [f"(double *)out[{i}]" for i in range(nout)])
    return f"""
#ifdef RCCL_VECTOR_TRIG
/* {k.name} for batches: the row above with its sines and cosines precomputed */
static inline void kv_{k.name}({", ".join(params)})
{{
{row}
}}

/* blocks of {TRIG_BLOCK} rows: arguments, then every sine/cosine over the block (vector
 * lanes, kin_prelude.h), then the straight-line rows */
static int batch_vector_{k.name}(Py_ssize_t n, const double *const *in, const Py_ssize_t *is, double *const *out, const Py_ssize_t *os)
{{
    if (!have_vector_trig) return 0;
    if (n == 1) {{  /* one row: its sines (and cosines) side by side in the vector lanes */
        {'; '.join(f'const double *restrict in{i} = (const double *)in[{i}]' for i in range(nin))};
        double ta[{nargs}][1], sv[{nargs}], cv[{nargs}], tv[{len(table)}];
        const int r = 0;
        {" ".join(stmts)}
        double a[{nargs}];
        for (int i = 0; i < {nargs}; ++i) a[i] = ta[i][0];
        {one_trig}
        {" ".join(f"tv[{t}] = {'sv' if fn == 'sin' else 'cv'}[{a}];" for t, (_, fn, a) in enumerate(table))}
        kv_{k.name}({one_call});
        return 1;
    }}
    {'; '.join(f'const double *inb{i} = (const double *)in[{i}]' for i in range(nin))};
    {'; '.join(f'double *outb{i} = out[{i}]' for i in range(nout))};
    double ta[{nargs}][{TRIG_BLOCK}], tv[{len(table)}][{TRIG_BLOCK}];
    for (Py_ssize_t r0 = 0; r0 < n; r0 += {TRIG_BLOCK}) {{
        const int m = n - r0 < {TRIG_BLOCK} ? (int)(n - r0) : {TRIG_BLOCK};
        for (int r = 0; r < m; ++r) {{
            {ins};
            {" ".join(stmts)}
        }}
{trig}
        for (int r = 0; r < m; ++r)
            kv_{k.name}({call});
    }}
    return 1;
}}
#endif
"""


def kernel_c(prog: Program, body: str) -> str:
    k = prog.kernel
    split = _vector_trig(prog)
    vector = _batch_vector(prog, split) if split else ""
    try_vector = (f"#ifdef RCCL_VECTOR_TRIG\n    if (batch_vector_{k.name}(n, in, is, out, os)) return;\n#endif\n"
                  if split else "")
    nin, nout = len(prog.in_names), len(prog.out_names)
    params = [f"const double *restrict in{i}" for i in range(nin)]
    params += [f"double *restrict out{i}" for i in range(nout)]
    sig = ", ".join(params)
    call = ", ".join([f"in{i} + r * is[{i}]" for i in range(nin)] + [f"out{i} + r * os[{i}]" for i in range(nout)])
    ins = ", ".join(f"(const double *)in[{i}]" for i in range(nin))
    outs = ", ".join(f"(double *)out[{i}]" for i in range(nout))
    return f"""
/* {k.robot}.{k.name}: {k.doc.splitlines()[0] if k.doc else ''} (thesis {k.source or '-'}; lowering: {prog.variant}) */
static inline void k_{k.name}({sig})
{{
/* BEGIN KERNEL {k.robot}.{k.name} */
{body}
/* END KERNEL {k.robot}.{k.name} */
}}
{vector}
static void batch_{k.name}(Py_ssize_t n, const double *const *in, const Py_ssize_t *is, double *const *out, const Py_ssize_t *os)
{{
{try_vector}    {'; '.join(f'const double *in{i} = (const double *)in[{i}]' for i in range(nin))};
    {'; '.join(f'double *out{i} = out[{i}]' for i in range(nout))};
    (void)is; (void)os;
    for (Py_ssize_t r = 0; r < n; ++r)
        k_{k.name}({call});
}}
"""


def finite_by_construction(prog: Program) -> bool:
    """True when every output is a polynomial in sines and cosines of the inputs (and
    constants): then finite inputs give finite outputs of bounded size, and the runtime
    need not scan the results for NaN/inf. An input used outside a sine or cosine (a
    prismatic joint, a force, a coefficient), a division or any other function breaks it."""
    if prog.kernel.guards:
        return False
    bounded = {sym for sym, f in prog.trig if isinstance(f, (sp.sin, sp.cos))}

    def polynomial_in_bounded(expr: sp.Expr) -> bool:
        free = expr.free_symbols
        return free <= bounded and not expr.atoms(sp.Function) and (not free or expr.is_polynomial(*free))

    for sym, expr in prog.temps:  # in dependency order
        if polynomial_in_bounded(expr):
            bounded.add(sym)
    for name, expr in prog.outputs:  # columns rebuilt by a cross product come last, as __<name>
        if not polynomial_in_bounded(expr):
            return False
        bounded.add(sp.Symbol(f"__{name}"))
    return True


def _shape(arg) -> tuple[int, ...]:
    return tuple(arg.shape)


def _shape_c(shape: tuple[int, ...]) -> str:
    dims = list(shape) + [0] * (2 - len(shape))
    return f"{{{len(shape)}, {{{dims[0]}, {dims[1]}}}, {max(1, math.prod(shape))}}}"


def module_c(robot: str, programs: list[tuple[Program, str]], command: str) -> str:
    kernels = "".join(kernel_c(p, b) for p, b in programs)
    table = []
    for p, _ in programs:
        k = p.kernel
        ins = [_shape(a) for a in k.inputs]
        outs = [_shape(a) for a in k.outputs] + [()] * len(k.guards)
        onames = [a.name for a in k.outputs] + [g.name for g in k.guards]
        table.append(
            f"    {{{_c_string(k.name)}, batch_{k.name}, {len(ins)}, {len(outs)}, {len(k.guards)},\n"
            f"     {{{', '.join(_shape_c(s) for s in ins)}}},\n"
            f"     {{{', '.join(_shape_c(s) for s in outs)}}},\n"
            f"     {{{', '.join(_c_string(a.name) for a in k.inputs)}}},\n"
            f"     {{{', '.join(_c_string(n) for n in onames)}}},\n"
            f"     {_c_string(_method_doc(k))}, {int(finite_by_construction(p))}}},")
    maxio = max([len(p.kernel.inputs) for p, _ in programs]
                + [len(p.kernel.outputs) + len(p.kernel.guards) for p, _ in programs] + [1])
    return RUNTIME.format(robot=robot, command=command, kernels=kernels, table="\n".join(table),
                          nk=len(programs), maxio=maxio)


def _method_doc(k: Kernel) -> str:
    ins = ", ".join(f"{a.name}{list(a.shape)}" for a in k.inputs)
    outs = ", ".join([f"{a.name}{list(a.shape)}" for a in k.outputs] + [g.name for g in k.guards])
    first = k.doc.strip().splitlines()[0] if k.doc.strip() else k.name
    return (f"{k.name}({ins}) -> ({outs}): {first} Each input may carry a leading batch axis N; "
            "unbatched inputs are broadcast.")


RUNTIME = r"""/* Kinematics kernels of the {robot}, as a CPython extension module.
 * GENERATED by `{command}` (derive/emit_c.py); do not edit by hand.
 * Each kernel has a row function (straight-line, no allocation, no pow()) and a batched
 * loop over N rows. The hand-written runtime beside this file (kin_prelude.h,
 * kin_runtime.h) gives the Python-callable entries, their checks, the batched rows over
 * threads and the public fast entries.
 */
#define RCCL_ROBOT "{robot}"
#define MAXIO {maxio}
#include "kin_prelude.h"
{kernels}
static const kernel_entry KERNELS[{nk}] = {{
{table}
}};

#include "kin_runtime.h"

RCCL_MODULE_INIT({robot})
"""


#: the lowered programs of the last ``emit`` per robot, reused by the CasADi back end
LAST_PROGRAMS: dict[str, tuple[list[Kernel], list[tuple[Program, str]]]] = {}

COMMAND = "make derive  (python -m derive)"


def emit(kernels: list[Kernel], robot: str, out_dir: Path) -> list[Path]:
    """Back-end entry of ``python -m derive``: ``out_dir/_c/<robot>.c`` and the op-count reports.

    The reports cover every generated C file present, so they are complete after the
    last robot. The extension is compiled by ``pip install`` (setup.py), not here.
    """
    out_dir = Path(out_dir)
    kernels = list(kernels) + all_configurations_kernels(kernels)
    path, programs = write(robot, kernels, out_dir / "_c", COMMAND)
    LAST_PROGRAMS[robot] = (kernels, programs)
    reports = out_dir.parent.parent / "reports"
    c_files = sorted((out_dir / "_c").glob("*.c"))
    opcount.write_reports(c_files, reports / "opcounts.md", reports / "opcounts.json", COMMAND)
    return [path, reports / "opcounts.md", reports / "opcounts.json"]


def all_configurations_kernels(kernels: list[Kernel]) -> list[Kernel]:
    """``ik_all``: the ``ik`` kernel evaluated for every configuration at once.

    Built here (a back-end composition, not new kinematics) by substituting each sign
    combination of the ``config`` input, in ``itertools.product((1, -1), repeat=n)``
    order (the order of the runtime's ``Config.all()``), so common subexpressions are
    shared between configurations. Outputs: ``q`` (n_configs, 6) and ``guards``
    (n_configs, n_guards), a configuration being valid when all its guards are >= 0.
    """
    ik = next((k for k in kernels if k.name == "ik"), None)
    if ik is None or len(ik.inputs) != 2 or ik.inputs[1].name != "config":
        return []
    signs = list(ik.inputs[1].value)
    q = ik.outputs[0].value
    rows, grows = [], []
    for combo in itertools.product((1, -1), repeat=len(signs)):
        sub = dict(zip(signs, combo))
        rows.append(dag_xreplace(list(q), sub))
        grows.append(dag_xreplace([g.expr for g in ik.guards], sub))
    doc = ("every configuration of ik at once (rows in Config.all() order); guards per row, "
           "a row is valid when all its guards are >= 0")
    return [Kernel(ik.robot, "ik_all", doc, (ik.inputs[0],),
                   (Arg("q", sp.Matrix(rows)), Arg("guards", sp.Matrix(grows))), (), dict(ik.params), ik.source)]


def write(robot: str, kernels: list[Kernel], out_dir: Path, command: str = "make derive") -> tuple[Path, list[tuple[Program, str]]]:
    """Write ``out_dir/<robot>.c``; return its path and the chosen (program, body) per kernel."""
    programs = [best_program(k) for k in kernels]
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / f"{robot}.c"
    text = module_c(robot, programs, command)
    if not path.exists() or path.read_text() != text:
        path.write_text(text)
    return path, programs
