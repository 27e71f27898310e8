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
from dataclasses import dataclass
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
    best = None
    stagings = (False, True) if kernel.stages else (False,)
    for collapse, factor, expand, cross, staged in itertools.product(collapses, factors, (True, False),
                                                                     cross_choices, stagings):
        if expand and not factor:
            continue
        try:
            prog = lower(kernel, factor=factor, cross=cross, collapse=collapse, cse_opt=not large, expand=expand,
                         staged=staged)
            body = kernel_body(prog)
        except ValueError:
            if factor:
                continue
            raise
        c = opcount.count_ops(body)
        key = (c["mul_div"] + c["add_sub"], c["trig"], c["mul_div"])
        if best is None or key < best[0]:
            best = (key, prog, body)
    assert best is not None
    prog = _flip_signs(best[1])
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
    trig = "\n".join(f"            vtrig_{fn}(ta[{a}], tv[{t}], m);" for t, (_, fn, a) in enumerate(table))
    fns = sorted({fn for _, fn, _ in table})
    one_trig = " ".join(f"vtrig_{fn}(a, {fn[0]}v, {nargs});" for fn in fns)
    one_call = ", ".join(["tv", "1"] + [f"in{i}" for i in range(nin)] + [f"(double *)out[{i}]" for i in range(nout)])
    return f"""
#ifdef RCCL_VECTOR_TRIG
/* {k.name} for batches: the row above with its sines and cosines precomputed */
static inline void kv_{k.name}({", ".join(params)})
{{
{row}
}}

/* blocks of {TRIG_BLOCK} rows: arguments, then every sine/cosine over the block (libmvec),
 * then the straight-line rows */
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


def _shape(arg) -> tuple[int, ...]:
    return tuple(arg.shape)


def _shape_c(shape: tuple[int, ...]) -> str:
    dims = list(shape) + [0] * (2 - len(shape))
    return f"{{{len(shape)}, {{{dims[0]}, {dims[1]}}}, {max(1, math.prod(shape))}}}"


def module_c(robot: str, programs: list[tuple[Program, str]], command: str) -> str:
    kernels = "".join(kernel_c(p, b) for p, b in programs)
    table, methods, pubdefs = [], [], []
    for i, (p, _) in enumerate(programs):
        k = p.kernel
        ins = [_shape(a) for a in k.inputs]
        outs = [_shape(a) for a in k.outputs] + [()] * len(k.guards)
        onames = [a.name for a in k.outputs] + [g.name for g in k.guards]
        table.append(
            f"    {{{_c_string(k.name)}, batch_{k.name}, {len(ins)}, {len(outs)}, {len(k.guards)},\n"
            f"     {{{', '.join(_shape_c(s) for s in ins)}}},\n"
            f"     {{{', '.join(_shape_c(s) for s in outs)}}},\n"
            f"     {{{', '.join(_c_string(a.name) for a in k.inputs)}}},\n"
            f"     {{{', '.join(_c_string(n) for n in onames)}}}}},")
        methods.append(
            f"static PyObject *py_{k.name}(PyObject *self, PyObject *const *args, Py_ssize_t nargs)\n"
            f"{{ (void)self; return call_kernel(&KERNELS[{i}], args, nargs); }}\n"
            f"#ifdef RCCL_NUMPY_API\n"
            f"static PyObject *pub_{k.name}(PyObject *self, PyObject *const *args, Py_ssize_t nargs, PyObject *kwnames)\n"
            f"{{ return public_call(&KERNELS[{i}], self, args, nargs, kwnames); }}\n"
            f"#endif\n")
        pubdefs.append(
            f"    {{{_c_string(k.name)}, (PyCFunction)(void (*)(void))pub_{k.name}, METH_FASTCALL | METH_KEYWORDS, "
            f"{_c_string(_method_doc(k))}}},")
    defs = "\n".join(
        f"    {{{_c_string(p.kernel.name)}, (PyCFunction)(void (*)(void))py_{p.kernel.name}, METH_FASTCALL, "
        f"{_c_string(_method_doc(p.kernel))}}}," for p, _ in programs)
    maxio = max([len(p.kernel.inputs) for p, _ in programs]
                + [len(p.kernel.outputs) + len(p.kernel.guards) for p, _ in programs] + [1])
    return RUNTIME.format(
        robot=robot, command=command, kernels=kernels, table="\n".join(table), nk=len(programs), maxio=maxio,
        methods="\n".join(methods), defs=defs, pubdefs="\n".join(pubdefs), fast=FAST_C)


def _method_doc(k: Kernel) -> str:
    ins = ", ".join(f"{a.name}{list(a.shape)}" for a in k.inputs)
    outs = ", ".join([f"{a.name}{list(a.shape)}" for a in k.outputs] + [g.name for g in k.guards])
    first = k.doc.strip().splitlines()[0] if k.doc.strip() else k.name
    return (f"{k.name}({ins}) -> ({outs}): {first} Each input may carry a leading batch axis N; "
            "unbatched inputs are broadcast.")


RUNTIME = r"""/* Kinematics kernels of the {robot}, as a CPython extension module.
 * GENERATED by `{command}` (derive/emit_c.py); do not edit by hand.
 * Plain C API and the buffer protocol (numpy is used only to allocate the results):
 * each kernel has a row function (straight-line, no allocation, no pow()) and a
 * batched loop over N rows in C; the Python-callable entry checks shapes, scans the
 * inputs for NaN/inf, allocates the outputs and runs the loop.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#ifdef RCCL_NUMPY_API
/* numpy's C API, when setup.py found numpy's headers: the public fast path below */
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#include <numpy/arrayobject.h>
#endif

#if defined(RCCL_LIBMVEC) && defined(__x86_64__) && defined(__GNUC__)
/* glibc's vector math library (libmvec): sin/cos of 4 doubles at once with AVX2, within
 * 4 ulp; used for batches when the CPU has AVX2 (checked at import), else plain libm. */
#define RCCL_VECTOR_TRIG 1
#include <immintrin.h>
__m256d _ZGVdN4v_sin(__m256d);
__m256d _ZGVdN4v_cos(__m256d);
static int have_vector_trig = 0;

