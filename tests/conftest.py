"""Suite-wide guards: a test must not leave a control running behind it, nor a test module
its caches.

A control thread (or the process-wide garbage-collector settings a control task holds,
rci.realtime.GCControl) left over by one test makes later tests fail for reasons that are
not theirs (issue 13, item 8: a hung control thread from an earlier test failed the GC
settings test in a full run). This fixture fails the test that leaves one, by name.

Every control task used to start with one full ``gc.collect()`` (rci.realtime.GCControl: now the
young generations only), whose cost grows with every object the test process still holds. A
module whose caches keep millions of
objects alive (pdoc's documentation objects of test_api_docs, the ASTs of test_architecture:
2.2 million objects, 1.5-7.5 s per collection at load 5-8) made every later control test pay
it at each control start (tests/test_rci_blame.py: 4 s alone; in the suite its 12 slowest
cases took 118 s, all 20 took 12 s once the caches were emptied). The
second fixture empties those caches when the module ends.
"""
from __future__ import annotations

import sys
import threading
import time

import pytest


def _leftovers() -> list[str]:
    from rci.realtime import GCControl

    found = [f"control thread {t.name}" for t in threading.enumerate() if t.name == "rci-control" and t.is_alive()]
    if GCControl._holders:   # noqa: SLF001 - the guard reads the process-wide count on purpose
        found.append(f"{GCControl._holders} garbage-collector setting(s) of a control task")   # noqa: SLF001
    return found


@pytest.fixture(autouse=True)
def no_control_left_behind(request):
    yield
    deadline = time.monotonic() + 2.0       # a control ending by itself (release in flight) is fine
    while _leftovers() and time.monotonic() < deadline:
        time.sleep(0.02)
    left = _leftovers()
    if left:
        pytest.fail(f"{request.node.nodeid} left {', '.join(left)} running after it ended", pytrace=False)


def _clear_caches_of(owner: object, module: str) -> None:
    """Empty every functools cache defined in ``module`` among the attributes of ``owner``."""
    for value in list(vars(owner).values()):
        if getattr(value, "__module__", None) != module:
            continue
        clear = getattr(value, "cache_clear", None)
        if callable(clear):
            clear()
        elif isinstance(value, type):
            _clear_caches_of(value, module)


@pytest.fixture(autouse=True, scope="module")
def caches_emptied_after_the_module(request):
    """When a test module ends, empty the functools caches of its own functions and those of
    pdoc (which tests/test_api_docs.py fills with every documented object)."""
    yield
    _clear_caches_of(request.module, request.module.__name__)
    for name, mod in list(sys.modules.items()):
        if mod is not None and (name == "pdoc" or name.startswith("pdoc.")):
            _clear_caches_of(mod, name)
