"""Lowering: a Kernel's SymPy expressions to a straight-line program (``LoweredKernel``).

The form both the C and the CasADi back ends print (derive.emit_c chooses among the
variants by counting the operations of the C text it prints):

1. robot constants (``Kernel.params``) are substituted numerically;
2. every distinct ``sin(x)`` / ``cos(x)`` becomes a local computed once at the top;
3. sums are factored greedily (multivariate Horner: pull out the factor shared by most
   terms, recursively), then common subexpressions are shared (``sympy.cse``);
4. for a 4x4 homogeneous-transform output one rotation column may be computed as the
   cross product of the other two (thesis 3.3: n = o x a, o = a x n, a = n x o).
5. in a guarded solve, divisions by several bounded divisors may share one reciprocal
   (``shared_reciprocal``).

Also ``ik_all`` (every configuration of ``ik`` at once), a composition of the derived
kernels that the compiled back ends add.
"""
from __future__ import annotations

import itertools
from collections import Counter
from dataclasses import dataclass, replace

import sympy as sp

from derive.kernel import Arg, Kernel

@dataclass
class LoweredKernel:
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


def outputs_of(kernel: Kernel) -> tuple[list[list[str]], list[sp.Expr]]:
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


def transform_columns(kernel: Kernel) -> list[tuple[int, int]]:
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
          collapse: bool = False, cse_opt: bool = True, expand: bool = True, staged: bool = False) -> LoweredKernel:
    """Lower a kernel to assignments.

    ``factor``: "" (none), "count" (most shared factor first), "base" / "tip" (trig of the
    joint nearest the base / the tool first). ``cross`` maps a transform output to the
    column (0 n, 1 o, 2 a) rebuilt by a cross product. ``collapse`` rewrites sums of
    products of sines and cosines into sines and cosines of sums (C2 C3 - S2 S3 -> C23).
    """
    in_names, sym_names = _input_symbols(kernel)
    out_names, exprs = outputs_of(kernel)
    n_stage = 0
    staged = staged or kernel.program  # a program's outputs exist only in its stage symbols
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
    for (oi, off) in transform_columns(kernel):
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
    temps = in_dependency_order(list(temps) + stage_defs)
    outputs: list[tuple[str, sp.Expr]] = [(flat_names[k], reduced[i]) for i, k in enumerate(keep)]
    for k in sorted(rebuilt):
        outputs.append((flat_names[k], rebuilt[k]))
    temps = _live(temps, [v for _, v in outputs])
    variant = (f"{'expand+' if expand else ''}horner[{factor}]+cse" if factor else "cse")
    variant += ", trig sums collapsed" if collapse else ""
    variant += ", staged (the kernel's structure hint)" if staged else ""
    variant += "".join(f", {'noa'[c]}=cross" for c in cross.values())
    return LoweredKernel(kernel, in_names, out_names, trig, list(temps), outputs, sym_names, variant)


def in_dependency_order(defs: list[tuple[sp.Symbol, sp.Expr]]) -> list[tuple[sp.Symbol, sp.Expr]]:
    """Order assignments so each comes after the ones it uses (stable otherwise: among the
    assignments ready at a step, the earliest in ``defs`` goes first)."""
    import heapq

    defined = {s: i for i, (s, _) in enumerate(defs)}
    waiting = {}
    users: dict[int, list[int]] = {}
    for i, (s, v) in enumerate(defs):
        deps = {defined[x] for x in v.free_symbols if x in defined and defined[x] != i}
        waiting[i] = len(deps)
        for d in deps:
            users.setdefault(d, []).append(i)
    ready = [i for i, n in waiting.items() if n == 0]
    heapq.heapify(ready)
    out: list[tuple[sp.Symbol, sp.Expr]] = []
    while ready:
        i = heapq.heappop(ready)
        out.append(defs[i])
        for u in users.get(i, ()):
            waiting[u] -= 1
            if waiting[u] == 0:
                heapq.heappush(ready, u)
    if len(out) != len(defs):
        raise ValueError(f"circular definitions among {[str(s) for s, _ in defs if (s, _) not in out]}")
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


#: at most this many divisions share one reciprocal (their product stays far from
#: underflow: each is a guarded singular factor, |d| > SINGULAR_TOL-scale, see below)
MAX_SHARED_DIVISORS = 4


