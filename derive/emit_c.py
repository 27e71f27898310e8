"""C back end: prints each lowered Kernel (derive.lowering) as straight-line optimised C
and writes one extension source per robot.

Of the lowering's variants (factoring, expanding, staging, which rotation column to
rebuild as a cross product) the one with fewest operations, counted by
``derive.opcount`` in the C text itself, is kept (``best_program``).

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
from dataclasses import dataclass, replace
from pathlib import Path

import sympy as sp

from derive import opcount
from derive.emit_c_lanes import lane_loop, lane_row
from derive.kernel import Kernel
from derive.lowering import (LoweredKernel, all_configurations_kernels, dag_size, lower, outputs_of,
                             shared_reciprocal, transform_columns, tree_size)

#: Functions the C printer knows, with their C spelling.
C_FUNCS = {
    sp.sin: "sin", sp.cos: "cos", sp.tan: "tan", sp.atan2: "atan2", sp.atan: "atan",
    sp.asin: "asin", sp.acos: "acos", sp.Abs: "fabs", sp.exp: "exp", sp.log: "log",
}


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
        if e.is_Number or e.is_NumberSymbol:  # pi: an atan2 of constants folded by SymPy
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


def kernel_body(prog: LoweredKernel) -> str:
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


#: above this many distinct subexpressions, or this many tree nodes, only plain CSE is
#: tried (the rewrites that expand or factor sums cost too much on large kernels)
LARGE_KERNEL = 1500
LARGE_TREE = 20000
#: the greedy sign flip reprints the kernel once per temporary: skipped above this many
#: (the dynamics programs, thousands of assignments, where it would take minutes)
FLIP_SIGNS_MAX_TEMPS = 400


def best_program(kernel: Kernel) -> tuple[LoweredKernel, str]:
    """Try the lowering variants and keep the one with fewest counted operations."""
    cols = [oi for oi, _ in transform_columns(kernel)]
    cross_choices: list[dict[int, int]] = [{}]
    if len(cols) == 1:
        cross_choices += [{cols[0]: c} for c in range(3)]
    _, exprs = outputs_of(kernel)
    # a 7-joint arm's kernels (expanded seven-fold products) take the one-pass lowering: the
    # search below costs minutes per kernel on them
    seven = any(a.name == "q" and a.value.rows == 7 for a in kernel.inputs)
    large = seven or dag_size(exprs) > LARGE_KERNEL or tree_size(exprs) > LARGE_TREE
    collapses = (False,) if large or kernel.program else (False, True)
    factors = ("",) if large else ("", "count") if kernel.program else ("", "count", "base", "tip")
    stagings = (True,) if kernel.program else (False, True) if kernel.stages else (False,)
    best_per_cross: list[tuple[tuple[int, int, int], LoweredKernel]] = []
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
        prog = best[1]
        prog = _shared_reciprocal(_flip_signs(prog) if len(prog.temps) <= FLIP_SIGNS_MAX_TEMPS else prog)
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


def _flip_signs(prog: LoweredKernel) -> LoweredKernel:
    """Store -t instead of t for temps where that removes unary minus signs (greedy)."""
    def cost(p: LoweredKernel) -> tuple[int, int]:
        c = opcount.count_ops(kernel_body(p))
        return c["add_sub"] + c["mul_div"], c["neg"]

    current = cost(prog)
    for i, (sym, _) in enumerate(list(prog.temps)):
        neg = sp.Symbol(sym.name + "_n")
        sub = {sym: -neg}
        temps = [(s, v.xreplace(sub)) for s, v in prog.temps]
        temps[i] = (neg, -prog.temps[i][1])
        trial = LoweredKernel(prog.kernel, prog.in_names, prog.out_names, prog.trig, temps,
                        [(n, v.xreplace(sub)) for n, v in prog.outputs], prog.symbol_names, prog.variant)
        c = cost(trial)
        if c < current:
            prog, current = trial, c
    return prog


def _shared_reciprocal(prog: LoweredKernel) -> LoweredKernel:
    """``derive.lowering.shared_reciprocal`` where it counts fewer cycles
    (``opcount.cycles``: a division costs 8 multiplications' throughput, and the divisions
    of a solve sit on its dependency chain, 13-15 cycles of latency each)."""
    trial = shared_reciprocal(prog)
    if trial is not None and opcount.cycles(kernel_body(trial)) < opcount.cycles(kernel_body(prog)):
        return trial
    return prog


# ---------------------------------------------------------------- module text

def _c_string(s: str) -> str:
    return json.dumps(s)


#: rows per block of the batched loops whose sines and cosines are computed a block at a time
TRIG_BLOCK = 32


@dataclass(frozen=True)
class TrigSplit:
    """A kernel split for vector sines and cosines: its trig arguments, then the row."""

    locals: list[str]                    # C statements of the arguments' helper sums (const double x_i = ...)
    args: list[str]                      # C expressions of the distinct arguments, in lane order
    table: list[tuple[str, str, int]]    # (row local, sin | cos, argument index), in tv order
    row: str                             # the row body, reading its trig values from tv[t * ts]

    @property
    def stmts(self) -> list[str]:
        """The block loop's statements for row r: helper sums, then ta[i][r] = argument i."""
        return self.locals + [f"ta[{i}][r] = {a};" for i, a in enumerate(self.args)]


