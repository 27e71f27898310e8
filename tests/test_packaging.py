"""Packaging outside the tree: build the wheel, install it into a fresh venv, and from another
directory run the installed ``simula -p`` and a short RCCL move against it.

The fresh venv gets the project's dependencies (pin, casadi, numpy, ...) from the test
venv's site-packages through ``.pth`` files (what ``--system-site-packages`` does for a
system Python), so nothing is downloaded and the test stays fast; the project itself comes only from the wheel:
the script checks that ``rcci.models``, ``rci`` and ``rccl`` load from the fresh venv and that
the robot files are found as package data. The wheel adds no generic top-level name
(``models``, ``calib``, ``derive``, ``bench``): the repository's ``models/`` and ``calib/`` are
installed as ``rcci.models`` and ``rcci.calib``.

The C kernels are compiled once per checkout, by `make venv` (the editable install runs the same
setup.py and its ``OptionalBuildExt``); the wheel build reuses those already compiled from the
same sources (``_reuse_compiled_kernels``: setuptools' build_ext skips an extension whose output
is newer than its sources and headers) instead of compiling all five again: that second compile
was 197 of this test's 200 s in the suite at load 8. A kernel whose source changed since, or that
was never compiled, is compiled here as before.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
import textwrap
import time
import venv
import zipfile
from pathlib import Path


ROOT = Path(__file__).resolve().parent.parent
#: what the source copy leaves out: local builds, venvs, caches, VCS
IGNORE = shutil.ignore_patterns(".git", ".venv", "build", "*.egg-info", "__pycache__", "*.so",
                                ".pytest_cache", ".hypothesis", "tmp")

CLIENT = textwrap.dedent('''
    import sys
    from pathlib import Path

    import numpy as np

    import rcci.models, rccl, rci
    from rccl import EQ, T6, TL, Trsf, makeposition
    from rccl.kinematics import puma260 as kin
    from rci.simula.process import ToolProcess

    prefix = Path(sys.prefix).resolve()
    for mod in (rcci.models, rci, rccl):
        where = Path(mod.__file__).resolve()
        assert prefix in where.parents, f"{mod.__name__} loaded from {where}, not from {prefix}"
    for generic in ("models", "calib", "derive", "bench"):
        try:
            __import__(generic)
        except ImportError:
            continue
        raise AssertionError(f"the installed project provides a top-level {generic!r}")
    data = rcci.models.models_dir()
    assert prefix in data.parents and (data / "puma260.toml").is_file() \\
        and (data / "urdf" / "puma260.urdf").is_file() and (data / "collision" / "puma260.toml").is_file(), \
        f"robot files not in the wheel: {data}"

    simula = str(Path(sys.executable).parent / "simula")
    goal = np.radians([10.0, 70.0, -160.0, 0.0, -50.0, 10.0])
    with ToolProcess([simula, "-p", "--power-on", "--lockstep", "--port", "0"]) as sim:
        with rccl.open(sim.url, robot="puma260", rate_hz=36, on_error="raise", timeout=2.0) as arm:
            arm.setmod("joint")
            arm.setvel(0.3, 3.0)
            p = makeposition("p", T6, EQ, Trsf("P", kin.fk(goal)), TL, T6)
            arm.move(p)
            arm.waitfor(p.end)
            arm.rci.wait(0.2)
            reached = kin.fk(arm.measured_q())
    print("models", data)
    print("position error (m)", float(np.linalg.norm(reached[:3, 3] - kin.fk(goal)[:3, 3])))
''')


def _run(argv: list[str], cwd: Path, timeout: float, home: Path | None = None) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "RCCI_MODELS")}
    if home is not None:
        env["HOME"] = str(home)
    return subprocess.run(argv, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)


def _parallel_build_home(tmp_path: Path) -> Path:
    """A home folder whose ~/.pydistutils.cfg (the per-user build configuration setuptools reads)
    has build_ext compile the extensions side by side, one per core: the four kernels are most
    of the build's time, and the wheel they make is the same (the source copy is left as is)."""
    home = tmp_path / "home"
    home.mkdir()
    (home / ".pydistutils.cfg").write_text(f"[build_ext]\nparallel = {max(2, os.cpu_count() or 2)}\n")
    return home