def shared_reciprocal(prog: LoweredKernel) -> LoweredKernel | None:
    """Divisions by several divisors d1..dk replaced by one reciprocal r = 1/(d1 ... dk) and
    multiplications (1/d1 = r d2 ... dk, shared as prefix and suffix products: 3(k - 1)
    multiplications for k - 1 divisions); None where that is not safe or there is nothing
    to share (derive.emit_c keeps it where it counts fewer cycles).

    Only where it is safe: the kernel has guards (its divisors are the singular factors
    it checks, so a divisor near zero makes the row invalid whatever its rounding), and
    every divisor is a polynomial in sines and cosines with constant coefficients, so
    bounded: the product cannot overflow, and with each factor above the guards'
    tolerance (1e-9 scale) it cannot underflow either. A divisor that depends on an
    input other than through a sine or cosine, on a division or on a function call is
    left as it is (then nothing is shared). The result is the same quotient up to
    rounding; the single-row and batched C paths print this same program, so they agree
    bit for bit.
    """
    if not prog.kernel.guards:
        return None
    n_main = len(prog.kernel.outputs)
    guard_names = {n for row in prog.out_names[n_main:] for n in row}
    temps = dict(prog.temps)
    trig_syms = {s for s, f in prog.trig if isinstance(f, (sp.sin, sp.cos))}
    bounded_memo: dict[sp.Symbol, bool] = {}

    def bounded(e: sp.Expr) -> bool:
        """A polynomial in sines and cosines with constant coefficients."""
        if any(p.is_Pow and not (p.exp.is_Integer and p.exp > 0) for p in sp.preorder_traversal(e)):
            return False
        if any(isinstance(a, sp.Function) for a in sp.preorder_traversal(e)):
            return False
        for sym in e.free_symbols:
            if sym in trig_syms:
                continue
            if sym not in temps:
                return False
            if sym not in bounded_memo:
                bounded_memo[sym] = bounded(temps[sym])
            if not bounded_memo[sym]:
                return False
        return True

    bodies = [v for _, v in prog.temps] + [v for n, v in prog.outputs if n not in guard_names]
    divisors: list[sp.Expr] = []
    for e in bodies:
        for p in sp.preorder_traversal(e):
            if p.is_Pow and p.exp == -1 and p.base not in divisors:
                divisors.append(p.base)
    if not 2 <= len(divisors) <= MAX_SHARED_DIVISORS or not all(bounded(d) for d in divisors):
        return None
    if any(p.is_Pow and p.exp.is_negative and p.exp != -1 for e in bodies for p in sp.preorder_traversal(e)):
        return None
    k = len(divisors)
    new: list[tuple[sp.Symbol, sp.Expr]] = []
    d = []
    for i, b in enumerate(divisors):  # each divisor a local of its own
        if b.is_Symbol:
            d.append(b)
        else:
            d.append(sp.Symbol(f"d_{i}"))
            new.append((d[-1], b))
    prefix = [d[0]]
    for i in range(1, k):
        prefix.append(sp.Symbol(f"dp_{i}"))
        new.append((prefix[i], prefix[i - 1] * d[i]))
    r = sp.Symbol("r_0")
    new.append((r, 1 / prefix[-1]))
    inv: dict[sp.Expr, sp.Symbol] = {}
    rest = r  # 1/(d0 ... di) while walking back
    for i in range(k - 1, 0, -1):
        inv[divisors[i]] = sp.Symbol(f"r_{i}_inv")
        new.append((inv[divisors[i]], rest * prefix[i - 1]))
        nxt = sp.Symbol(f"r_{i}")
        new.append((nxt, rest * d[i]))
        rest = nxt
    inv[divisors[0]] = rest
    subs = {sp.Pow(b, -1): inv[b] for b in divisors}
    temps_new = [(s_, v.xreplace(subs)) for s_, v in prog.temps]
    outputs = [(n, v if n in guard_names else v.xreplace(subs)) for n, v in prog.outputs]
    return replace(prog, temps=in_dependency_order(new + temps_new), outputs=outputs,
                   variant=prog.variant + f", {k} divisions by one shared reciprocal")


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


def all_configurations_kernels(kernels: list[Kernel]) -> list[Kernel]:
    """``ik_all``: the ``ik`` kernel evaluated for every configuration at once.

    Built here (a back-end composition, not new kinematics) by substituting each sign
    combination of the ``config`` input, in ``itertools.product((1, -1), repeat=n)``
    order (the order of the runtime's ``Config.all()``), so common subexpressions are
    shared between configurations. Outputs: ``q`` (n_configs, 6) and ``guards``
    (n_configs, n_guards), a configuration being valid when all its guards are >= 0.
    """
    ik = next((k for k in kernels if k.name == "ik"), None)
    if ik is None or ik.inputs[-1].name != "config":
        return []
    signs = list(ik.inputs[-1].value)
    q = ik.outputs[0].value
    rows, grows = [], []
    for combo in itertools.product((1, -1), repeat=len(signs)):
        sub = dict(zip(signs, combo))
        rows.append(dag_xreplace(list(q), sub))
        grows.append(dag_xreplace([g.expr for g in ik.guards], sub))
    doc = ("every configuration of ik at once (rows in Config.all() order); guards per row, "
           "a row is valid when all its guards are >= 0")
    # every input but config (the pose; a redundant arm's free value too: derive.inverse_redundant)
    return [Kernel(ik.robot, "ik_all", doc, tuple(ik.inputs[:-1]),
                   (Arg("q", sp.Matrix(rows)), Arg("guards", sp.Matrix(grows))), (), dict(ik.params), ik.source)]
