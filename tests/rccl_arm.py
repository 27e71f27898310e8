"""Shared test helpers for an RCCL arm against a lockstep simula of one robot.

Imported by the per-arm RCCL tests (``from rccl_arm import go, open_arm, tail``).
"""
from __future__ import annotations

import warnings
from collections.abc import Iterator

import numpy as np

import rccl
from rccl import EQ, T6, TL, Trsf, makeposition


def lockstep_simula(robot: str) -> Iterator:
    """A powered lockstep ``simula --robot ROBOT`` process (yield it from a module fixture)."""
    from rci.simula.process import SimulaProcess
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # Python kinematics when the C kernels are not built
        with SimulaProcess("-p", "--power-on", robot=robot, lockstep=True) as s:
            yield s


def open_arm(sim, robot: str, rate_hz: int = 36):
    """An RCCL arm on ``sim`` that records its trace and raises on errors."""
    return rccl.open(sim.url, robot=robot, rate_hz=rate_hz, record=True, on_error="raise", timeout=2.0)


def go(arm, q: np.ndarray, name: str = "start", rot_speed: float = 1.0) -> np.ndarray:
    """Joint-mode move to joint values q (rad), translation speed 0.1 m/s and ``rot_speed``
    rad/s; returns T6 there."""
    arm.setmod("joint")
    arm.setvel(0.1, rot_speed)
    p = makeposition(name, T6, EQ, Trsf(name.upper(), arm.kinematics.fk(q)), TL, T6)
    arm.move(p)
    arm.waitfor(p.end)
    return arm.t6


def tail(arm, n0: int) -> tuple[np.ndarray, np.ndarray]:
    """The commanded and measured joint values the arm recorded from sample ``n0`` on."""
    tr = arm.trace[n0:]
    return np.array([x[1] for x in tr]), np.array([x[2] for x in tr])

