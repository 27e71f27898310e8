"""Operation counts read from the emitted C text (not from SymPy's idea of the expression).

``count_ops`` tokenises the statements of a kernel body and counts

* ``mul_div``: binary ``*`` and ``/``;
* ``add_sub``: binary ``+`` and ``-`` plus unary minus (a negation costs an FP op too;
  ``neg`` says how many of ``add_sub`` are negations);
* ``trig``: calls of sin, cos, tan, atan2, atan, asin, acos;
* ``sqrt`` and ``other`` (fabs, fmin, fmax, exp, log) calls, listed apart; a comparison
  (``<``, ``>``: the sign of eq. 4.27's friction) counts as ``other`` too.

``write_reports`` produces ``reports/opcounts.md`` and ``reports/opcounts.json`` from the
generated C files, with the thesis figures (Table 3.3, section 6.1) beside them.
"""
from __future__ import annotations

import json
import re
from pathlib import Path

TRIG = {"sin", "cos", "tan", "atan2", "atan", "asin", "acos"}
OTHER = {"fabs", "fmin", "fmax", "exp", "log"}

_TOKEN = re.compile(
    r"\s*(?:(?P<num>(?:\d+\.\d*|\.\d+|\d+)(?:[eE][+-]?\d+)?)|(?P<id>[A-Za-z_]\w*)|(?P<op>[-+*/=(),;\[\]<>]))")
_KERNEL = re.compile(r"/\* BEGIN KERNEL (?P<robot>\w+)\.(?P<name>\w+) \*/\n(?P<body>.*?)/\* END KERNEL", re.S)


def tokens(text: str) -> list[tuple[str, str]]:
    """(kind, text) tokens of C statements; kind is num, id or op."""
    out, pos = [], 0
    text = text.strip()
    while pos < len(text):
        m = _TOKEN.match(text, pos)
        if not m or m.end() == pos:
            raise ValueError(f"opcount: cannot tokenise C near {text[pos:pos + 30]!r}")
        kind = m.lastgroup
        out.append((kind, m.group(kind)))
        pos = m.end()
    return out


_COMMENT = re.compile(r"/\*.*?\*/", re.S)
_STMT = re.compile(r"^\s*(?:const double\s+)?(?P<lhs>[A-Za-z_]\w*(?:\[\d+\])?)\s*=\s*(?P<rhs>.*);\s*$")
_REF = re.compile(r"[A-Za-z_]\w*(?:\[\d+\])?")
GUARD_MARK = "/* guards:"


def without_guards(body: str) -> str:
    """The statements a kernel needs for its main outputs only (guards sliced away).

    Guard statements follow the ``/* guards: ... */`` marker; temporaries only the guards
    use are dropped by following the dependencies back from the main outputs.
    """
    head, sep, _ = body.partition(GUARD_MARK)
    if not sep:
        return body
    stmts = []
    for line in head.splitlines():
        m = _STMT.match(line)
        if m:
            stmts.append((m["lhs"], m["rhs"], line))
    defined = {lhs: (rhs, line) for lhs, rhs, line in stmts}
    need = {lhs for lhs, _, _ in stmts if lhs.startswith("out")}
    stack = list(need)
    while stack:
        rhs, _ = defined[stack.pop()]
        for ref in _REF.findall(rhs):
            if ref in defined and ref not in need:
                need.add(ref)
                stack.append(ref)
    return "\n".join(line for lhs, _, line in stmts if lhs in need)