def _vector_trig(prog: LoweredKernel) -> TrigSplit | None:
    """The kernel split for vector sines and cosines; None when a sine or cosine takes an
    argument that is not a sum of inputs (then the plain row loop is used)."""
    trig_funcs = [(sym, f) for sym, f in prog.trig if isinstance(f, (sp.sin, sp.cos))]
    if not trig_funcs:
        return None
    inputs = set(prog.symbol_names)
    xsyms = {sym for sym, f in prog.trig if not isinstance(f, (sp.sin, sp.cos))}
    for _, f in trig_funcs:
        a = f.args[0]
        if a.atoms(sp.Function) or not a.free_symbols <= inputs | xsyms:
            return None
    # the helper sums are computed before the row: only of inputs (a redundant arm's ik has
    # atan2 locals of the config signs, derive.inverse_redundant)
    if any(not f.free_symbols <= inputs for sym, f in prog.trig if sym in xsyms):
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
    lines = kernel_body(prog).splitlines()
    local = {name: t for t, (name, _, _) in enumerate(table)}
    row = []
    for line in lines:
        head = line.strip().split(" = ")[0].replace("const double ", "")
        if head in local:
            row.append(f"    const double {head} = tv[{local[head]} * ts];")
        else:
            row.append(line)
    return TrigSplit(stmts, args, table, "\n".join(row))


def _slot(slot: dict[tuple[int, str], int], arg: int, fn: str) -> str:
    """The block row of tv that receives ``fn`` of argument ``arg``, or NULL: not needed."""
    t = slot.get((arg, fn))
    return "NULL" if t is None else f"tv[{t}]"


#: lanes of a vector of the sine/cosine code (kin_prelude.h: AVX2, 4 doubles)
LANES = 4