def _reuse_compiled_kernels(src: Path) -> list[str]:
    """Put the kernels this checkout's editable install compiled (rccl/kinematics/_c/*.so) where
    the wheel build of the copy ``src`` looks for its own (build/lib.<platform>-<tag>/), keeping
    their times: build_ext compiles only those older than their .c or headers. Returns their names."""
    lib = src / "build" / f"lib.{sysconfig.get_platform()}-{sys.implementation.cache_tag}" / "rccl" / "kinematics" / "_c"
    lib.mkdir(parents=True)
    suffix = sysconfig.get_config_var("EXT_SUFFIX")
    reused = []
    for so in sorted((ROOT / "rccl" / "kinematics" / "_c").glob(f"*{suffix}")):
        shutil.copy2(so, lib / so.name)
        reused.append(so.name)
    return reused


def test_wheel_installs_and_runs_outside_the_tree(tmp_path):
    t0 = time.monotonic()
    src = tmp_path / "src"
    shutil.copytree(ROOT, src, ignore=IGNORE)
    reused = _reuse_compiled_kernels(src)
    wheels = tmp_path / "wheels"
    # the test venv's setuptools builds it (no download); C kernels compiled as in `make venv`;
    # -v shows the build backend's own output, where setuptools prints its deprecations
    built = _run([sys.executable, "-m", "pip", "wheel", "-v", "--no-deps", "--no-build-isolation",
                  "--no-index", "-w", str(wheels), str(src)], cwd=tmp_path, timeout=300,
                 home=_parallel_build_home(tmp_path))
    assert built.returncode == 0, built.stdout + built.stderr
    noise = [line for line in (built.stdout + built.stderr).splitlines()
             if "deprecat" in line.lower() or "BuildBackendWarning" in line]
    assert not noise, "setuptools deprecation warnings in the build:\n" + "\n".join(noise)
    (wheel,) = wheels.glob("rcci-*.whl")
    with zipfile.ZipFile(wheel) as zf:
        tops = {name.split("/")[0] for name in zf.namelist() if not name.split("/")[0].endswith(".dist-info")}
    assert tops == {"rci", "rccl", "rcci"}, f"top-level names in the wheel: {sorted(tops)}"
    with zipfile.ZipFile(wheel) as zf:
        kernels = {Path(n).stem.split(".")[0] for n in zf.namelist() if n.startswith("rccl/kinematics/_c/") and n.endswith(".so")}
    assert kernels == {c.stem for c in (ROOT / "rccl" / "kinematics" / "_c").glob("*.c")}, f"kernels in the wheel: {kernels}"
    t_build = time.monotonic() - t0

    fresh = tmp_path / "fresh"
    venv.EnvBuilder(with_pip=False).create(fresh)
    py = fresh / "bin" / "python"
    site = Path(_run([str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                     cwd=tmp_path, timeout=30).stdout.strip())
    # dependencies only: the test venv's site-packages, appended after the fresh venv's own
    # ("_" sorts first: the path is there before the dependencies' own .pth hooks run, e.g.
    # pin's cmeel prefix); the test venv's editable install of this tree is not carried over
    deps = Path(sysconfig.get_paths()["purelib"])
    (site / "_deps.pth").write_text(f"{deps}\n")
    for pth in deps.glob("*.pth"):
        if not pth.name.startswith("__editable__"):
            shutil.copy(pth, site / pth.name)
    installed = _run([sys.executable, "-m", "pip", "--python", str(py), "install", "--no-deps",
                      "--no-index", str(wheel)], cwd=tmp_path, timeout=120)
    assert installed.returncode == 0, installed.stdout + installed.stderr
    assert (fresh / "bin" / "simula").is_file() and (fresh / "bin" / "calib").is_file()

    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (elsewhere / "move.py").write_text(CLIENT)
    ran = _run([str(py), "move.py"], cwd=elsewhere, timeout=120)
    assert ran.returncode == 0, ran.stdout + ran.stderr
    err = float(ran.stdout.split("position error (m)")[1].split()[0])
    assert err < 1e-3, ran.stdout   # the move ended at the goal (encoder resolution, not a tolerance of the test)
    total = time.monotonic() - t0
    print(f"wheel build {t_build:.1f} s ({len(reused)} compiled kernels reused), build+install+simula+move {total:.1f} s")
