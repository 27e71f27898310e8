"""One BLAS thread for calib's small dense linear algebra (the excitation design, the dynamics fit).

numpy's OpenBLAS starts a worker thread per core for a matrix product or an SVD above a few
thousand elements. On a shared machine whose cores are already busy those workers wait for
each other: on this project's 2-core machine at a load average of 9, the SVD of the Panda's
1532 x 76 stacked regressor took 1.1 s with two BLAS threads and 0.011 s with one, and the
Panda's excitation design 8.9 s of wall time against 2.0 s (the same coefficients). The
matrices calib factors are small enough that one thread loses nothing on a quiet machine.

:func:`one_blas_thread` sets every OpenBLAS library loaded in this process (found in
``/proc/self/maps``: Linux) to one thread and restores each one's count afterwards; where no
OpenBLAS is found (another BLAS, another system) it changes nothing.
"""
from __future__ import annotations

import ctypes
from collections.abc import Iterator
from contextlib import contextmanager

#: (get, set) symbol pairs of OpenBLAS builds: numpy's and scipy's wheels, then a plain build
_SYMBOLS = (("scipy_openblas_get_num_threads64_", "scipy_openblas_set_num_threads64_"),
            ("scipy_openblas_get_num_threads", "scipy_openblas_set_num_threads"),
            ("openblas_get_num_threads64_", "openblas_set_num_threads64_"),
            ("openblas_get_num_threads", "openblas_set_num_threads"))


def _loaded_libraries() -> list[str]:
    """Paths of the shared libraries with "openblas" in their name mapped into this process."""
    try:
        with open("/proc/self/maps") as f:
            lines = f.read().splitlines()
    except OSError:
        return []
    paths = {line.split()[-1] for line in lines if "openblas" in line.lower() and "/" in line}
    return sorted(p for p in paths if p.startswith("/"))


def blas_controls() -> list[tuple]:
    """(get, set) C functions of the thread count of each loaded OpenBLAS."""
    out = []
    for path in _loaded_libraries():
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        for get, put in _SYMBOLS:
            if hasattr(lib, get) and hasattr(lib, put):
                g, s = getattr(lib, get), getattr(lib, put)
                g.restype, g.argtypes = ctypes.c_int, []
                s.restype, s.argtypes = None, [ctypes.c_int]
                out.append((g, s))
                break
    return out


@contextmanager
def one_blas_thread() -> Iterator[None]:
    """Run the body with every loaded OpenBLAS at one thread (module docstring)."""
    controls = blas_controls()
    before = [g() for g, _ in controls]
    for _, s in controls:
        s(1)
    try:
        yield
    finally:
        for (_, s), n in zip(controls, before):
            s(n)
