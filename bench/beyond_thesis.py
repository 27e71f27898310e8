"""The sections of reports/bench.md beyond the thesis's six-joint kinematics (issue 28): the
Panda's closed-form redundant IK (bench/ik_redundant.py) and one configuration's collision
check on every arm (bench/collision.py), measured in the same `make bench` run as the rest.

Each section is the report its own script writes (``python -m bench.ik_redundant``,
``python -m bench.collision``), with its title one level down and its command naming this run.
"""
from __future__ import annotations

import os
import time
import warnings

import numpy as np

from bench import collision, ik_redundant

COMMAND = "make bench (python -m bench.run, bench/beyond_thesis.py)"


def _demoted(text: str) -> list[str]:
    return [("#" + line) if line.startswith("#") else line for line in text.splitlines()]


def redundant_ik_section(calls: int = 20000, batch: int = 100000) -> list[str]:
    """The Panda's ik / ik_all per call and batched, Pinocchio's fk in the same run (us)."""
    t0, load0 = time.perf_counter(), os.getloadavg()[0]
    m = ik_redundant.measure(calls, batch)
    return _demoted(ik_redundant.report(m, time.perf_counter() - t0, (load0, os.getloadavg()[0]), COMMAND))


def collision_section(seed: int = 28) -> list[str]:
    """One configuration's full collision check per arm (every checked pair + the environment, us)."""
    rng = np.random.default_rng(seed)
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        rows = {robot: collision.bench_arm(robot, rng) for robot in collision.ARMS}
    return _demoted(collision.report(rows, time.perf_counter() - t0, COMMAND))


def sections() -> list[str]:
    """Both sections, each ending with a blank line."""
    return [*redundant_ik_section(), "", *collision_section(), ""]