#define VTRIG(fn) \
__attribute__((target("avx2,fma"))) static void vtrig_##fn(const double *x, double *y, int m) \
{{ \
    int i = 0; \
    for (; i + 4 <= m; i += 4) _mm256_storeu_pd(y + i, _ZGVdN4v_##fn(_mm256_loadu_pd(x + i))); \
    if (i < m) {{ /* the tail, padded into one vector */ \
        double xt[4] = {{0, 0, 0, 0}}, yt[4]; \
        for (int j = 0; i + j < m; ++j) xt[j] = x[i + j]; \
        _mm256_storeu_pd(yt, _ZGVdN4v_##fn(_mm256_loadu_pd(xt))); \
        for (int j = 0; i + j < m; ++j) y[i + j] = yt[j]; \
    }} \
}}
VTRIG(sin)
VTRIG(cos)
#endif

#define MAXIO {maxio}
#define RCCL_SOURCE_HASH "@HASH@"
{kernels}
typedef void (*batch_fn)(Py_ssize_t, const double *const *, const Py_ssize_t *, double *const *, const Py_ssize_t *);

typedef struct {{ int ndim; Py_ssize_t dim[2]; Py_ssize_t size; }} arg_shape;

typedef struct {{
    const char *name;
    batch_fn fn;
    int nin, nout, nguard;      /* nout counts the outputs and then the nguard guards */
    arg_shape in[MAXIO];
    arg_shape out[MAXIO];
    const char *in_name[MAXIO];
    const char *out_name[MAXIO];
}} kernel_entry;

static const kernel_entry KERNELS[{nk}] = {{
{table}
}};

static PyObject *np_empty = NULL;         /* numpy.empty, to allocate results */
static PyObject *np_array = NULL;         /* numpy.array, to convert lists and other dtypes */
static PyObject *np_array_kw = NULL;      /* {{"dtype": "float64", "order": "C"}} */
{fast}

/* Shape tuple of one unbatched output (new reference); small shapes are cached so the
 * common single call builds no tuple. */
static PyObject *single_shape(const arg_shape *s)
{{
    static PyObject *cache0 = NULL, *cache1[64] = {{NULL}}, *cache2[16][16] = {{{{NULL}}}};
    PyObject **slot = NULL;
    if (s->ndim == 0) slot = &cache0;
    else if (s->ndim == 1 && s->dim[0] < 64) slot = &cache1[s->dim[0]];
    else if (s->ndim == 2 && s->dim[0] < 16 && s->dim[1] < 16) slot = &cache2[s->dim[0]][s->dim[1]];
    if (slot && *slot) {{ Py_INCREF(*slot); return *slot; }}
    PyObject *t = s->ndim == 0 ? PyTuple_New(0) : s->ndim == 1 ? Py_BuildValue("(n)", s->dim[0])
                : Py_BuildValue("(nn)", s->dim[0], s->dim[1]);
    if (slot && t) {{ Py_INCREF(t); *slot = t; }}  /* the cache keeps one reference for the process */
    return t;
}}

static PyObject *shape_text(const arg_shape *s)
{{
    if (s->ndim == 0) return PyUnicode_FromString("() or (N,)");
    if (s->ndim == 1) return PyUnicode_FromFormat("(%zd,) or (N, %zd)", s->dim[0], s->dim[0]);
    return PyUnicode_FromFormat("(%zd, %zd) or (N, %zd, %zd)", s->dim[0], s->dim[1], s->dim[0], s->dim[1]);
}}

/* Get a float64 C-contiguous view of x; convert through numpy when x is not one already. */
static int get_input(PyObject *x, Py_buffer *view, PyObject **owner)
{{
    *owner = NULL;
    if (PyObject_GetBuffer(x, view, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) == 0) {{
        if (view->itemsize == 8 && view->format && strcmp(view->format, "d") == 0) return 0;
        PyBuffer_Release(view);
    }} else {{
        PyErr_Clear();
    }}
    PyObject *conv_args = PyTuple_Pack(1, x);
    if (!conv_args) return -1;
    PyObject *conv = PyObject_Call(np_array, conv_args, np_array_kw);
    Py_DECREF(conv_args);
    if (!conv) return -1;
    if (PyObject_GetBuffer(conv, view, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0) {{ Py_DECREF(conv); return -1; }}
    *owner = conv;
    return 0;
}}

static PyObject *call_kernel(const kernel_entry *k, PyObject *const *args, Py_ssize_t nargs)
{{
    if (nargs != k->nin) {{
        PyErr_Format(PyExc_TypeError, "{robot}.%s takes %d inputs, got %zd", k->name, k->nin, nargs);
        return NULL;
    }}
    Py_buffer iv[MAXIO];
    PyObject *owners[MAXIO];
    const double *ip[MAXIO];
    double *op[MAXIO];
    Py_ssize_t is[MAXIO], os[MAXIO];
    PyObject *outs[MAXIO] = {{NULL}};
    PyObject *result = NULL;
    Py_ssize_t n = -1;
    int ni = 0;
    for (; ni < k->nin; ++ni) {{
        if (get_input(args[ni], &iv[ni], &owners[ni]) < 0) goto done;
        const arg_shape *s = &k->in[ni];
        int nd = iv[ni].ndim;
        int batched = (nd == s->ndim + 1);
        int ok = (nd == s->ndim || batched);
        for (int d = 0; ok && d < s->ndim; ++d) ok = iv[ni].shape[d + batched] == s->dim[d];
        if (ok && batched) {{
            if (n >= 0 && iv[ni].shape[0] != n) {{
                PyErr_Format(PyExc_ValueError, "{robot}.%s: input '%s' has %zd rows, an earlier input has %zd",
                             k->name, k->in_name[ni], iv[ni].shape[0], n);
                ++ni; goto done;
            }}
            n = iv[ni].shape[0];
        }}
        if (!ok) {{
            PyObject *need = shape_text(s);
            PyObject *got = PyTuple_New(nd);
            for (int d = 0; got && d < nd; ++d) PyTuple_SET_ITEM(got, d, PyLong_FromSsize_t(iv[ni].shape[d]));
            PyErr_Format(PyExc_ValueError, "{robot}.%s: input '%s' has shape %R, need %U",
                         k->name, k->in_name[ni], got, need);
            Py_XDECREF(need); Py_XDECREF(got);
            ++ni; goto done;
        }}
        ip[ni] = (const double *)iv[ni].buf;
        is[ni] = batched ? s->size : 0;
        Py_ssize_t len = iv[ni].len / 8;
        for (Py_ssize_t j = 0; j < len; ++j) {{
            if (!isfinite(ip[ni][j])) {{
                if (batched)
                    PyErr_Format(PyExc_ValueError, "{robot}.%s: input '%s' row %zd element %zd is %s",
                                 k->name, k->in_name[ni], j / s->size, j % s->size,
                                 isnan(ip[ni][j]) ? "NaN" : "infinite");
                else
                    PyErr_Format(PyExc_ValueError, "{robot}.%s: input '%s' element %zd is %s",
                                 k->name, k->in_name[ni], j, isnan(ip[ni][j]) ? "NaN" : "infinite");
                ++ni; goto done;
            }}
        }}
    }}
    Py_ssize_t rows = n < 0 ? 1 : n;
    for (int o = 0; o < k->nout; ++o) {{
        const arg_shape *s = &k->out[o];
        PyObject *shape;
        if (n < 0) {{
            shape = single_shape(s);
            if (!shape) goto done;
            outs[o] = PyObject_Vectorcall(np_empty, &shape, 1, NULL);
            Py_DECREF(shape);
        }} else {{
            shape = PyTuple_New(1 + s->ndim);
            if (!shape) goto done;
            PyTuple_SET_ITEM(shape, 0, PyLong_FromSsize_t(n));
            for (int d = 0; d < s->ndim; ++d) PyTuple_SET_ITEM(shape, d + 1, PyLong_FromSsize_t(s->dim[d]));
            outs[o] = PyObject_Vectorcall(np_empty, &shape, 1, NULL);
            Py_DECREF(shape);
        }}
        if (!outs[o]) goto done;
        Py_buffer ov;
        if (PyObject_GetBuffer(outs[o], &ov, PyBUF_C_CONTIGUOUS | PyBUF_WRITABLE) < 0) goto done;
        op[o] = (double *)ov.buf;   /* the array keeps the memory alive */
        PyBuffer_Release(&ov);
        os[o] = s->size;
    }}
    if (rows > 4096) {{
        Py_BEGIN_ALLOW_THREADS
        run_rows(k, rows, ip, is, op, os, 0);
        Py_END_ALLOW_THREADS
    }} else {{
        k->fn(rows, ip, is, op, os);
    }}
    result = PyTuple_New(k->nout);
    if (!result) goto done;
    for (int o = 0; o < k->nout; ++o) {{
        if (n < 0 && k->out[o].ndim == 0) {{
            PyTuple_SET_ITEM(result, o, PyFloat_FromDouble(op[o][0]));
            Py_CLEAR(outs[o]);
        }} else {{
            PyTuple_SET_ITEM(result, o, outs[o]);
            outs[o] = NULL;
        }}
    }}
done:
    for (int i = 0; i < ni; ++i) {{ PyBuffer_Release(&iv[i]); Py_XDECREF(owners[i]); }}
    for (int o = 0; o < k->nout; ++o) Py_XDECREF(outs[o]);
    return result;
}}


{methods}
#ifdef RCCL_NUMPY_API
static PyMethodDef PUBLIC_DEFS[] = {{
{pubdefs}
}};

/* public(name, fallback, keys=None): the fast public entry of a single-output kernel
 * (keys: names of the coefficients its last input may also be given by, as a mapping), or
 * of "ik", "ik_all", "config_of" (after ik_setup), falling back to `fallback`. */
static PyObject *public(PyObject *self, PyObject *args)
{{
    const char *name;
    PyObject *fallback, *keys = Py_None;
    if (!PyArg_ParseTuple(args, "sO|O:public", &name, &fallback, &keys)) return NULL;
    if (!PyCallable_Check(fallback)) {{ PyErr_SetString(PyExc_TypeError, "public: fallback must be callable"); return NULL; }}
    if (keys != Py_None && !PyTuple_Check(keys)) {{ PyErr_SetString(PyExc_TypeError, "public: keys must be a tuple"); return NULL; }}
    for (int i = 0; i < (int)(sizeof IK_DEFS / sizeof IK_DEFS[0]); ++i)
        if (strcmp(IK_DEFS[i].ml_name, name) == 0) {{
            if (!IK.ready) {{ PyErr_SetString(PyExc_RuntimeError, "public: call ik_setup first"); return NULL; }}
            return PyCFunction_NewEx(&IK_DEFS[i], fallback, NULL);
        }}
    for (int i = 0; i < {nk}; ++i)
        if (strcmp(KERNELS[i].name, name) == 0) {{
            if (KERNELS[i].nout - KERNELS[i].nguard != 1) break;
            if (keys != Py_None) {{
                for (Py_ssize_t j = 0; j < PyTuple_GET_SIZE(keys); ++j) PyUnicode_InternInPlace(&PyTuple_GET_ITEM(keys, j));
            }}
            PyObject *data = PyTuple_Pack(2, fallback, keys);
            if (!data) return NULL;
            PyObject *fn = PyCFunction_NewEx(&PUBLIC_DEFS[i], data, NULL);
            Py_DECREF(data);
            return fn;
        }}
    PyErr_Format(PyExc_KeyError, "{robot}: no single-output kernel %s", name);
    return NULL;
}}
#endif

static PyObject *arg_shape_tuple(const arg_shape *s)
{{
    return s->ndim == 0 ? PyTuple_New(0) : s->ndim == 1 ? Py_BuildValue("(n)", s->dim[0])
                        : Py_BuildValue("(nn)", s->dim[0], s->dim[1]);
}}

/* kernels(): {{name: (input shapes, output shapes)}}, for the loader to check it matches. */
static PyObject *kernels(PyObject *self, PyObject *noargs)
{{
    (void)self; (void)noargs;
    PyObject *d = PyDict_New();
    if (!d) return NULL;
    for (int i = 0; i < {nk}; ++i) {{
        const kernel_entry *k = &KERNELS[i];
        PyObject *ins = PyTuple_New(k->nin), *outs = PyTuple_New(k->nout);
        if (!ins || !outs) {{ Py_XDECREF(ins); Py_XDECREF(outs); Py_DECREF(d); return NULL; }}
        for (int j = 0; j < k->nin; ++j) PyTuple_SET_ITEM(ins, j, arg_shape_tuple(&k->in[j]));
        for (int j = 0; j < k->nout; ++j) PyTuple_SET_ITEM(outs, j, arg_shape_tuple(&k->out[j]));
        PyObject *v = Py_BuildValue("(NN)", ins, outs);
        if (!v || PyDict_SetItemString(d, k->name, v) < 0) {{ Py_XDECREF(v); Py_DECREF(d); return NULL; }}
        Py_DECREF(v);
    }}
    return d;
}}

static PyObject *threads(PyObject *self, PyObject *noargs)
{{
    (void)self; (void)noargs;
    return PyLong_FromLong(n_threads);
}}

static PyObject *source_hash(PyObject *self, PyObject *noargs)
{{
    (void)self; (void)noargs;
    return PyUnicode_FromString(RCCL_SOURCE_HASH);
}}

static PyMethodDef methods[] = {{
{defs}
    {{"kernels", kernels, METH_NOARGS, "kernels() -> {{name: (input shapes, output shapes)}}"}},
    {{"source_hash", source_hash, METH_NOARGS, "sha256 of the generated C this module was built from"}},
    {{"threads", threads, METH_NOARGS, "threads() -> the most threads a large batch is split over (RCCL_KINEMATICS_THREADS)"}},
#ifdef RCCL_NUMPY_API
    {{"public", public, METH_VARARGS, "public(name, fallback, keys=None) -> fast public entry of a kernel (see public_call)"}},
    {{"ik_setup", ik_setup, METH_VARARGS, "ik_setup(Config, fields, configs, revolute, lower, upper, rigid_tol, same_tol): data of the ik/ik_all/config_of entries"}},
#endif
    {{NULL, NULL, 0, NULL}}
}};

static struct PyModuleDef moduledef = {{
    PyModuleDef_HEAD_INIT, "{robot}", "Generated C kinematics kernels of the {robot} (see derive/emit_c.py).", -1, methods
}};

PyMODINIT_FUNC PyInit_{robot}(void)
{{
#ifdef RCCL_NUMPY_API
    import_array();
    str_value = PyUnicode_InternFromString("value");
    str_gravity_coeffs = PyUnicode_InternFromString("gravity_coeffs");
    if (!str_value || !str_gravity_coeffs) return NULL;
#endif
    init_threads();
#ifdef RCCL_VECTOR_TRIG
    __builtin_cpu_init();
    have_vector_trig = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
#endif
    PyObject *np = PyImport_ImportModule("numpy");
    if (!np) return NULL;
    np_empty = PyObject_GetAttrString(np, "empty");
    np_array = PyObject_GetAttrString(np, "array");
    Py_DECREF(np);
    np_array_kw = Py_BuildValue("{{ssss}}", "dtype", "float64", "order", "C");
    if (!np_empty || !np_array || !np_array_kw) return NULL;
    return PyModule_Create(&moduledef);
}}
"""


FAST_C = r"""/* ---------------------------------------------------------------- batched rows
 * Every batched call runs its rows in chunks of CHUNK: inputs of the chunk scanned for
 * NaN/inf, the kernel's batched loop, then (public entries) its guards and first output
 * checked while they are still in cache. Large batches are split over threads (pthreads;
 * RCCL_KINEMATICS_THREADS, default the online CPUs, at most MAX_THREADS). */
#define CHUNK 64
#define MAX_THREADS 8
#define ROWS_PER_THREAD 16384
#if defined(__unix__) || defined(__APPLE__)
#define RCCL_THREADS 1
#include <pthread.h>
#include <unistd.h>
#endif
static int n_threads = 1;

typedef struct {
    const kernel_entry *k;
    Py_ssize_t r0, r1;
    const double *ip[MAXIO];
    Py_ssize_t is[MAXIO];
    double *op[MAXIO];          /* NULL: a guard, written to per-chunk scratch */
    Py_ssize_t os[MAXIO];
    int check;                  /* scan inputs, guards (>= 0) and the first output (finite) */
    int bad;                    /* a check failed */
} row_job;

/* 1 when no element is NaN or inf: x - x is 0 for every finite x and NaN otherwise;
 * two lanes at a time with SSE2 (every x86-64), so the check costs little beside a row */
#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
/* four lanes with AVX where the CPU has it (checked at import) */
__attribute__((target("avx"))) static int all_finite_avx(const double *v, Py_ssize_t len)
{
    __m256d bad = _mm256_setzero_pd();
    Py_ssize_t j = 0;
    for (; j + 8 <= len; j += 8) {
        const __m256d a = _mm256_loadu_pd(v + j), b = _mm256_loadu_pd(v + j + 4);
        const __m256d da = _mm256_sub_pd(a, a), db = _mm256_sub_pd(b, b);
        bad = _mm256_or_pd(bad, _mm256_or_pd(_mm256_cmp_pd(da, da, _CMP_UNORD_Q), _mm256_cmp_pd(db, db, _CMP_UNORD_Q)));
    }
    int ok = _mm256_movemask_pd(bad) == 0;
    for (const double *e = v + len, *x = v + j; x < e; ++x) ok &= isfinite(*x) != 0;
    return ok;
}
static int have_avx = 0;
#define FINITE_AVX(v, len) if (have_avx && (len) >= 16) return all_finite_avx(v, len)
#else
#define FINITE_AVX(v, len)
#endif
#if defined(__SSE2__)
#include <emmintrin.h>
static int all_finite(const double *v, Py_ssize_t len)
{
    FINITE_AVX(v, len);
    __m128d bad = _mm_setzero_pd();
    Py_ssize_t j = 0;
    for (; j + 4 <= len; j += 4) {
        const __m128d a = _mm_loadu_pd(v + j), b = _mm_loadu_pd(v + j + 2);
        const __m128d da = _mm_sub_pd(a, a), db = _mm_sub_pd(b, b);
        bad = _mm_or_pd(bad, _mm_or_pd(_mm_cmpunord_pd(da, da), _mm_cmpunord_pd(db, db)));
    }
    int ok = _mm_movemask_pd(bad) == 0;
    for (const double *e = v + len, *x = v + j; x < e; ++x) ok &= isfinite(*x) != 0;
    return ok;
}
#else
static int all_finite(const double *v, Py_ssize_t len)
{
    int ok = 1;
    for (Py_ssize_t j = 0; j < len; ++j) ok &= isfinite(v[j]) != 0;
    return ok;
}
#endif

static void run_job(row_job *j)
{
    const kernel_entry *k = j->k;
    double scratch[MAXIO][CHUNK];
    const double *ic[MAXIO];
    double *oc[MAXIO];
    Py_ssize_t osc[MAXIO];
    for (Py_ssize_t r = j->r0; r < j->r1; r += CHUNK) {
        const Py_ssize_t m = j->r1 - r < CHUNK ? j->r1 - r : CHUNK;
        for (int i = 0; i < k->nin; ++i) {
            ic[i] = j->ip[i] + r * j->is[i];
            if (j->check && j->is[i] && !all_finite(ic[i], m * j->is[i])) { j->bad = 1; return; }
        }
        for (int o = 0; o < k->nout; ++o) {
            if (j->op[o]) { oc[o] = j->op[o] + r * j->os[o]; osc[o] = j->os[o]; }
            else { oc[o] = scratch[o]; osc[o] = 1; }
        }
        k->fn(m, ic, j->is, oc, osc);
        if (j->check) {
            for (int g = k->nout - k->nguard; g < k->nout; ++g)
                for (Py_ssize_t t = 0; t < m; ++t)
                    if (!(oc[g][t * osc[g]] >= 0)) { j->bad = 1; return; }
            if (!all_finite(oc[0], m * osc[0])) { j->bad = 1; return; }
        }
    }
}

#ifdef RCCL_THREADS
static void *job_thread(void *arg) { run_job((row_job *)arg); return NULL; }
#endif

/* n rows of kernel k, split over up to n_threads threads; returns nonzero when a check
 * failed (check = 1 only). Safe without the GIL: touches no Python object. */
static int run_rows(const kernel_entry *k, Py_ssize_t n, const double *const *ip, const Py_ssize_t *is,
                    double *const *op, const Py_ssize_t *os, int check)
{
    row_job jobs[MAX_THREADS];
    int t = 1;
#ifdef RCCL_THREADS
    t = n_threads;
    if (n / ROWS_PER_THREAD < t) t = (int)(n / ROWS_PER_THREAD);
    if (t < 1) t = 1;
#endif
    for (int w = 0; w < t; ++w) {
        row_job *j = &jobs[w];
        j->k = k; j->check = check; j->bad = 0;
        j->r0 = n * w / t; j->r1 = n * (w + 1) / t;
        for (int i = 0; i < k->nin; ++i) { j->ip[i] = ip[i]; j->is[i] = is[i]; }
        for (int o = 0; o < k->nout; ++o) { j->op[o] = op[o]; j->os[o] = os[o]; }
    }
    if (t == 1) { run_job(&jobs[0]); return jobs[0].bad; }
    int bad = 0;
#ifdef RCCL_THREADS
    pthread_t th[MAX_THREADS];
    int started[MAX_THREADS] = {0};
    for (int w = 1; w < t; ++w) started[w] = pthread_create(&th[w], NULL, job_thread, &jobs[w]) == 0;
    run_job(&jobs[0]);
    bad = jobs[0].bad;
    for (int w = 1; w < t; ++w) {
        if (started[w]) pthread_join(th[w], NULL);
        else run_job(&jobs[w]);       /* no thread to be had: run it here */
        bad |= jobs[w].bad;
    }
#endif
    return bad;
}

static void init_threads(void)
{
    long c = 1;
#ifdef RCCL_THREADS
    const char *env = getenv("RCCL_KINEMATICS_THREADS");
    c = (env && *env) ? strtol(env, NULL, 10) : sysconf(_SC_NPROCESSORS_ONLN);
#endif
    n_threads = c < 1 ? 1 : c > MAX_THREADS ? MAX_THREADS : (int)c;
#if defined(__x86_64__) && defined(__GNUC__)
    __builtin_cpu_init();
    have_avx = __builtin_cpu_supports("avx");
#endif
}

#ifdef RCCL_NUMPY_API
/* ---------------------------------------------------------------- public fast entries
 * The public functions of the generated module (rccl.kinematics.backend.public) are these
 * entries: when every argument is already in the form the C can take directly (float64
 * C-contiguous numpy arrays of the kernel's shape, one configuration or a batch along a
 * leading axis; gravity coefficients also as a mapping of floats; a valid pose; a Config)
 * and every check passes (finite inputs, guards >= 0, finite results), they return the
 * result. Anything else goes to `fallback`, the Python runtime, which gives the contract's
 * conversions, messages and exceptions: no error behaviour is lost. With out= the result
 * is written there; a call that then falls back may have written part of it. */

static PyObject *str_value = NULL, *str_gravity_coeffs = NULL;   /* interned attribute names */

/* a numpy array the entries can read in place: exact ndarray, float64, C-contiguous, aligned */
static PyArrayObject *plain_array(PyObject *x)
{
    if (!PyArray_CheckExact(x)) return NULL;
    PyArrayObject *a = (PyArrayObject *)x;
    if (PyArray_TYPE(a) != NPY_DOUBLE || !PyArray_CHKFLAGS(a, NPY_ARRAY_C_CONTIGUOUS | NPY_ARRAY_ALIGNED)) return NULL;
    return a;
}

/* coefficient values by name from a dict, a mappingproxy or a record with gravity_coeffs;
 * each a float or int, or a record with a float `.value` (rci.robot_model.Value).
 * 0 on success; -1 (no exception set) when the Python path must decide. */
static int mapping_values(PyObject *x, PyObject *keys, double *v)
{
    PyObject *m = x, *owned = NULL;
    if (!PyDict_Check(m) && !PyObject_TypeCheck(m, &PyDictProxy_Type)) {
        owned = PyObject_GetAttr(m, str_gravity_coeffs);
        if (!owned) { PyErr_Clear(); return -1; }
        m = owned;
        if (!PyDict_Check(m) && !PyObject_TypeCheck(m, &PyDictProxy_Type)) { Py_DECREF(owned); return -1; }
    }
    int rc = 0;
    for (Py_ssize_t i = 0; rc == 0 && i < PyTuple_GET_SIZE(keys); ++i) {
        PyObject *key = PyTuple_GET_ITEM(keys, i), *item;
        if (PyDict_Check(m)) { item = PyDict_GetItemWithError(m, key); Py_XINCREF(item); }
        else item = PyObject_GetItem(m, key);
        if (!item) { PyErr_Clear(); rc = -1; break; }
        double d = NAN;
        if (PyFloat_Check(item)) d = PyFloat_AS_DOUBLE(item);
        else if (PyLong_CheckExact(item)) { d = PyLong_AsDouble(item); if (PyErr_Occurred()) { PyErr_Clear(); d = NAN; } }
        else {
            PyObject *val = PyObject_GetAttr(item, str_value);
            if (!val) PyErr_Clear();
            else if (PyFloat_Check(val)) d = PyFloat_AS_DOUBLE(val);
            Py_XDECREF(val);
        }
        Py_DECREF(item);
        if (!isfinite(d)) rc = -1;
        else v[i] = d;
    }
    Py_XDECREF(owned);
    return rc;
}

/* the keyword `out` (or none); -1 for any other keyword */
static int out_keyword(PyObject *kwnames, PyObject *const *args, Py_ssize_t nargs, PyObject **out)
{
    *out = NULL;
    if (!kwnames) return 0;
    if (PyTuple_GET_SIZE(kwnames) != 1 || PyUnicode_CompareWithASCIIString(PyTuple_GET_ITEM(kwnames, 0), "out") != 0)
        return -1;
    if (args[nargs] != Py_None) *out = args[nargs];
    return 0;
}

static int overlaps(const void *a, Py_ssize_t na, const void *b, Py_ssize_t nb)
{
    const char *pa = (const char *)a, *pb = (const char *)b;
    return pa < pb + nb && pb < pa + na;
}

/* self = (fallback, coefficient names or None) */
static PyObject *public_call(const kernel_entry *k, PyObject *self, PyObject *const *args, Py_ssize_t nargs,
                             PyObject *kwnames)
{
    PyObject *fallback = PyTuple_GET_ITEM(self, 0), *keys = PyTuple_GET_ITEM(self, 1);
    const double *ip[MAXIO];
    double *op[MAXIO];
    Py_ssize_t is[MAXIO], os[MAXIO], ilen[MAXIO];
    double guard[MAXIO], coeffs[64];
    PyObject *out, *res;
    Py_ssize_t n = -1;
    if (nargs != k->nin || k->nout - k->nguard != 1 || out_keyword(kwnames, args, nargs, &out) < 0) goto slow;
    for (int i = 0; i < k->nin; ++i) {
        const arg_shape *s = &k->in[i];
        PyArrayObject *a = plain_array(args[i]);
        if (!a) {  /* the last input of gravity may be a mapping of coefficient values */
            if (keys == Py_None || i != k->nin - 1 || PyArray_Check(args[i]) || s->ndim != 1
                || s->dim[0] != PyTuple_GET_SIZE(keys) || s->dim[0] > 64 || mapping_values(args[i], keys, coeffs) < 0)
                goto slow;
            ip[i] = coeffs; is[i] = 0; ilen[i] = 0;
            continue;
        }
        const int nd = PyArray_NDIM(a), b = nd == s->ndim + 1;
        if (!(nd == s->ndim || b)) goto slow;
        for (int d = 0; d < s->ndim; ++d) if (PyArray_DIM(a, d + b) != s->dim[d]) goto slow;
        ip[i] = (const double *)PyArray_DATA(a);
        ilen[i] = PyArray_NBYTES(a);
        if (b) {
            const Py_ssize_t rows = PyArray_DIM(a, 0);
            if (rows == 0 || (n >= 0 && rows != n)) goto slow;
            n = rows;
            is[i] = s->size;          /* scanned chunk by chunk in run_rows */
        } else {
            if (!all_finite(ip[i], s->size)) goto slow;
            is[i] = 0;
        }
    }
    const arg_shape *s = &k->out[0];
    npy_intp dims[3];
    int nd = 0;
    if (n >= 0) dims[nd++] = n;
    for (int d = 0; d < s->ndim; ++d) dims[nd++] = s->dim[d];
    if (out) {  /* numpy's convention: exactly the result's shape and dtype, writable */
        PyArrayObject *o = plain_array(out);
        if (!o || PyArray_NDIM(o) != nd || !PyArray_ISWRITEABLE(o)) goto slow;
        for (int d = 0; d < nd; ++d) if (PyArray_DIM(o, d) != dims[d]) goto slow;
        for (int i = 0; i < k->nin; ++i)  /* written while read: the Python path copies */
            if (ilen[i] && overlaps(ip[i], ilen[i], PyArray_DATA(o), PyArray_NBYTES(o))) goto slow;
        Py_INCREF(out);
        res = out;
    } else {
        res = PyArray_SimpleNew(nd, dims, NPY_DOUBLE);
        if (!res) return NULL;
    }
    op[0] = (double *)PyArray_DATA((PyArrayObject *)res);
    os[0] = s->size;
    int bad = 0;
    if (n < 0) {
        for (int g = 0; g < k->nguard; ++g) { op[1 + g] = &guard[g]; os[1 + g] = 0; }
        k->fn(1, ip, is, op, os);
        for (int g = 0; g < k->nguard; ++g) bad |= !(guard[g] >= 0);
        bad |= !all_finite(op[0], s->size);
    } else {
        for (int g = 0; g < k->nguard; ++g) { op[1 + g] = NULL; os[1 + g] = 1; }
        if (n > 4096) {
            Py_BEGIN_ALLOW_THREADS
            bad = run_rows(k, n, ip, is, op, os, 1);
            Py_END_ALLOW_THREADS
        } else {
            bad = run_rows(k, n, ip, is, op, os, 1);
        }
    }
    if (bad) { Py_DECREF(res); goto slow; }
    return res;
slow:
    return PyObject_Vectorcall(fallback, args, (size_t)nargs, kwnames);
}

/* ---------------------------------------------------------------- ik, ik_all, config_of */

static struct {
    int ready, ik, ik_all, ind;                 /* kernel indices (-1: absent) */
    PyObject *config_type, *fields, *configs;   /* Config class, its field names, Config.all() */
    int nfield, nconf;
    double revolute[6], lower[6], upper[6];
    double rigid_tol, same_tol;
} IK = {0, -1, -1, -1, NULL, NULL, NULL, 0, 0, {0}, {0}, {0}, 0, 0};

static int kernel_index(const char *name)
{
    for (int i = 0; i < (int)(sizeof KERNELS / sizeof KERNELS[0]); ++i)
        if (strcmp(KERNELS[i].name, name) == 0) return i;
    return -1;
}

static int six_floats(PyObject *seq, double *v, const char *what)
{
    PyObject *f = PySequence_Fast(seq, what);
    if (!f) return -1;
    if (PySequence_Fast_GET_SIZE(f) != 6) { Py_DECREF(f); PyErr_Format(PyExc_ValueError, "%s: need 6 values", what); return -1; }
    for (int j = 0; j < 6; ++j) {
        v[j] = PyFloat_AsDouble(PySequence_Fast_GET_ITEM(f, j));
        if (v[j] == -1.0 && PyErr_Occurred()) { Py_DECREF(f); return -1; }
    }
    Py_DECREF(f);
    return 0;
}

/* ik_setup(Config, field names, Config.all(), revolute flags, lower, upper, rigid tol, same-solution tol) */
static PyObject *ik_setup(PyObject *self, PyObject *args)
{
    (void)self;
    PyObject *ct, *fields, *configs, *rev, *lo, *hi;
    double rigid, same;
    if (!PyArg_ParseTuple(args, "OO!O!OOOdd:ik_setup", &ct, &PyTuple_Type, &fields, &PyTuple_Type, &configs,
                          &rev, &lo, &hi, &rigid, &same)) return NULL;
    IK.ik = kernel_index("ik");
    IK.ik_all = kernel_index("ik_all");
    IK.ind = kernel_index("config_indicators");
    IK.nfield = (int)PyTuple_GET_SIZE(fields);
    IK.nconf = (int)PyTuple_GET_SIZE(configs);
    if (IK.nfield < 1 || IK.nfield > 8 || IK.nconf != (1 << IK.nfield)) {
        PyErr_SetString(PyExc_ValueError, "ik_setup: need 1..8 fields and 2**fields configurations");
        return NULL;
    }
    if (six_floats(rev, IK.revolute, "ik_setup revolute") < 0 || six_floats(lo, IK.lower, "ik_setup lower") < 0
        || six_floats(hi, IK.upper, "ik_setup upper") < 0) return NULL;
    /* the kernels must have the layout the entries assume; otherwise they stay unused */
    if (IK.ik >= 0 && !(KERNELS[IK.ik].nin == 2 && KERNELS[IK.ik].in[0].size == 16 && KERNELS[IK.ik].in[1].size == IK.nfield
                        && KERNELS[IK.ik].out[0].size == 6 && KERNELS[IK.ik].nout == 1 + KERNELS[IK.ik].nguard)) IK.ik = -1;
    if (IK.ik_all >= 0 && !(KERNELS[IK.ik_all].nout == 2 && KERNELS[IK.ik_all].out[0].size == 6 * IK.nconf
                            && KERNELS[IK.ik_all].out[1].size <= 16 * IK.nconf)) IK.ik_all = -1;
    if (IK.ind >= 0 && !(KERNELS[IK.ind].nin == 1 && KERNELS[IK.ind].in[0].size == 6 && KERNELS[IK.ind].nguard == 0
                         && KERNELS[IK.ind].nout == 1 && KERNELS[IK.ind].out[0].size == IK.nfield)) IK.ind = -1;
    Py_XSETREF(IK.config_type, Py_NewRef(ct));
    Py_XSETREF(IK.fields, Py_NewRef(fields));
    Py_XSETREF(IK.configs, Py_NewRef(configs));
    IK.rigid_tol = rigid;
    IK.same_tol = same;
    IK.ready = 1;
    Py_RETURN_NONE;
}

/* 1 when the 16 doubles are clearly a rigid transform: finite, last row exactly 0 0 0 1,
 * rotation orthonormal within half the runtime's tolerance (the borderline band is left to
 * the Python check), determinant > 0 */
static int pose_ok(const double *t)
{
    if (!all_finite(t, 16) || t[12] != 0.0 || t[13] != 0.0 || t[14] != 0.0 || t[15] != 1.0) return 0;
    double dev = 0.0;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
            const double d = t[i] * t[j] + t[4 + i] * t[4 + j] + t[8 + i] * t[8 + j] - (i == j);
            dev = fabs(d) > dev ? fabs(d) : dev;
        }
    const double det = t[0] * (t[5] * t[10] - t[6] * t[9]) - t[1] * (t[4] * t[10] - t[6] * t[8])
                     + t[2] * (t[4] * t[9] - t[5] * t[8]);
    return dev <= 0.5 * IK.rigid_tol && det > 0;
}

/* the pose as 16 doubles when it is a plain (4, 4) array and pose_ok */
static const double *pose_arg(PyObject *x)
{
    PyArrayObject *a = plain_array(x);
    if (!a || PyArray_NDIM(a) != 2 || PyArray_DIM(a, 0) != 4 || PyArray_DIM(a, 1) != 4) return NULL;
    const double *t = (const double *)PyArray_DATA(a);
    return pose_ok(t) ? t : NULL;
}

/* q_ref when None (NULL), or a plain finite (6,) array; *ok = 0 when the Python path must decide */
static const double *ref_arg(PyObject *x, int *ok)
{
    *ok = 1;
    if (!x || x == Py_None) return NULL;
    PyArrayObject *a = plain_array(x);
    if (!a || PyArray_NDIM(a) != 1 || PyArray_DIM(a, 0) != 6 || !all_finite((const double *)PyArray_DATA(a), 6)) {
        *ok = 0;
        return NULL;
    }
    return (const double *)PyArray_DATA(a);
}

/* the +-1 signs of a Config instance (exactly the generated module's Config class) */
static int config_signs(PyObject *c, double *signs)
{
    if ((PyObject *)Py_TYPE(c) != IK.config_type) return -1;
    for (int i = 0; i < IK.nfield; ++i) {
        PyObject *v = PyObject_GetAttr(c, PyTuple_GET_ITEM(IK.fields, i));
        if (!v) { PyErr_Clear(); return -1; }
        const long s = PyLong_CheckExact(v) ? PyLong_AsLong(v) : 0;
        Py_DECREF(v);
        if (s != 1 && s != -1) { PyErr_Clear(); return -1; }
        signs[i] = (double)s;
    }
    return 0;
}

/* (x + pi) mod 2 pi - pi with numpy's floor modulo: runtime._wrap, to the bit */
static double wrap_angle(double x)
{
    double y = fmod(x + M_PI, 2 * M_PI);
    if (y != 0.0) { if (y < 0) y += 2 * M_PI; }
    else y = 0.0;
    return y - M_PI;
}

/* q_ref's 2 pi branch on revolute joints, then finite and prismatic joints in range;
 * 0 when all is well */
static int finish_q(double *q, const double *ref)
{
    if (!all_finite(q, 6)) return -1;
    if (ref)
        for (int j = 0; j < 6; ++j)
            if (IK.revolute[j] != 0) q[j] = ref[j] + wrap_angle(q[j] - ref[j]);
    for (int j = 0; j < 6; ++j)
        if (IK.revolute[j] == 0 && (q[j] < IK.lower[j] - 1e-12 || q[j] > IK.upper[j] + 1e-12)) return -1;
    return all_finite(q, 6) ? 0 : -1;
}

static PyObject *new_vector(const double *v, npy_intp len)
{
    PyObject *a = PyArray_SimpleNew(1, &len, NPY_DOUBLE);
    if (a) memcpy(PyArray_DATA((PyArrayObject *)a), v, (size_t)len * sizeof(double));
    return a;
}

/* the q_ref argument of ik(T, config, q_ref=None) / ik_all(T, q_ref=None): position `pos`
 * or the keyword; *ok = 0 for any other call form */
static PyObject *q_ref_object(PyObject *const *args, Py_ssize_t nargs, PyObject *kwnames, Py_ssize_t pos, int *ok)
{
    const Py_ssize_t nkw = kwnames ? PyTuple_GET_SIZE(kwnames) : 0;
    *ok = 1;
    if (nkw == 0 && nargs == pos) return NULL;
    if (nkw == 0 && nargs == pos + 1) return args[pos];
    if (nkw == 1 && nargs == pos && PyUnicode_CompareWithASCIIString(PyTuple_GET_ITEM(kwnames, 0), "q_ref") == 0)
        return args[pos];
    *ok = 0;
    return NULL;
}

/* ik(T, config, q_ref=None) for one pose */
static PyObject *pubfast_ik(PyObject *fallback, PyObject *const *args, Py_ssize_t nargs, PyObject *kwnames)
{
    int ok;
    if (!IK.ready || IK.ik < 0 || nargs < 2) goto slow;
    PyObject *ref_obj = q_ref_object(args, nargs, kwnames, 2, &ok);
    if (!ok) goto slow;
    const double *ref = ref_arg(ref_obj, &ok), *t = pose_arg(args[0]);
    double signs[8], q[6], guard[MAXIO];
    if (!ok || !t || config_signs(args[1], signs) < 0) goto slow;
    const kernel_entry *k = &KERNELS[IK.ik];
    const double *ip[2] = {t, signs};
    double *op[MAXIO];
    static const Py_ssize_t zero[MAXIO] = {0};
    op[0] = q;
    for (int g = 0; g < k->nguard; ++g) op[1 + g] = &guard[g];
    k->fn(1, ip, zero, op, zero);
    for (int g = 0; g < k->nguard; ++g) if (!(guard[g] >= 0)) goto slow;  /* unreachable, singular: messages */
    if (finish_q(q, ref) < 0) goto slow;
    return new_vector(q, 6);
slow:
    return PyObject_Vectorcall(fallback, args, (size_t)nargs, kwnames);
}

/* every configuration of one pose from the ik_all kernel, duplicates (2 pi apart) dropped
 * with the first kept: a new list of (Config, q), NULL with *slow = 1 when the Python path
 * must decide (a configuration failing a guard: left out, wrist fallback or an error) */
static PyObject *ik_all_one(const double *t, const double *ref, int *slow)
{
    const kernel_entry *k = &KERNELS[IK.ik_all];
    const int nc = IK.nconf, ng = (int)(k->out[1].size / nc);
    double q[256 * 6], g[256 * 16];
    int found[256], kept[256], nkept = 0;
    *slow = 1;
    if (nc > 256 || !pose_ok(t)) return NULL;
    const double *ip[1] = {t};
    double *op[2] = {q, g};
    static const Py_ssize_t zero[2] = {0, 0};
    k->fn(1, ip, zero, op, zero);
    for (int j = 0; j < nc; ++j) {
        for (int c = 0; c < ng; ++c) if (!(g[j * ng + c] >= 0)) return NULL;
        if (!all_finite(q + 6 * j, 6)) return NULL;
        found[j] = finish_q(q + 6 * j, ref) == 0;   /* a prismatic joint out of range: left out */
    }
    for (int j = 0; j < nc; ++j) {
        if (!found[j]) continue;
        int dup = 0;
        for (int m = 0; m < nkept && !dup; ++m) {
            int same = 1;
            for (int c = 0; c < 6 && same; ++c) {
                double d = q[6 * j + c] - q[6 * kept[m] + c];
                if (IK.revolute[c] != 0) d = wrap_angle(d);
                same = fabs(d) < IK.same_tol;
            }
            dup = same;
        }
        if (!dup) kept[nkept++] = j;
    }
    *slow = 0;
    PyObject *list = PyList_New(nkept);
    if (!list) return NULL;
    for (int m = 0; m < nkept; ++m) {
        PyObject *v = new_vector(q + 6 * kept[m], 6);
        PyObject *pair = v ? PyTuple_Pack(2, PyTuple_GET_ITEM(IK.configs, kept[m]), v) : NULL;
        Py_XDECREF(v);
        if (!pair) { Py_DECREF(list); return NULL; }
        PyList_SET_ITEM(list, m, pair);
    }
    return list;
}

/* ik_all(T, q_ref=None) for one pose (4, 4) or a batch (N, 4, 4) (q_ref then (N, 6)); a
 * batch goes to the Python path as a whole when any of its poses must */
static PyObject *pubfast_ik_all(PyObject *fallback, PyObject *const *args, Py_ssize_t nargs, PyObject *kwnames)
{
    int ok, slow;
    if (!IK.ready || IK.ik_all < 0 || nargs < 1) goto slow;
    PyObject *ref_obj = q_ref_object(args, nargs, kwnames, 1, &ok);
    if (!ok) goto slow;
    PyArrayObject *a = plain_array(args[0]);
    if (!a || PyArray_DIM(a, PyArray_NDIM(a) - 1) != 4) goto slow;
    if (PyArray_NDIM(a) == 2) {
        const double *ref = ref_arg(ref_obj, &ok), *t = pose_arg(args[0]);
        if (!ok || !t) goto slow;
        PyObject *res = ik_all_one(t, ref, &slow);
        if (slow) goto slow;
        return res;
    }
    if (PyArray_NDIM(a) != 3 || PyArray_DIM(a, 1) != 4 || PyArray_DIM(a, 0) == 0) goto slow;
    const Py_ssize_t n = PyArray_DIM(a, 0);
    const double *refs = NULL;
    if (ref_obj && ref_obj != Py_None) {
        PyArrayObject *r = plain_array(ref_obj);
        if (!r || PyArray_NDIM(r) != 2 || PyArray_DIM(r, 0) != n || PyArray_DIM(r, 1) != 6) goto slow;
        refs = (const double *)PyArray_DATA(r);
        if (!all_finite(refs, 6 * n)) goto slow;
    }
    const double *ts = (const double *)PyArray_DATA(a);
    PyObject *out = PyList_New(n);
    if (!out) return NULL;
    for (Py_ssize_t i = 0; i < n; ++i) {
        PyObject *res = ik_all_one(ts + 16 * i, refs ? refs + 6 * i : NULL, &slow);
        if (!res) {
            Py_DECREF(out);
            if (slow) goto slow;
            return NULL;
        }
        PyList_SET_ITEM(out, i, res);
    }
    return out;
slow:
    return PyObject_Vectorcall(fallback, args, (size_t)nargs, kwnames);
}

/* config_of(q) for one configuration: the Config.all() entry of the indicators' signs */
static PyObject *pubfast_config_of(PyObject *fallback, PyObject *const *args, Py_ssize_t nargs, PyObject *kwnames)
{
    if (!IK.ready || IK.ind < 0 || nargs != 1 || kwnames) goto slow;
    PyArrayObject *a = plain_array(args[0]);
    if (!a || PyArray_NDIM(a) != 1 || PyArray_DIM(a, 0) != 6) goto slow;
    const double *q = (const double *)PyArray_DATA(a);
    if (!all_finite(q, 6)) goto slow;
    double ind[8];
    const double *ip[1] = {q};
    double *op[1] = {ind};
    static const Py_ssize_t zero[1] = {0};
    KERNELS[IK.ind].fn(1, ip, zero, op, zero);
    if (!all_finite(ind, IK.nfield)) goto slow;
    int idx = 0;
    for (int i = 0; i < IK.nfield; ++i) idx = 2 * idx + (ind[i] >= 0 ? 0 : 1);  /* product((1, -1)) order */
    return Py_NewRef(PyTuple_GET_ITEM(IK.configs, idx));
slow:
    return PyObject_Vectorcall(fallback, args, (size_t)nargs, kwnames);
}

static PyMethodDef IK_DEFS[] = {
    {"ik", (PyCFunction)(void (*)(void))pubfast_ik, METH_FASTCALL | METH_KEYWORDS,
     "ik(T, config, q_ref=None): fast entry for one float64 pose; anything else, and every error, via the runtime"},
    {"ik_all", (PyCFunction)(void (*)(void))pubfast_ik_all, METH_FASTCALL | METH_KEYWORDS,
     "ik_all(T, q_ref=None): fast entry for float64 poses (one or a batch); anything else, and every error, via the runtime"},
    {"config_of", (PyCFunction)(void (*)(void))pubfast_config_of, METH_FASTCALL | METH_KEYWORDS,
     "config_of(q): fast entry for one float64 configuration; anything else via the runtime"},
};
#endif
"""


def source_hash(text: str) -> str:
    """sha256 of a generated C file without its RCCL_SOURCE_HASH line (see rccl.kinematics.backend)."""
    import hashlib
    body = "".join(line for line in text.splitlines(keepends=True) if not line.startswith("#define RCCL_SOURCE_HASH"))
    return hashlib.sha256(body.encode()).hexdigest()


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
    text = text.replace("@HASH@", source_hash(text))
    if not path.exists() or path.read_text() != text:
        path.write_text(text)
    return path, programs
