"""The floors of the house, read from the source (AST, no imports executed).

``models`` (the robot description) is the ground floor: it imports none of the project's
other packages. ``derive`` and ``rci`` stand on it and not on each other; ``rccl`` and
``calib`` stand above. A package may import only from its own floor or below (``calib``
uses ``rccl``'s kinematics and calibrated arm, which share its floor). The 3D view (``view``,
installed as ``rcci.view``) is the top floor: it shows rci's logs and rccl's plans, and nothing
imports it (a viewed process feeds it through ``rci.view_link``).

Each file is parsed once for the whole module (``_import_statements``, a cache that
tests/conftest.py empties when the module ends): the four tests used to parse every file again,
the generated kinematics among them, 9-12 s each in the suite at load 8.
"""
from __future__ import annotations

import ast
import functools
from pathlib import Path
from typing import NamedTuple

ROOT = Path(__file__).resolve().parent.parent
FLOOR = {"models": 0, "derive": 1, "rci": 1, "rccl": 2, "calib": 2, "view": 3}
#: models, calib and view are installed as rcci.models, rcci.calib and rcci.view (setup.py): imports use those names
INSTALLED_PREFIX = "rcci."
INSTALLED_ELSEWHERE = ("models", "calib", "view")
#: same-floor imports that are part of the design
ALLOWED_SIDEWAYS = {("calib", "rccl")}


class ImportStatement(NamedTuple):
    """One ``import a, b`` (``module`` None, ``level`` 0) or ``from .module import a, b`` of a file."""

    lineno: int
    names: tuple[str, ...]
    module: str | None
    level: int


@functools.cache
def _import_statements(path: Path) -> tuple[ImportStatement, ...]:
    """Every import statement of ``path``, at any depth (only these are kept, not the tree)."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out.append(ImportStatement(node.lineno, tuple(a.name for a in node.names), None, 0))
        elif isinstance(node, ast.ImportFrom):
            out.append(ImportStatement(node.lineno, tuple(a.name for a in node.names), node.module, node.level))
    return tuple(out)


def _is_from(st: ImportStatement) -> bool:
    return st.module is not None or st.level > 0


def _imports(path: Path, module: str) -> set[str]:
    """Absolute names of the project modules that ``path`` (module ``module``) imports."""
    package = module.split(".") if path.name == "__init__.py" else module.split(".")[:-1]
    out: set[str] = set()
    for st in _import_statements(path):
        if not _is_from(st):
            out.update(st.names)
        elif st.level:
            base = package[:len(package) - (st.level - 1)]
            out.add(".".join(base + ([st.module] if st.module else [])))
        elif st.module:
            out.add(st.module)
    out = {name.removeprefix(INSTALLED_PREFIX) for name in out}
    return {name for name in out if name.split(".")[0] in FLOOR}


def _graph() -> dict[str, set[str]]:
    """Package -> the project packages its modules import."""
    graph: dict[str, set[str]] = {pkg: set() for pkg in FLOOR}
    for pkg in FLOOR:
        for path in (ROOT / pkg).rglob("*.py"):
            rel = path.relative_to(ROOT).with_suffix("")
            module = ".".join(rel.parts[:-1] if rel.name == "__init__" else rel.parts)
            graph[pkg].update(name.split(".")[0] for name in _imports(path, module))
        graph[pkg].discard(pkg)
    return graph


def test_no_package_imports_a_higher_floor_or_sideways():
    bad = [f"{pkg} -> {dep}" for pkg, deps in _graph().items() for dep in sorted(deps)
           if FLOOR[dep] > FLOOR[pkg] or (FLOOR[dep] == FLOOR[pkg] and (pkg, dep) not in ALLOWED_SIDEWAYS)]
    assert not bad, "imports against the layering: " + ", ".join(bad)


def test_the_robot_description_is_the_ground_floor():
    graph = _graph()
    assert graph["models"] == set()
    assert graph["derive"] == {"models"}
    assert "models" in graph["rci"] and "models" in graph["rccl"] and "models" in graph["calib"]


def test_no_module_of_the_project_imports_the_old_robot_model_path():
    """``rci.robot_model`` stays for users' programs; the project's own code uses ``models``."""
    users = []
    for pkg in (*FLOOR, "bench", "examples"):
        for path in (ROOT / pkg).rglob("*.py"):
            if path == ROOT / "rci" / "robot_model.py":
                continue
            for st in _import_statements(path):
                if _is_from(st) and st.module and st.module.endswith("robot_model"):
                    users.append(str(path.relative_to(ROOT)))
    assert not users, users


def test_the_project_imports_its_folders_by_their_installed_names():
    """``models`` and ``calib`` are installed as ``rcci.models`` and ``rcci.calib``: an import of the
    bare folder name works only from the repository's root, and would put a second copy of the
    package beside the installed one (its exceptions then not caught as themselves)."""
    bare = []
    for top in (*FLOOR, "bench", "examples", "tests", "docs"):
        for path in (ROOT / top).rglob("*.py"):
            for st in _import_statements(path):
                names = (list(st.names) if not _is_from(st) else [st.module] if st.module and not st.level else [])
                bare += [f"{path.relative_to(ROOT)}:{st.lineno} {n}" for n in names
                         if n.split(".")[0] in INSTALLED_ELSEWHERE]
    assert not bare, "imports of a folder by a name that is not installed: " + ", ".join(bare)