def count_ops(body: str) -> dict[str, int]:
    """Count the floating-point operations in the statements of one kernel body."""
    c = {"mul_div": 0, "add_sub": 0, "neg": 0, "trig": 0, "sqrt": 0, "other": 0}
    toks = tokens(_COMMENT.sub("", body))
    prev: tuple[str, str] | None = None
    for i, (kind, t) in enumerate(toks):
        if kind == "op" and t in "*/":
            c["mul_div"] += 1
        elif kind == "op" and t in "<>":
            c["other"] += 1
        elif kind == "op" and t in "+-":
            # unary when it follows an operator or an opening bracket (or starts the text)
            unary = prev is None or (prev[0] == "op" and prev[1] in "=(,*/+-[<>")
            if unary and t == "+":
                pass
            else:
                c["add_sub"] += 1
                c["neg"] += unary
        elif kind == "id" and i + 1 < len(toks) and toks[i + 1] == ("op", "("):
            if t in TRIG:
                c["trig"] += 1
            elif t == "sqrt":
                c["sqrt"] += 1
            elif t in OTHER:
                c["other"] += 1
            else:
                raise ValueError(f"opcount: unknown function {t!r} in emitted C")
        prev = (kind, t)
    return c


#: throughput cost in cycles of one scalar double operation on current x86-64 cores (Intel
#: Ice Lake / Sapphire Rapids, AMD Zen 3/4: two adds or multiplies per cycle, one division
#: every 4-5 cycles, latency 13-15): what ``cycles`` weighs a kernel's operations by
CYCLES_ADD_MUL = 0.5
CYCLES_DIV = 4.0


def divisions(body: str) -> int:
    """The binary ``/`` of a kernel body (counted in ``mul_div`` with the products)."""
    return sum(1 for kind, t in tokens(_COMMENT.sub("", body)) if kind == "op" and t == "/")


def cycles(body: str) -> float:
    """Throughput estimate of a kernel body's arithmetic in cycles (sines, cosines and other
    calls left out): additions and multiplications at CYCLES_ADD_MUL, divisions at CYCLES_DIV."""
    c = count_ops(body)
    d = divisions(body)
    return CYCLES_ADD_MUL * (c["add_sub"] + c["mul_div"] - d) + CYCLES_DIV * d


_ANGLE_SUM = re.compile(r"^\s*const double x_\d+\s*=\s*(?P<rhs>in0\[\d+\](?:\s*[-+]\s*in0\[\d+\])+);\s*$")


def angle_sums(body: str) -> int:
    """The additions that only form a sum of joint angles for sin/cos (theta2 + theta3 of
    the thesis's S23, C23); counted in add_sub like any other, reported apart."""
    return sum(count_ops(m["rhs"])["add_sub"] for m in map(_ANGLE_SUM.match, body.splitlines()) if m)


#: the comment emit_c.py writes above each kernel; its lowering names the variant chosen
#: and, for a transform, what the other choices of the rebuilt column (3.3) counted
_HEADER = re.compile(r"/\* (?P<robot>\w+)\.(?P<name>\w+): .*; lowering: (?P<lowering>[^\n]*)\) \*/\n")


def count_file(path: Path) -> list[dict]:
    """One record per kernel found between the BEGIN/END KERNEL markers of a C file."""
    rows = []
    text = Path(path).read_text()
    tried = {(m["robot"], m["name"]): m["lowering"].partition("; columns tried (mul/add): ")[2]
             for m in _HEADER.finditer(text)}
    for m in _KERNEL.finditer(text):
        row = {"robot": m["robot"], "kernel": m["name"], **count_ops(m["body"]),
               "angle_sum": angle_sums(without_guards(m["body"]))}
        if tried.get((m["robot"], m["name"])):
            row["columns_tried"] = tried[(m["robot"], m["name"])]
        if GUARD_MARK in m["body"]:
            bare = count_ops(without_guards(m["body"]))
            row.update({f"{k}_without_guards": bare[k] for k in ("mul_div", "add_sub", "neg", "trig")})
        rows.append(row)
    return rows


