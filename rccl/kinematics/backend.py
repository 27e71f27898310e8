"""Loader of the compiled C kinematics kernels, the fast path behind the generated modules.

The generated Python modules (``rccl.kinematics.puma260`` ...) ask ``kernel(robot, name,
input shapes, output shapes)`` for each of their straight-line kernels. They get a
``CKernel`` when the C extension ``rccl.kinematics._c.<robot>`` was compiled at install
time and matches the kernel's shapes, and ``None`` otherwise, in which case they keep
their own Python code. A missing or stale extension gives one ``RuntimeWarning`` per
process, naming the cause and how to build it.

Setting the environment variable ``RCCL_KINEMATICS=python`` before import selects the
Python code without a warning (for comparisons and debugging).
"""
from __future__ import annotations

import hashlib
import importlib
import os
import warnings
from pathlib import Path
from typing import Any, Callable

Shape = tuple[int, ...]

_modules: dict[str, Any] = {}
_warned = False


def _warn_once(message: str) -> None:
    global _warned
    if not _warned:
        _warned = True
        warnings.warn(message, RuntimeWarning, stacklevel=3)


#: the hand-written runtime every generated ``_c/<robot>.c`` includes
RUNTIME_HEADERS = ("kin_prelude.h", "kin_runtime.h", "kin_redundant.h")


def source_hash(c_file: Path) -> str:
    """sha256 of a generated C file and the runtime headers beside it: what setup.py compiles
    into the extension (RCCL_SOURCE_HASH), so a stale build is recognised at import."""
    digest = hashlib.sha256()
    for path in (c_file, *(c_file.with_name(h) for h in RUNTIME_HEADERS)):
        digest.update(path.read_bytes())
    return digest.hexdigest()


def enabled() -> bool:
    """False when ``RCCL_KINEMATICS=python`` asks for the Python kernels."""
    return os.environ.get("RCCL_KINEMATICS", "c").lower() != "python"


def c_module(robot: str) -> Any | None:
    """The compiled kernel module of ``robot``, or None (with one warning) when it is unavailable."""
    if robot in _modules:
        return _modules[robot]
    mod = None
    if enabled():
        try:
            mod = importlib.import_module(f"rccl.kinematics._c.{robot}")
        except ImportError as exc:
            _warn_once(
                f"rccl.kinematics: compiled kernels for {robot!r} are not available ({exc}); using the "
                "slower generated Python code. Install a C compiler and reinstall (pip install -e .) to build them.")
        else:
            source = Path(__file__).with_name("_c") / f"{robot}.c"
            if source.exists() and source_hash(source) != mod.source_hash():
                _warn_once(
                    f"rccl.kinematics: the compiled {robot} kernels were built from an older {source} (or "
                    f"runtime headers {', '.join(RUNTIME_HEADERS)}); using the "
                    "generated Python code. Rebuild with `pip install -e .` (or `python setup.py build_ext --inplace`).")
                mod = None
    _modules[robot] = mod
    return mod


def kernel(robot: str, name: str, in_shapes: tuple[Shape, ...], out_shapes: tuple[Shape, ...]) -> Callable | None:
    """The compiled kernel ``robot.name`` if available and of the given shapes, else None.

    ``out_shapes`` lists the outputs followed by one ``()`` per guard, as in the Kernel.
    The returned callable takes one array per input, each of the input's shape or with a
    leading batch axis N (unbatched inputs are broadcast over the batch), and returns a
    tuple of outputs: arrays of the output shape, or ``(N,) + shape`` for a batch; scalar
    outputs (guards) of an unbatched call are floats. Wrong shapes, mismatched N and
    NaN/inf inputs raise ValueError naming the kernel, the input and the row.
    """
    mod = c_module(robot)
    if mod is None:
        return None
    meta = mod.kernels().get(name)
    want = (tuple(tuple(s) for s in in_shapes), tuple(tuple(s) for s in out_shapes))
    if meta is None or tuple(meta) != want:
        _warn_once(
            f"rccl.kinematics: the compiled {robot} kernels do not match the generated code ({name!r} "
            f"{'is missing' if meta is None else f'has shapes {meta}, expected {want}'}); using the generated "
            "Python code. Rebuild with `pip install -e .` after `make derive`.")
        return None
    return getattr(mod, name)


def accelerate(robot: str, kernels: dict[str, Any]) -> dict[str, Any]:
    """Swap the Python code of generated kernels for the compiled C where it is available.

    ``kernels`` maps names to the runtime's ``KernelFn`` records (fields ``one``,
    ``many``, ``inputs``, ``outputs``, ``guards``); each record whose C kernel exists
    with the same shapes gets the C function as both its single and batched code.
    The C does its own shape and NaN checks and returns the same tuple layout
    (outputs, then guards) as the generated Python.
    """
    import dataclasses

    out = {}
    for name, k in kernels.items():
        fn = kernel(robot, name, tuple(s for _, s in k.inputs),
                    tuple(s for _, s in k.outputs) + ((),) * len(k.guards))
        out[name] = dataclasses.replace(k, one=fn, many=fn) if fn is not None else k
    return out


