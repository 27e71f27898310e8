"""The `chg` record: commands from the control program to the robot (thesis A.4).

A command is issued by setting its ``value`` (if it has one) and then its ``com``; the
control task dispatches every entry whose ``com`` is non-zero once per cycle and then
clears that ``com`` (A.4: a command is consumed when dispatched). ``motion[i].com`` takes
POS / CUR / STOP / STOPCAL; every other entry only needs a true ``com``.

Values are integers in robot units: POS and STOPCAL in encoder counts, CUR in signed
12-bit DAC units (-2048..2047). A float value is rounded to the nearest integer when
dispatched; NaN or infinity ends the control with R_NANCMD.
"""
from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field
from typing import Iterator

from .how import NJ
from .rate import MAX_RATE_HZ, RATE_CODES, RateChange, rate_from_code  # noqa: F401 (re-exported)

# motion commands (chg.motion[i].com)
NONE = 0
POS = 1       # move, during the next cycle, to the encoder count in value
CUR = 2       # set the motor current to the signed 12-bit DAC value in value
STOP = 3      # stop the joint; value ignored
STOPCAL = 4   # stop the joint and set its encoder count to value (calibration)
MOTION_NAMES = {NONE: "NONE", POS: "POS", CUR: "CUR", STOP: "STOP", STOPCAL: "STOPCAL"}

# chg.hand values
OPEN = 1
CLOSE = 2

# chg.rate values: the thesis's codes 0..3, or any integer rate in Hz from 4 to 1000; the
# validation and the typed event are rci.rate's (these names stay for programs that use them)
rate_hz = rate_from_code
DAC_MIN, DAC_MAX = -2048, 2047

# order of the valued single commands, as on the wire
VALUED = ("setparamALL", "adco", "hand", "rate", "checking", "outport1", "pendant", "zindex")
UNVALUED = ("end", "stop", "power_on", "power_off")


@dataclass
class Cmd:
    """A valued command (A.4 ``CMDVAL``): ``com`` code and ``value``."""

    com: int = 0
    value: int | float = 0

    def issue(self, com: int = 1, value: int | float = 0) -> None:
        """Set value then com, the order A.4 prescribes."""
        self.value = value
        self.com = com


@dataclass
class Flag:
    """An unvalued command (A.4 ``CMD``): only ``com``."""

    com: int = 0

    def issue(self) -> None:
        self.com = 1


@dataclass
class Chg:
    """Robot commands (A.4 ``struct chg``).

    ``lock`` serialises the control task's dispatch-and-clear with planning-level code
    that must issue several commands in the same cycle (``with chg.lock: ...``).
    """

    nj: int = NJ
    motion: list[Cmd] = field(default_factory=list)
    setparam: list[Cmd] = field(default_factory=list)
    setparamALL: Cmd = field(default_factory=Cmd)
    adco: Cmd = field(default_factory=Cmd)
    hand: Cmd = field(default_factory=Cmd)
    rate: Cmd = field(default_factory=Cmd)
    checking: Cmd = field(default_factory=Cmd)
    outport1: Cmd = field(default_factory=Cmd)
    pendant: Cmd = field(default_factory=Cmd)
    zindex: Cmd = field(default_factory=Cmd)
    end: Flag = field(default_factory=Flag)
    stop: Flag = field(default_factory=Flag)
    power_on: Flag = field(default_factory=Flag)
    power_off: Flag = field(default_factory=Flag)
    lock: threading.RLock = field(default_factory=threading.RLock, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not self.motion:
            self.motion = [Cmd() for _ in range(self.nj)]
        if not self.setparam:
            self.setparam = [Cmd() for _ in range(self.nj)]
        if len(self.motion) != self.nj or len(self.setparam) != self.nj:
            raise ValueError(f"chg: motion/setparam need {self.nj} entries")

    def entries(self) -> Iterator[tuple[str, Cmd | Flag]]:
        """Every command entry with its name (``motion[2]``, ``hand``, ``end`` ...)."""
        for i, c in enumerate(self.motion):
            yield f"motion[{i}]", c
        for i, c in enumerate(self.setparam):
            yield f"setparam[{i}]", c
        for name in VALUED:
            yield name, getattr(self, name)
        for name in UNVALUED:
            yield name, getattr(self, name)

    def rate_change(self) -> RateChange | None:
        """The rate change this record commands (``rate`` set), or None; ValueError for a bad value."""
        return RateChange.of(self)

    def pending(self) -> list[str]:
        """Names of the entries whose com is set."""
        return [name for name, c in self.entries() if c.com]

    def clear(self) -> None:
        """Clear every com (values stay, as in the thesis)."""
        for _, c in self.entries():
            c.com = 0

    def repair(self) -> list[str]:
        """Put back a fresh entry wherever user code replaced one with something else.

        ``chg.motion[2] = None`` or ``chg.hand = 5`` would otherwise break every later
        control of the session; returns the names of the entries replaced.
        """
        fixed: list[str] = []
        for name, n in (("motion", self.nj), ("setparam", self.nj)):
            seq = getattr(self, name)
            if not isinstance(seq, list) or len(seq) != n:
                setattr(self, name, [Cmd() for _ in range(n)])
                fixed.append(name)
                continue
            for i, c in enumerate(seq):
                if not isinstance(c, Cmd):
                    seq[i] = Cmd()
                    fixed.append(f"{name}[{i}]")
        for name in VALUED:
            if not isinstance(getattr(self, name), Cmd):
                setattr(self, name, Cmd())
                fixed.append(name)
        for name in UNVALUED:
            if not isinstance(getattr(self, name), (Flag, Cmd)):
                setattr(self, name, Flag())
                fixed.append(name)
        return fixed

    def copy(self) -> "Chg":
        """An independent snapshot (same coms and values; a new lock)."""
        new = Chg(nj=self.nj)
        for (_, mine), (_, theirs) in zip(new.entries(), self.entries()):
            mine.com = theirs.com
            if isinstance(mine, Cmd):
                mine.value = theirs.value
        return new


def as_wire_int(value: int | float, where: str) -> int:
    """Convert a user value to an int for the wire; ValueError naming ``where`` for NaN/inf/junk.

    Text is refused even when it spells a number (``"12"``): a command value is a number.
    """
    if isinstance(value, bool):
        return int(value)
    if isinstance(value, (str, bytes, bytearray)):
        raise ValueError(f"chg.{where}.value is {value!r}, text and not a number")
    try:
        f = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"chg.{where}.value is {value!r}, not a number") from None
    if not math.isfinite(f):
        raise ValueError(f"chg.{where}.value is {value!r}")
    if isinstance(value, int):
        return value
    return int(round(f))
