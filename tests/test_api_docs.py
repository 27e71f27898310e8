"""The API reference (issue 29, item 5): `make docs` (docs/api.py, pdoc) builds a page per module
from the docstrings and fails on a broken reference. Built here in three parts so that each
test stays short (`make docs` builds them together, linked across packages)."""
from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
spec = importlib.util.spec_from_file_location("docs_api", ROOT / "docs" / "api.py")
api = importlib.util.module_from_spec(spec)
spec.loader.exec_module(api)


@pytest.mark.parametrize("packages", [("rcci.models", "rci"), ("rccl",), ("rcci.calib", "rcci.view")], ids="+".join)
def test_the_api_reference_builds_without_a_broken_reference(packages, tmp_path):
    problems = api.build(tmp_path, packages)
    assert problems == [], "\n".join(problems)
    pages = {p.relative_to(tmp_path).as_posix() for p in tmp_path.rglob("*.html")}
    expected = {f"{m.replace('.', '/')}.html" for m in api.modules(packages)}
    assert expected <= pages, sorted(expected - pages)
    if "rci" in packages:
        page = (tmp_path / "rci" / "recorder.html").read_text()
        assert 'id="Recorder.flush"' in page and "on_write_error" in page
        assert 'id="open"' in (tmp_path / "rci.html").read_text()       # rci.open, imported on first use


def test_a_broken_reference_fails_the_build(tmp_path, monkeypatch):
    pkg = tmp_path / "src" / "apidoc_probe"
    pkg.mkdir(parents=True)
    (pkg / "__init__.py").write_text('"""A probe package.\n\nWrites with ``rci.recorder.Recorder`` '
                                     '(there), ``rci.recorder.NoSuchRecorder`` (renamed away) and '
                                     '``apidoc_probe.part.gone``."""\n')
    (pkg / "part.py").write_text('"""Part of the probe: ``apidoc_probe.part.kept`` is here."""\n\n\n'
                                 'def kept() -> int:\n    """One."""\n    return 1\n')
    monkeypatch.syspath_prepend(str(tmp_path / "src"))
    monkeypatch.chdir(tmp_path)
    problems = api.build(Path("out"), ("apidoc_probe",))           # relative, as `make docs` gives it
    named = "\n".join(problems)
    assert len(problems) == 2, named
    assert "rci.recorder.NoSuchRecorder" in named and "apidoc_probe.part.gone" in named
    assert "`rci.recorder.Recorder`" not in named and "apidoc_probe.part.kept" not in named
    sys.modules.pop("apidoc_probe", None)
    sys.modules.pop("apidoc_probe.part", None)
