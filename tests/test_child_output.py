"""rci.child_output: the first lines a child prints, within a deadline (simula's, a tool's and the
view's addresses), and the two ways it can fail; and the errors simula's starter and the view's
link turn them into."""
from __future__ import annotations

import subprocess
import sys

import pytest

from rci.child_output import Silent, first_lines
from rci.simula.exceptions import StartError
from rci.simula.process import ToolProcess


def _child(code: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-u", "-c", code], stdout=subprocess.PIPE,
                            stdin=subprocess.DEVNULL, bufsize=0)


def test_the_lines_wanted_and_what_came_with_them():
    proc = _child("print('socket://127.0.0.1:5'); print('control socket://x:6'); print('more')")
    try:
        head, rest = first_lines(proc, 2, timeout=20.0)
    finally:
        proc.wait(10)
    assert head == ["socket://127.0.0.1:5", "control socket://x:6"]
    assert rest in ([], ["more"])     # the third line may or may not have come in the same read


def test_a_child_that_exits_first_gives_its_exit_code():
    proc = _child("import sys; print('half', end=''); sys.exit(3)")
    with pytest.raises(Silent) as e:
        first_lines(proc, 1, timeout=20.0)
    assert e.value.exit_code == 3


def test_a_silent_child_runs_out_the_deadline():
    proc = _child("import time; time.sleep(30)")
    try:
        with pytest.raises(Silent) as e:
            first_lines(proc, 1, timeout=0.3)
        assert e.value.exit_code is None and proc.poll() is None    # the caller decides to stop it
    finally:
        proc.kill()
        proc.wait(10)


def test_a_tool_that_dies_before_its_address_is_a_start_error_naming_the_code():
    tool = ToolProcess([sys.executable, "-c", "import sys; sys.exit(4)"], start_timeout=20.0)
    with pytest.raises(StartError, match="exited with code 4 before printing its address"):
        tool.start()