#: Thesis figures (multiplications/divisions, additions), trig calls excluded.
#: Table 3.3 gives best/worst cases over the four Jacobian computations (3.71-3.74 and
#: 3.75-3.78) in link 4; section 3.8 adds 8 mul + 4 add for each D/F map of (3.79) to
#: frame 6. Section 6.1: RCCL's forward kinematics, 41 mul/div and 17 additions.
THESIS = {
    ("puma260", "jacobian_best"): (41, 23, "Table 3.3, PUMA 260 best case"),
    ("puma260", "jacobian_worst"): (46, 23, "Table 3.3, PUMA 260 worst case"),
    ("microbo", "jacobian_best"): (24, 13, "Table 3.3, Microbo best case"),
    ("microbo", "jacobian_worst"): (31, 15, "Table 3.3, Microbo worst case"),
    ("puma260", "fk"): (41, 17, "section 6.1, RCCL forward kinematics"),
    "frame_map": (8, 4, "section 3.8: each transform of (3.79)"),
}


def thesis_figure(robot: str, kernel: str) -> tuple[int, int, str] | None:
    """The thesis bound a kernel is compared against, or None.

    Frame-4 Jacobian computations are held to the worst case of Table 3.3; frame-6 ones
    to that plus one D/F map of (3.79) (8 mul, 4 add); forward kinematics to 6.1.
    """
    name = kernel.lower()
    if name == "fk" or name.startswith("fk"):
        return THESIS.get((robot, "fk"))
    jac = ("cartesian_from_joint", "torque_from_force", "joint_from_cartesian", "force_from_torque")
    if any(name.startswith(j) for j in jac):
        worst = THESIS.get((robot, "jacobian_worst"))
        if worst is None:
            return None
        if name.endswith("6"):
            fm = THESIS["frame_map"]
            return worst[0] + fm[0], worst[1] + fm[1], worst[2] + " + one map of (3.79)"
        return worst
    return None


