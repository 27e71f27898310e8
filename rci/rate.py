"""The sample rate of a control: its range, the thesis's rate codes, and the typed rate-change event.

One validation for every place a rate enters: a session's ``rate_hz``, START, HELLO,
simula's ``--rate`` (``check_rate_hz``), and the ``chg.rate`` command
(``rate_from_code``). A rate command travels as one typed event, ``RateChange``, read
from the ``chg`` record by whoever executes it (the robot) or follows it (the control
task).

The timing contract (docs/protocol.md, "Timing: one cycle"): a HOW's ``rate_hz`` is the
rate at which the robot executes the CHG that answers that HOW, i.e. the period from
that HOW to the next. A CHG that carries a rate command is still executed at the old
rate; the next HOW already carries the new rate and starts the first period at it.
"""
from __future__ import annotations

import math
import numbers
from dataclasses import dataclass
from typing import Protocol

MIN_RATE_HZ = 4
MAX_RATE_HZ = 1000
#: the thesis's chg.rate codes (A.4) and the rate each one means, Hz
RATE_CODES = {0: 72, 1: 36, 2: 18, 3: 9}


def check_rate_hz(value: object, where: str = "rate_hz") -> int:
    """A sample rate in Hz (an integer 4..1000) as an int; ValueError naming ``where`` otherwise.

    A float is accepted only when it is a whole number (``36.0``): a rate of 36.5 Hz cannot
    be run and is refused rather than truncated.
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"{where} must be a whole number of Hz, {MIN_RATE_HZ}..{MAX_RATE_HZ}, not {value!r}")
    if not math.isfinite(value) or int(value) != value:
        raise ValueError(f"{where} must be a whole number of Hz, {MIN_RATE_HZ}..{MAX_RATE_HZ}, not {value!r}")
    hz = int(value)
    if not MIN_RATE_HZ <= hz <= MAX_RATE_HZ:
        raise ValueError(f"{where} must be {MIN_RATE_HZ}..{MAX_RATE_HZ} Hz, not {value!r}")
    return hz


def rate_from_code(value: int) -> int:
    """Sample rate in Hz for a ``chg.rate`` value: a thesis code 0..3 or a rate 4..1000 Hz.

    ValueError otherwise (the control task ends the control with R_BADCMD on it; a robot
    answers status 4).
    """
    if value in RATE_CODES:
        return RATE_CODES[value]
    if MIN_RATE_HZ <= value <= MAX_RATE_HZ:
        return int(value)
    raise ValueError(f"chg.rate value {value} is neither a code 0..3 nor a rate "
                     f"{MIN_RATE_HZ}..{MAX_RATE_HZ} Hz")


class _RateCommand(Protocol):
    com: int
    value: int | float


class _HasRate(Protocol):
    rate: _RateCommand


@dataclass(frozen=True)
class RateChange:
    """A rate command of one CHG: from the next HOW on, the robot runs at ``hz``.

    The CHG that carries it is executed at the old rate (the period of the HOW it answers);
    the next HOW carries ``hz`` and begins the first period at it.
    """

    hz: int

    @property
    def period(self) -> float:
        """The new sample period, s."""
        return 1.0 / self.hz

    @staticmethod
    def of(chg: _HasRate) -> "RateChange | None":
        """The rate change a ``chg`` record commands, or None when its ``rate`` entry is not set.

        ValueError for a value that is no rate (see ``rate_from_code``) or not a number.
        """
        cmd = chg.rate
        if not cmd.com:
            return None
        value = cmd.value
        if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value):
            raise ValueError(f"chg.rate value {value!r} is not a number")
        return RateChange(rate_from_code(int(round(float(value)))))
