"""What a workcell reports when an arm's control ends: the arm's termination, and the error of
its lockstep barrier (rci.multi; each names the arm it is about)."""
from __future__ import annotations

from dataclasses import dataclass, field

from . import codes
from .exceptions import ControlTerminated
from .workcell_data import MultiError


class SyncTimeout(MultiError):
    """Lockstep: an arm did not reach the sample barrier in time (names the arm that is late)."""


@dataclass
class ArmTermination:
    """Why the workcell's control ended: ``arm`` (its name) and its ``rci.codes.Termination``.

    ``released`` names the other arms the workcell released because of it.
    """

    arm: str
    robot: str
    termination: codes.Termination
    released: list[str] = field(default_factory=list)

    @property
    def code(self) -> int:
        return self.termination.code

    def __str__(self) -> str:
        rel = f"; released {', '.join(self.released)}" if self.released else ""
        return f"arm {self.arm!r} ({self.robot}): {self.termination}{rel}"

    def message(self) -> str:
        """The TERMINATE/ message (the reason is printed after it by ``print_terminate_code``)."""
        t = self.termination
        where = f" (cycle {t.cycle})" if t.cycle >= 0 else ""
        rel = f"; released {', '.join(self.released)}" if self.released else ""
        return f"arm {self.arm!r} ({self.robot}): {t.detail or t.name}{where}{rel}"


class ArmTerminated(ControlTerminated):
    """Raised at the planning level (``on_error="raise"``): one arm's control ended on an error."""

    def __init__(self, t: ArmTermination) -> None:
        self.arm = t.arm
        self.arm_termination = t
        super().__init__(t.termination)
        self.args = (str(t),)

    def __str__(self) -> str:
        return str(self.arm_termination)
