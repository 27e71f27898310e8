"""Shared test fixture: a PUMA 260 and a Microbo simula, each its own lockstep process.

Imported by the two-arm tests (``from simula_pair import SLACK, sims``); pytest picks up the
imported fixture.
"""
from __future__ import annotations

import pytest

from rci.simula.process import SimulaProcess

# the machine is shared (2 cores, load up to 6 seen): a lockstep simula may be descheduled for
# longer than RCI's 0.25 s default before sending its next HOW; these tests are not about that
SLACK = {"lockstep_timeout": 2.0}


@pytest.fixture(scope="module")
def sims():
    """(puma, microbo) SimulaProcess pair, powered on, lockstep; one pair per test module."""
    with SimulaProcess("-p", "--power-on", robot="puma260", lockstep=True) as p, \
            SimulaProcess("-p", "--power-on", robot="microbo", lockstep=True) as m:
        yield p, m
