"""Suite-wide guard: a test must not leave a control running behind it.

A control thread (or the process-wide garbage-collector settings a control task holds,
rci.realtime.GCControl) left over by one test makes later tests fail for reasons that are
not theirs (issue 13, item 8: a hung control thread from an earlier test failed the GC
settings test in a full run). This fixture fails the test that leaves one, by name.
"""
from __future__ import annotations

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
