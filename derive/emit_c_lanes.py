"""The rows of a batched block computed side by side in vector lanes.

The batched path of a kernel (``derive.emit_c``) computes a block's sines and cosines a
vector at a time; this module turns the rest of the row, its straight-line arithmetic,
into a loop over the block's rows that the C compiler vectorises: every value the row
reads or writes sits in a block table indexed ``[element][row]`` (structure of arrays),
so the loop body is the row itself with unit-stride loads and stores, and the compiler
computes four rows per AVX2 instruction or eight per AVX-512 one.

The block's inputs are copied into the table ``ti`` by the loop that already gathers the
trig arguments, and the outputs copied out of ``to`` after the lane loop; both copies are
with the caller's strides, so broadcast and strided arguments take this path too.

Every operation of the row (+, -, *, /, fabs, sqrt) is correctly rounded lane by lane, and
the lane loop is compiled without fused multiply-adds, so a row gives the same bits here as
in the one-row path. A row that calls anything else (atan2: no vector form in the C
library) keeps the row-at-a-time loop.
"""
from __future__ import annotations

import re
from dataclasses import dataclass

#: calls a row may make and still be computed in vector lanes
LANE_FUNCS = {"fabs", "sqrt"}

_CALL = re.compile(r"\b([A-Za-z_]\w*)\s*\(")
_INPUT = re.compile(r"\bin(\d+)\[(\d+)\]")
_OUTPUT = re.compile(r"^(\s*)out(\d+)\[(\d+)\] = ")
_OUT_READ = re.compile(r"\bout(\d+)\[(\d+)\]")
_TRIG = re.compile(r"\btv\[(\d+) \* ts\]")
_DEFINES = re.compile(r"^\s*const double (\w+) = ")


@dataclass(frozen=True)
class LaneRow:
    """A kernel's row as a lane loop, with the block tables it reads and writes."""

    body: str                            # the loop body: the row on tv[t][r], ti[j][r], to[j][r]
    inputs: list[tuple[int, int]]        # ti[j] holds input in{i}[e]: (i, e) for j = 0, 1, ...
    outputs: list[tuple[int, int]]       # to[j] goes to output out{o}[e]: (o, e) for j = 0, 1, ...

    def gather(self) -> list[str]:
        """Statements for row r of the block's argument loop: ti[j][r] = in{i}[e]."""
        return [f"ti[{j}][r] = in{i}[{e}];" for j, (i, e) in enumerate(self.inputs)]

    def prefetch(self) -> list[str]:
        """Statements for row r of the argument loop: the row's results' cache lines fetched
        for writing (every 8 doubles, and the last), so that the copy-out after the block's
        arithmetic does not wait on memory (a 1e6-row fk: 16 -> 9 ns a row)."""
        size: dict[int, int] = {}
        for o, e in self.outputs:
            size[o] = max(size.get(o, 0), e + 1)
        stmts = []
        for o, n in sorted(size.items()):
            stmts.append(f"double *p{o} = outb{o} + (r0 + r) * os[{o}];")
            stmts += [f"__builtin_prefetch(p{o} + {e}, 1);" for e in sorted({*range(0, n, 8), n - 1})]
        return stmts

    def scatter(self) -> list[str]:
        """Statements for row r of the copy-out loop: o{o}[e] = to[j][r] (o{o}: output o at row r)."""
        return [f"o{o}[{e}] = to[{j}][r];" for j, (o, e) in enumerate(self.outputs)]


def _live_lines(lines: list[str]) -> list[str]:
    """The lines without definitions that no other line reads (the row's trig-argument sums:
    their values now come from tv)."""
    while True:
        text = "\n".join(lines)
        dead = [ln for ln in lines
                if (m := _DEFINES.match(ln)) and len(re.findall(rf"\b{m.group(1)}\b", text)) == 1]
        if not dead:
            return lines
        lines = [ln for ln in lines if ln not in dead]


def lane_row(row: str) -> LaneRow | None:
    """``row`` (the batched row reading its sines and cosines from ``tv[t * ts]``) as a lane
    loop body (an output the row reads back is read from ``to``); None when the row calls a
    function without a vector form, or reads an output before writing it."""
    if set(_CALL.findall(row)) - LANE_FUNCS:
        return None
    lines = _live_lines(row.splitlines())
    used = sorted({(int(i), int(e)) for ln in lines for i, e in _INPUT.findall(ln)})
    inputs = {ie: j for j, ie in enumerate(used)}
    outputs: dict[tuple[int, int], int] = {}
    body = []
    for ln in lines:
        out = _OUTPUT.match(ln)
        rhs = ln[out.end():] if out else ln
        reads = {(int(o), int(e)) for o, e in _OUT_READ.findall(rhs)}
        if not reads <= outputs.keys():  # an output read before it is written
            return None
        rhs = _OUT_READ.sub(lambda m: f"to[{outputs[int(m[1]), int(m[2])]}][r]", rhs)
        rhs = _TRIG.sub(r"tv[\1][r]", rhs)
        rhs = _INPUT.sub(lambda m: f"ti[{inputs[int(m[1]), int(m[2])]}][r]", rhs)
        if out:
            key = (int(out[2]), int(out[3]))
            if key in outputs:
                return None
            outputs[key] = len(outputs)
            ln = f"{out[1]}to[{outputs[key]}][r] = {rhs}"
        else:
            ln = rhs
        body.append("    " + ln)
    return LaneRow("\n".join(body), list(inputs), list(outputs))


def lane_loop(name: str, lr: LaneRow, block: int, n_trig: int) -> str:
    """The C of the lane loops of kernel ``name``: the loop once, inlined into one function
    compiled for AVX2 (four rows at a time) and one for AVX-512F (eight); no fused
    multiply-adds in either (the prelude's fp-contract=off, and AVX2 without the FMA target)."""
    params = (f"int m, const double (*restrict tv)[{block}], const double (*restrict ti)[{block}], "
              f"double (*restrict to)[{block}]")
    wrappers = "\n".join(
        f'__attribute__((target("{target}"))) static void kl{suffix}_{name}({params}) {{ kl_rows_{name}(m, tv, ti, to); }}'
        for suffix, target in (("", "avx2"), ("_512", "avx512f")))
    return f"""
/* {name}'s rows side by side in vector lanes: the block's {n_trig} sines/cosines in tv, its
 * {len(lr.inputs)} input elements in ti, its {len(lr.outputs)} results to (derive/emit_c_lanes.py) */
__attribute__((always_inline)) static inline void kl_rows_{name}({params})
{{
    for (int r = 0; r < m; ++r) {{
{lr.body}
    }}
}}
{wrappers}
"""