def _one_row_trig(prog: LoweredKernel, split: TrigSplit) -> str:
    """The single-row path's sines and cosines: the row's arguments straight into vector
    registers, all of them in one stretch of AVX2 code (kin_prelude.h vtrig_row), into the
    row's ``tv``. Only the sines and cosines: the row itself stays in the caller, compiled as
    the block path's rows are (the same code gives the same bits; GCC's SLP vectorizer with
    AVX2 rounds some rows differently)."""
    k = prog.kernel
    nin = len(prog.in_names)
    params = [f"const double *restrict in{i}" for i in range(nin)] + ["double *restrict tv"]
    nv = -(-len(split.args) // LANES)
    lanes = split.args + ["0.0"] * (nv * LANES - len(split.args))
    vectors = ", ".join(f"_mm256_setr_pd({', '.join(lanes[v * LANES:(v + 1) * LANES])})" for v in range(nv))
    fill = " ".join(f"tv[{t}] = {'sv' if fn == 'sin' else 'cv'}[{a}];" for t, (_, fn, a) in enumerate(split.table))
    locals_ = "".join(f"\n    {st}" for st in split.locals)
    return f"""
/* {k.name} for one row: its sine/cosine arguments side by side in vector lanes, their
 * values into tv; 0 when one is beyond VTRIG_BIG (then the block path below, which sends
 * it to libm) */
VTRIG_TARGET static int kv1_{k.name}({", ".join(params)})
{{{locals_}
    const __m256d x[{nv}] = {{{vectors}}};
    double sv[{nv * LANES}], cv[{nv * LANES}];
    if (!vtrig_row(x, sv, cv, {nv})) return 0;
    {fill}
    return 1;
}}
"""


def _batch_vector(prog: LoweredKernel, split: TrigSplit) -> str:
    k = prog.kernel
    table = split.table
    nin, nout = len(prog.in_names), len(prog.out_names)
    params = ["const double *restrict tv", "Py_ssize_t ts"]
    params += [f"const double *restrict in{i}" for i in range(nin)]
    params += [f"double *restrict out{i}" for i in range(nout)]
    ins = "; ".join(f"const double *restrict in{i} = inb{i} + (r0 + r) * is[{i}]" for i in range(nin))
    call = ", ".join([f"&tv[0][r], {TRIG_BLOCK}"] + [f"inb{i} + (r0 + r) * is[{i}]" for i in range(nin)]
                     + [f"outb{i} + (r0 + r) * os[{i}]" for i in range(nout)])
    # one reduction per argument gives its sine and cosine together (kin_prelude.h)
    slot = {(a, fn): t for t, (_, fn, a) in enumerate(table)}
    nargs = len(split.args)
    trig = "\n".join(
        f"        vtrig_sincos(ta[{a}], {_slot(slot, a, 'sin')}, {_slot(slot, a, 'cos')}, m);"
        for a in range(nargs))
    one_ins = [f"(const double *)in[{i}]" for i in range(nin)]
    one_call = ", ".join(["t1", "1"] + one_ins + [f"(double *)out[{i}]" for i in range(nout)])
    lanes = lane_row(split.row)
    rows = f"""        for (int r = 0; r < m; ++r)
            kv_{k.name}({call});"""
    tables, gather, lane_c = "", [], ""
    if lanes is not None:  # the rows side by side in vector lanes (derive/emit_c_lanes.py)
        lane_c = lane_loop(k.name, lanes, TRIG_BLOCK, len(table))
        tables = f", ti[{max(1, len(lanes.inputs))}][{TRIG_BLOCK}], to[{len(lanes.outputs)}][{TRIG_BLOCK}]"
        gather = lanes.gather() + lanes.prefetch()
        outs = " ".join(f"double *restrict o{o} = outb{o} + (r0 + r) * os[{o}];" for o in range(nout))
        rows = f"""        if (have_vector_trig512) kl_512_{k.name}(m, tv, ti, to);
        else kl_{k.name}(m, tv, ti, to);
        for (int r = 0; r < m; ++r) {{
            {outs}
            {" ".join(lanes.scatter())}
        }}"""
    return f"""
#ifdef RCCL_VECTOR_TRIG
/* {k.name} for batches: the row above with its sines and cosines precomputed */
static inline void kv_{k.name}({", ".join(params)})
{{
{split.row}
}}
{_one_row_trig(prog, split)}{lane_c}
/* blocks of {TRIG_BLOCK} rows: arguments, then every sine/cosine over the block (vector
 * lanes, kin_prelude.h), then the straight-line rows{" (side by side in vector lanes)" if lanes else ""} */
static int batch_vector_{k.name}(Py_ssize_t n, const double *const *in, const Py_ssize_t *is, double *const *out, const Py_ssize_t *os)
{{
    if (!have_vector_trig) return 0;
    if (n == 1) {{  /* one row: its sines and cosines side by side in vector lanes */
        double t1[{len(table)}];
        if (kv1_{k.name}({", ".join(one_ins + ["t1"])})) {{
            kv_{k.name}({one_call});
            return 1;
        }}
    }}
    {'; '.join(f'const double *inb{i} = (const double *)in[{i}]' for i in range(nin))};
    {'; '.join(f'double *outb{i} = out[{i}]' for i in range(nout))};
    double ta[{nargs}][{TRIG_BLOCK}], tv[{len(table)}][{TRIG_BLOCK}]{tables};
    for (Py_ssize_t r0 = 0; r0 < n; r0 += {TRIG_BLOCK}) {{
        const int m = n - r0 < {TRIG_BLOCK} ? (int)(n - r0) : {TRIG_BLOCK};
        for (int r = 0; r < m; ++r) {{
            {ins};
            {" ".join(split.stmts + gather)}
        }}
{trig}
{rows}
    }}
    return 1;
}}
#endif
"""


def kernel_c(prog: LoweredKernel, body: str) -> str:
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


def finite_by_construction(prog: LoweredKernel) -> bool:
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


def module_c(robot: str, programs: list[tuple[LoweredKernel, str]], command: str) -> str:
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


COMMAND = "make derive  (python -m derive)"


def lower_all(kernels: list[Kernel]) -> list[tuple[LoweredKernel, str]]:
    """The chosen program and its C body for every kernel and for ``ik_all``
    (derive.lowering.all_configurations_kernels): what the C and CasADi back ends print."""
    return [best_program(k) for k in list(kernels) + all_configurations_kernels(kernels)]


def emit(kernels: list[Kernel], programs: list[tuple[LoweredKernel, str]], robot: str, out_dir: Path) -> list[Path]:
    """Back-end entry of ``python -m derive``: ``out_dir/_c/<robot>.c`` and the op-count reports.

    ``programs`` is :func:`lower_all` of ``kernels``. The reports cover every generated C
    file present, so they are complete after the last robot. The extension is compiled by
    ``pip install`` (setup.py), not here.
    """
    out_dir = Path(out_dir)
    path = write_programs(robot, programs, out_dir / "_c", COMMAND)
    reports = out_dir.parent.parent / "reports"
    c_files = sorted((out_dir / "_c").glob("*.c"))
    opcount.write_reports(c_files, reports / "opcounts.md", reports / "opcounts.json", COMMAND)
    return [path, reports / "opcounts.md", reports / "opcounts.json"]


def write(robot: str, kernels: list[Kernel], out_dir: Path, command: str = "make derive") -> tuple[Path, list[tuple[LoweredKernel, str]]]:
    """Write ``out_dir/<robot>.c``; return its path and the chosen (program, body) per kernel."""
    programs = [best_program(k) for k in kernels]
    return write_programs(robot, programs, out_dir, command), programs


def write_programs(robot: str, programs: list[tuple[LoweredKernel, str]], out_dir: Path, command: str) -> Path:
    """Write ``out_dir/<robot>.c`` from chosen (program, body) pairs; return its path."""
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / f"{robot}.c"
    text = module_c(robot, programs, command)
    if not path.exists() or path.read_text() != text:
        path.write_text(text)
    return path
