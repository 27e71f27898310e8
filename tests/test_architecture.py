"""The house rules, read from the source (AST, nothing imported): no import circles, no
module reaching into another's private names, no big room without a reason, one name per
concept. tests/test_layers.py checks the floors (which package may import which).

An import counts wherever it is written: a function-level import is still a dependency, and
so is one under ``if TYPE_CHECKING:`` (an annotation-only import is a circle a type checker
and a reader walk round; the shared type belongs a floor down). Modules loaded by name
(``importlib``, the registry of calib/fits) are not edges. Exceptions to a rule are listed here with their reason.
"""
from __future__ import annotations

import ast
from collections import defaultdict
from functools import cache
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("models", "derive", "rci", "rccl", "calib", "view")
#: the folders installed under another name (setup.py's INSTALLED_AS): an import of the
#: installed name is an edge to the folder's module
INSTALLED_PREFIX = "rcci."
# written by `make derive`: one module per robot data file under models/
GENERATED = tuple(f"rccl/kinematics/{p.stem}.py" for p in sorted((ROOT / "models").glob("*.toml")))
LONG_LINES = 600
LONG_REASON = "Why this module is long:"

#: (module, private name) -> why the access is right
PRIVATE_EXCEPTIONS: dict[tuple[str, str], str] = {
    ("derive.emit_python", "_hprint_Pow"): "SymPy's printer API: a subclass overrides the printer's own hook",
    ("rccl.segments", "_replace"): "typing.NamedTuple's public copy-with-changes method (named so to avoid field clashes)",
}
#: class name -> why two modules define it (distinct concepts that share a name on purpose)
CLASS_NAME_EXCEPTIONS: dict[str, str] = {}


@cache
def _modules() -> dict[str, Path]:
    found = {}
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            rel = path.relative_to(ROOT).with_suffix("")
            found[".".join(rel.parts[:-1] if rel.name == "__init__" else rel.parts)] = path
    return found


@cache
def _tree(path: Path) -> ast.Module:
    return ast.parse(path.read_text(), str(path))


def _imported_names(name: str, path: Path) -> set[str]:
    """Dotted names ``name`` imports (module and module.attr), TYPE_CHECKING blocks included."""
    package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    out: set[str] = set()

    def visit(node: ast.AST) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.Import):
                out.update(a.name for a in child.names)
            elif isinstance(child, ast.ImportFrom):
                base = package[:len(package) - (child.level - 1)] if child.level else []
                module = ".".join(base + ([child.module] if child.module else []))
                for a in child.names:   # "from . import codes" imports the module rci.codes;
                    sub = f"{module}.{a.name}"      # "from rci import Session", the package rci
                    out.add(sub if sub in _modules() else module)
            visit(child)

    visit(_tree(path))
    return {n.removeprefix(INSTALLED_PREFIX) for n in out}


def _graph() -> dict[str, set[str]]:
    """Module -> the project modules it imports (each import resolved to the longest module name)."""
    mods = _modules()
    graph = {}
    for name, path in mods.items():
        deps = set()
        for imported in _imported_names(name, path):
            parts = imported.split(".")
            for k in range(len(parts), 0, -1):
                if ".".join(parts[:k]) in mods:
                    deps.add(".".join(parts[:k]))
                    break
        deps.discard(name)
        graph[name] = deps
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found = []
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            v, children = work[-1]
            for w in children:
                if w not in index:
                    index[w] = low[w] = len(index)
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(sorted(graph[w]))))
                    break
                if w in on_stack:
                    low[v] = min(low[v], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    component = []
                    while True:
                        w = stack.pop()
                        on_stack.discard(w)
                        component.append(w)
                        if w == v:
                            break
                    if len(component) > 1:
                        found.append(sorted(component))
    return found


def test_no_import_circles():
    cycles = _cycles(_graph())
    assert not cycles, "modules that import each other (directly or round a circle): " + "; ".join(
        " <-> ".join(c) for c in cycles)


def test_an_annotation_only_import_counts(tmp_path):
    """``if TYPE_CHECKING:`` imports are edges: a circle through one is still a circle."""
    path = tmp_path / "probe.py"
    path.write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from rccl.session import Arm\n")
    assert "rccl.session" in _imported_names("calib.probe", path)


def test_the_circle_finder_finds_a_circle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []


def _own_names(tree: ast.Module) -> set[str]:
    """Names a module defines or assigns anywhere (its own privates, its classes' attributes)."""
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store):
            names.add(node.attr)
        elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
            names.add(node.id)
        elif isinstance(node, ast.arg):
            names.add(node.arg)
        elif isinstance(node, ast.alias):
            names.add(node.asname or node.name.split(".")[0])
    return names


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _private_uses(name: str, path: Path) -> list[tuple[int, str]]:
    """``from m import _x`` of another module, and ``obj._x`` where ``_x`` is none of this
    module's own names and ``obj`` is not ``self``/``cls``/``super()`` (a subclass using
    its base's protected state is the base's design)."""
    tree = _tree(path)
    own = _own_names(tree)
    uses = []
    package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            base = package[:len(package) - (node.level - 1)] if node.level else []
            module = ".".join(base + ([node.module] if node.module else []))
            uses += [(node.lineno, f"from {module} import {a.name}") for a in node.names
                     if _private(a.name) and module != name]
        elif isinstance(node, ast.Attribute) and _private(node.attr) and node.attr not in own:
            base = node.value
            if isinstance(base, ast.Name) and base.id in ("self", "cls"):
                continue
            if isinstance(base, ast.Call) and isinstance(base.func, ast.Name) and base.func.id == "super":
                continue
            uses.append((node.lineno, ast.unparse(node)))
    return [(line, text) for line, text in uses
            if (name, text.rsplit(".", 1)[-1].split(" ")[-1]) not in PRIVATE_EXCEPTIONS]


def test_no_module_reads_another_modules_private_names():
    bad = [f"{path.relative_to(ROOT)}:{line}: {text}"
           for name, path in _modules().items() for line, text in _private_uses(name, path)]
    assert not bad, "private names used across modules:\n" + "\n".join(bad)


def test_no_big_room_without_a_reason():
    bad = []
    for path in _modules().values():
        rel = path.relative_to(ROOT).as_posix()
        if rel in GENERATED:
            continue
        lines = len(path.read_text().splitlines())
        doc = ast.get_docstring(_tree(path)) or ""
        if lines > LONG_LINES and LONG_REASON not in doc:
            bad.append(f"{rel}: {lines} lines")
    assert not bad, (f"modules over {LONG_LINES} lines whose docstring gives no '{LONG_REASON}': "
                     + ", ".join(bad))


def test_one_class_name_per_concept():
    where = defaultdict(list)
    for name, path in _modules().items():
        for node in _tree(path).body:
            if isinstance(node, ast.ClassDef):
                where[node.name].append(name)
    clashes = {cls: mods for cls, mods in where.items() if len(mods) > 1 and cls not in CLASS_NAME_EXCEPTIONS}
    assert not clashes, "class names defined in more than one module: " + "; ".join(
        f"{cls} in {', '.join(mods)}" for cls, mods in sorted(clashes.items()))


def test_every_package_names_its_errors_module_alike():
    """Each package keeps its exception classes in ``exceptions.py`` (never ``errors.py``)."""
    odd = [p.relative_to(ROOT).as_posix() for pkg in PACKAGES for p in (ROOT / pkg).rglob("errors.py")]
    assert not odd, "errors modules not named exceptions.py: " + ", ".join(odd)