def _compiled(mod: Any, kernels: dict[str, Any], name: str) -> bool:
    k = kernels.get(name)
    return mod is not None and k is not None and hasattr(mod, "public") and k.one is getattr(mod, name, None)


def public(robot: str, name: str, fallback: Callable, kernels: dict[str, Any],
           keys: tuple[str, ...] | None = None) -> Callable:
    """The public function of kernel ``name``: its compiled fast entry, or ``fallback``.

    The fast entry (C, built with numpy's headers) runs the kernel directly when every
    argument is a float64 C-contiguous numpy array of the kernel's shape (one configuration)
    or with a leading batch axis (a batch, split over threads when large), with finite
    values, every guard >= 0 and a finite result, and returns the first output; the keyword
    ``out=`` takes an array of exactly the result's shape to write it into. ``keys`` (the
    coefficient names of gravity) lets the last input also be a mapping of floats (or of
    records with a float ``.value``). Any other call (lists, keywords, bad input, failing
    guards, a wrong ``out``) is handed to ``fallback`` unchanged, so errors and conversions
    are exactly those of the Python runtime. ``kernels`` are the accelerated KernelFn
    records: the fast entry is used only when the record's code is this module's compiled
    kernel (same shapes).
    """
    mod = c_module(robot)
    if not _compiled(mod, kernels, name):
        return fallback
    return mod.public(name, fallback, None if keys is None else tuple(str(k) for k in keys))


def public_ik(robot: str, fallbacks: dict[str, Callable], kernels: dict[str, Any], config_type: type,
              revolute: Any, lower: Any, upper: Any, rigid_tol: float, same_tol: float) -> dict[str, Callable]:
    """Fast entries of ``ik``, ``ik_all`` and ``config_of`` (keys of ``fallbacks``) for one pose
    or configuration, or the fallbacks themselves without the compiled kernels.

    The C checks the pose (finite, last row 0 0 0 1, rotation orthonormal within half of
    ``rigid_tol``, determinant > 0), the Config (an instance of ``config_type``), q_ref, the
    guards and the prismatic joint ranges, applies q_ref's 2 pi branch, and for ``ik_all``
    drops solutions within ``same_tol`` of an earlier one; whenever anything is off it calls
    the fallback, which builds the message or takes the wrist-singular path.
    """
    mod = c_module(robot)
    if not (hasattr(mod, "ik_setup") and _compiled(mod, kernels, "ik") and _compiled(mod, kernels, "config_indicators")):
        return dict(fallbacks)
    import dataclasses

    fields = tuple(f.name for f in dataclasses.fields(config_type))
    mod.ik_setup(config_type, fields, tuple(config_type.all()), [float(r) for r in revolute],
                 [float(x) for x in lower], [float(x) for x in upper], float(rigid_tol), float(same_tol))
    return {name: mod.public(name, fn) for name, fn in fallbacks.items()}


def public_redundant_ik(robot: str, fallbacks: dict[str, Callable], kernels: dict[str, Any], config_type: type,
                        lower: Any, upper: Any, singular: tuple[bool, ...],
                        tols: tuple[float, float, float, float]) -> dict[str, Callable]:
    """Fast entries of a redundant arm's ``ik(T, config, q_ref=None, q7=...)`` and
    ``ik_all(T, q7, q_ref=None)`` (keys of ``fallbacks``, with ``config_of``, which stays the
    fallback), or the fallbacks themselves without the compiled kernels.

    The C (rccl/kinematics/_c/kin_redundant.h) checks the pose, q7 (inside joint 7's range),
    q_ref and the guards (``singular``: per guard, True when its failure is Singular), moves
    each joint into its range ``lower``..``upper`` (rad), evaluates fk of every solution
    against T, and drops duplicates; ``tols`` = (rigid, same solution, range, reproduce), the
    runtime's. Whenever anything is off it calls the fallback, which raises or decides.
    """
    mod = c_module(robot)
    if not (hasattr(mod, "redundant_setup") and _compiled(mod, kernels, "ik") and _compiled(mod, kernels, "fk")):
        return dict(fallbacks)
    import dataclasses

    fields = tuple(f.name for f in dataclasses.fields(config_type))
    if not mod.redundant_setup(config_type, fields, tuple(config_type.all()), [float(x) for x in lower],
                               [float(x) for x in upper], tuple(bool(s) for s in singular), *map(float, tols)):
        return dict(fallbacks)
    return {"ik": mod.redundant_public("redundant_ik", fallbacks["ik"]),
            "ik_all": mod.redundant_public("redundant_ik_all", fallbacks["ik_all"]),
            "config_of": fallbacks["config_of"]}