def write_reports(c_files: list[Path], md_path: Path, json_path: Path, command: str = "make derive") -> list[dict]:
    """Write the Markdown and JSON op-count reports; return the records.

    A kernel with guards is compared with the thesis on the statements its main outputs
    need (``*_without_guards``): the thesis's computations had no domain checks.
    """
    rows = []
    for f in c_files:
        rows.extend(count_file(f))
    for r in rows:
        th = thesis_figure(r["robot"], r["kernel"])
        if th:
            md = r.get("mul_div_without_guards", r["mul_div"])
            ad = r.get("add_sub_without_guards", r["add_sub"])
            r["thesis_mul_div"], r["thesis_add_sub"], r["thesis_source"] = th
            r["at_or_below_thesis"] = md <= th[0] and ad <= th[1]
            r["excess_mul_div"], r["excess_add_sub"] = max(0, md - th[0]), max(0, ad - th[1])
    json_path.parent.mkdir(parents=True, exist_ok=True)
    _write_if_changed(json_path, json.dumps(rows, indent=1) + "\n")
    lines = [
        "# Operation counts of the generated C kernels",
        "",
        f"Regenerated by `{command}`: derive/opcount.py counts the operators in the emitted C",
        "(`rccl/kinematics/_c/<robot>.c`, between each kernel's BEGIN/END KERNEL markers),",
        "not SymPy's idea of the expression. Machine-readable: `reports/opcounts.json`.",
        "",
        "How counting is done (the same rules for every row, thesis rows included):",
        "",
        "- mul/div: every binary `*` and `/` in the C text, multiplications by constants",
        "  (link lengths, 1/d4) included; a constant folded at generation time (0.2032*0.12624",
        "  written as one number) costs nothing.",
        "- add/sub: every binary `+` and `-`, and every unary minus (a negation is an FP",
        "  operation too); in brackets, how many of them are negations and how many only form",
        "  a sum of joint angles for sin/cos (`x_0 = q2 + q3`, the argument of the thesis's",
        "  S23/C23). Neither is left out of the comparison.",
        "- trig: sin, cos, tan, atan2, asin, acos calls; sqrt and other calls (fabs, fmax)",
        "  apart. Like the thesis (\"excluding trigonometric function calls\"), mul/div and",
        "  add/sub exclude the function calls themselves.",
        "- Kernels with guards (domain checks the thesis did not have) list the count of the",
        "  whole kernel and, after the slash, of the statements the outputs alone need; the",
        "  latter is compared with the thesis.",
        "",
        "Thesis figures and what they are compared with:",
        "",
        "- Table 3.3: the four Jacobian computations in link 4 (3.71-3.78); PUMA 260 worst",
        "  case 46 mul/div and 23 additions (best 41/23), Microbo 31/15 (best 24/13). Each",
        "  frame-4 kernel is held to the worst case.",
        "- Frame 6 (3.79): Table 3.3 plus the 8 mul and 4 additions section 3.8 gives for a",
        "  transform of (3.79). Those 8/4 are what B of 3.81/3.82 costs on ONE 3-vector",
        "  (two plane rotations, by theta5 and theta6, of 4 mul and 2 additions each); a D or F",
        "  map of (3.80) applies B to both halves of the 6-vector, 16 mul and 8 additions,",
        "  which is what the PUMA frame-6 kernels spend on it, plus one negation where B's",
        "  signs leave a sum of two negative terms (the halves are independent, so neither",
        "  half's work can be shared). The frame-6 rows are still held to the thesis's worst",
        "  case + 8/4.",
        "- Section 6.1: RCCL's forward kinematics, 41 mul/div and 17 additions; the thesis",
        "  does not say whether RCCL's 17 include negations or the theta2 + theta3 argument.",
        "  Ours counts both (19 = 17 + the angle sum + one negation), and we found no way",
        "  to drop either: S23 and C23 from S2, C2, S3, C3 cost two additions instead of one;",
        "  in the PUMA 260's frames every term of a_y = -S1 C23 C4 S5 - S1 S23 C5 - C1 S4 S5",
        "  is negative (tests/test_derive.py checks the derived T6), so an a column formed",
        "  from products of sines and cosines needs one sign change, or extra subtractions",
        "  whose terms cancel; rebuilding a (or n) by a cross product instead costs more.",
        "  What each choice of the rebuilt column counted at best (from the generated C's",
        "  lowering comments):",
        *[f"  {r['robot']} {r['kernel']}: {r['columns_tried']}." for r in rows if r.get("columns_tried")],
        "- The frame-4 and frame-6 Jacobian computations are emitted the way 3.73/3.74 are",
        "  written: substitution in the block-triangular 4J' (its top block observed in frame",
        "  3 is triangular), not a product with the expanded inverse 3.68; forward",
        "  kinematics one run of A matrices at a time (A1 | A2 A3 | A4 A5 A6), with one",
        "  rotation column a cross product of the other two (3.3). The lowering keeps such a",
        "  structure only where it counts fewer operations than the expanded expressions.",
        "- `ik_all` is `ik` for every configuration in one kernel (shared subexpressions).",
        "",
        "| robot | kernel | mul/div | add/sub (neg, angle sums) | trig | sqrt | other | thesis mul/div, add | at or below |",
        "|---|---|---:|---:|---:|---:|---:|---|---|",
    ]
    for r in rows:
        md = f"{r['mul_div']}" + (f" / {r['mul_div_without_guards']}" if "mul_div_without_guards" in r else "")
        ad = f"{r['add_sub']} ({r['neg']}, {r['angle_sum']})" + (
            f" / {r['add_sub_without_guards']}" if "add_sub_without_guards" in r else "")
        th = f"{r['thesis_mul_div']}, {r['thesis_add_sub']} ({r['thesis_source']})" if "thesis_source" in r else ""
        if "thesis_source" not in r:
            ok = ""
        elif r["at_or_below_thesis"]:
            ok = "yes"
        else:
            ok = f"**no** (+{r['excess_mul_div']} mul/div, +{r['excess_add_sub']} add/sub)"
        lines.append(f"| {r['robot']} | {r['kernel']} | {md} | {ad} | {r['trig']} | {r['sqrt']} | {r['other']} | {th} | {ok} |")
    _write_if_changed(md_path, "\n".join(lines) + "\n")
    return rows


def _write_if_changed(path: Path, text: str) -> None:
    if not path.exists() or path.read_text() != text:
        path.write_text(text)
