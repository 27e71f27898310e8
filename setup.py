"""Build script for the compiled kinematics kernels (metadata lives in pyproject.toml).

Every generated ``rccl/kinematics/_c/<robot>.c`` becomes the extension module
``rccl.kinematics._c.<robot>``. The build is optional: without a working C compiler the
install still succeeds, prints one warning, and the generated Python code is used.
"""
from __future__ import annotations

import sys
from pathlib import Path

from setuptools import Extension, find_namespace_packages, setup
from setuptools.command.build_ext import build_ext

HERE = Path(__file__).parent
C_DIR = Path("rccl", "kinematics", "_c")


def _source_hash(c_file: Path) -> str:
    """rccl.kinematics.backend.source_hash, loaded by path (the package need not import here)."""
    import importlib.util
    spec = importlib.util.spec_from_file_location("_rccl_kin_backend", HERE / "rccl" / "kinematics" / "backend.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.source_hash(c_file)


def _numpy_include() -> str | None:
    """numpy's C headers, for the public fast path of the kernels; None without numpy."""
    try:
        import numpy
    except ImportError:
        return None
    return numpy.get_include()


class OptionalBuildExt(build_ext):
    """Compile the kernels with optimisation; warn once and carry on when that fails."""

    def build_extensions(self) -> None:
        include = _numpy_include()
        if include is None:
            print("WARNING: numpy headers not found; the C kinematics kernels are built without "
                  "their fast public entry (calls go through the Python checks).", file=sys.stderr)
        for ext in self.extensions:
            # the identity of the sources (the .c and the runtime headers), checked at import
            ext.define_macros.append(("RCCL_SOURCE_HASH", '"%s"' % _source_hash(HERE / ext.sources[0])))
            if include is not None:
                ext.include_dirs.append(include)
                ext.define_macros.append(("RCCL_NUMPY_API", "1"))
        if self.compiler.compiler_type == "unix":
            for ext in self.extensions:
                # -fno-math-errno lets sin/cos pairs become sincos and sqrt inline
                ext.extra_compile_args = ["-O3", "-fno-math-errno", "-Wno-unused-variable", "-pthread"]
                # large batches are split over threads (emit_c.py: run_rows)
                ext.extra_link_args = ["-pthread"]
        try:
            super().build_extensions()
        except Exception as exc:  # no compiler, missing headers: fall back to Python kernels
            self._warn(exc)

    def run(self) -> None:
        try:
            super().run()
        except Exception as exc:
            self._warn(exc)

    @staticmethod
    def _warn(exc: Exception) -> None:
        print(f"WARNING: the C kinematics kernels were not compiled ({exc}); "
              "rccl.kinematics will use the slower generated Python code.", file=sys.stderr)


extensions = [
    Extension(f"rccl.kinematics._c.{src.stem}", [str(src)], optional=True,
              depends=[str(C_DIR / h) for h in ("kin_prelude.h", "kin_runtime.h", "kin_redundant.h")])
    for src in sorted((HERE / C_DIR).glob("*.c"))
    for src in [src.relative_to(HERE)]
]

#: the repository's folders and the names they are installed under: rci and rccl are their own
#: names; the robot descriptions, the calibration and the 3D view go under the project's name, so that
#: installing it adds no generic top-level import (a user's own ``models/`` stays theirs)
INSTALLED_AS = {"rci": "rci", "rccl": "rccl", "models": "rcci.models", "calib": "rcci.calib", "view": "rcci.view"}


def _packages() -> tuple[list[str], dict[str, str]]:
    """Every package under each folder of INSTALLED_AS, by its installed name, and where it lives."""
    names: list[str] = []
    where: dict[str, str] = {}
    for folder, name in INSTALLED_AS.items():
        for sub in ["", *find_namespace_packages(str(HERE / folder), exclude=["*__pycache__*"])]:
            installed = name + ("." + sub if sub else "")
            names.append(installed)
            if name != folder:
                where[installed] = str(Path(folder, *sub.split("."))) if sub else folder
    return names, where


PACKAGES, PACKAGE_DIR = _packages()

setup(
    packages=PACKAGES,
    package_dir=PACKAGE_DIR,
    ext_modules=extensions,
    cmdclass={"build_ext": OptionalBuildExt},
    # the generated C (for rebuilds and the staleness check) and the CasADi Function files
    # the robot data files and their URDFs ship inside rcci.models ($RCCI_MODELS overrides)
    package_data={"rccl.kinematics": ["_c/*.c", "_c/*.h", "casadi/*/*.casadi"],
                  "rcci.models": ["*.toml", "urdf/*.urdf", "collision/*.toml", "README.md"]},
)
