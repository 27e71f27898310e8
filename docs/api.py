"""Build the API reference (HTML, pdoc) from the docstrings, and fail on a broken reference: ``make docs``.

    .venv/bin/python docs/api.py                 # writes docs/api/index.html (not committed)
    .venv/bin/python docs/api.py --out /tmp/api  # elsewhere

Every module of the installed packages ``rcci.models``, ``rci``, ``rccl``, ``rcci.calib`` and ``rcci.view`` gets a page
(``__main__`` modules, which run a program when imported, are left out). The build fails
(exit 1, each problem named) when pdoc cannot import a module or warns, when a page links to a
page or anchor that does not exist, or when a docstring names a project object in backticks
(```rci.recorder.Recorder```, ```Recorder.flush```) that does not exist, so a rename that
leaves a docstring behind is caught (tests/test_api_docs.py).
"""
from __future__ import annotations

import argparse
import gc
import html
import importlib
import pkgutil
import re
import sys
import warnings
from pathlib import Path

PACKAGES = ("rcci.models", "rci", "rccl", "rcci.calib", "rcci.view")
ROOT = Path(__file__).resolve().parent.parent


def modules(packages: tuple[str, ...] = PACKAGES) -> list[str]:
    """Every module of ``packages``, each package before its modules, without ``__main__`` modules."""
    out = []
    for name in packages:
        pkg = importlib.import_module(name)
        out.append(name)
        for info in pkgutil.walk_packages(pkg.__path__, prefix=name + "."):
            if info.name.rsplit(".", 1)[-1] != "__main__":
                out.append(info.name)
    return out


_HREF = re.compile(r'href="([^"#:]*\.html)?(?:#([^"]*))?"')
_ID = re.compile(r'id="([^"]+)"')


def _code_names(packages: tuple[str, ...]) -> re.Pattern:
    """A name of ``packages`` in backticks that pdoc did not link (a name it links becomes <a>, without <code>)."""
    return re.compile(r"<code>((?:%s)(?:\.[A-Za-z_][A-Za-z0-9_]*)+)</code>" % "|".join(map(re.escape, packages)))


def check(out: Path, packages: tuple[str, ...] = PACKAGES) -> list[str]:
    """Broken links, and names of ``packages`` that name nothing, in the built pages under ``out``."""
    problems = []
    out = out.resolve()                  # links are resolved to absolute paths below
    code = _code_names(tuple(packages) + tuple(p for p in PACKAGES if p not in packages))
    pages = {p: p.read_text(encoding="utf-8") for p in out.rglob("*.html")}
    ids = {p: set(_ID.findall(text)) for p, text in pages.items()}
    for page, text in pages.items():
        for target, anchor in _HREF.findall(text):
            dest = (page.parent / target).resolve() if target else page
            if target and dest not in pages:
                problems.append(f"{page.relative_to(out)}: link to a missing page {target}")
            elif anchor and dest in ids and html.unescape(anchor) not in ids[dest]:
                problems.append(f"{page.relative_to(out)}: link to a missing anchor {target}#{anchor}")
        for name in sorted(set(code.findall(text))):
            if not _resolves(name):
                problems.append(f"{page.relative_to(out)}: `{name}` names nothing (a renamed or removed object?)")
    return problems


def _resolves(dotted: str) -> bool:
    """True when ``dotted`` is a module, or an attribute path inside one."""
    parts = dotted.split(".")
    for k in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:k]))
        except ImportError:
            continue
        for attr in parts[k:]:
            if not hasattr(obj, attr):
                # a dataclass field or an instance attribute set in __init__ is documented too
                annotations = getattr(obj, "__annotations__", {}) if isinstance(obj, type) else {}
                if attr in annotations:
                    obj = None
                    continue
                return False
            obj = getattr(obj, attr)
        return True
    return False


def build(out: Path, packages: tuple[str, ...] = PACKAGES) -> list[str]:
    """Write the pages of ``packages`` into ``out``; returns the problems (empty: a clean build)."""
    import pdoc
    import pdoc.render

    pdoc.render.configure(docformat="restructuredtext", footer_text="RCI/RCCL API reference: make docs",
                          search=True, show_source=False)
    names = modules(packages)
    import rci
    for lazy in rci.__all__:          # rci.open and rci.Session are imported on first use (rci.__getattr__)
        setattr(rci, lazy, getattr(rci, lazy))
    gc.collect()                      # what earlier code left to the collector is not the build's to report
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        pdoc.pdoc(*names, output_directory=out)
    problems, notes = [], []
    for w in caught:
        text = str(w.message)
        if issubclass(w.category, DeprecationWarning) or "has already been added" in text:
            continue                  # a package's spec adds its submodules, which are also listed: harmless
        # an annotation naming a type imported only for type checkers is shown as written; a
        # ResourceWarning is the collector finding some object's unclosed file, not a reference
        note = text.startswith("Error parsing type annotation") or issubclass(w.category, ResourceWarning)
        (notes if note else problems).append(f"pdoc: {text}")
    for n in notes:
        print(n, file=sys.stderr)
    return problems + check(out, packages)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="docs/api.py", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "api", help="output folder (default docs/api)")
    args = ap.parse_args(argv)
    problems = build(args.out)
    pages = len(list(args.out.rglob("*.html")))
    for p in problems:
        print(p, file=sys.stderr)
    if problems:
        print(f"docs/api.py: {len(problems)} problems in {pages} pages under {args.out}", file=sys.stderr)
        return 1
    print(f"wrote {pages} pages under {args.out}: open {args.out / 'index.html'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
