"""Conditional motion requests (thesis 5.6.1, Figure 5.5 (b)): a "pruned tree" of motions chosen by how one ends.

Used by the adaptive generator (rccl.adaptive, which attaches them with ``cond``) and by
event flag triples (rccl.events), so it stands beside both.

A motion request may carry conditional requests, each with a condition on its
``MotionEnd``. When the motion ends early and a condition matches, the trajectory level
(without waiting for the planning level) deletes every request still queued, finishing
them as not run, and runs the conditional request next; the planning level notices
through the dropped requests and ``ended`` records. A conditional request cannot carry
conditionals of its own (the tree stays pruned). Conditions: a string matched against the
end's reason ("limit", "monitor"), component or monitor name ("fz", "dz", "my_monitor"),
or the monitor's code as text; or a function of the MotionEnd returning a bool.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

from .ending import MotionEnd
from .exceptions import BadRequest


@dataclass
class Conditional:
    """One branch: ``when`` (str or callable) and the request to run if it matches."""

    when: Any
    request: Any

    def __post_init__(self) -> None:
        if not (isinstance(self.when, str) or callable(self.when)):
            raise BadRequest(f"cond: the condition must be a string or a function of the MotionEnd, got {self.when!r}")

    def matches(self, end: MotionEnd) -> bool:
        if callable(self.when):
            return bool(self.when(end))
        return self.when in (end.reason, end.what) or (end.code is not None and self.when == str(end.code))


def choose(conditionals: list[Conditional], end: MotionEnd) -> Conditional | None:
    """The first branch whose condition matches ``end``, or None."""
    for c in conditionals:
        if c.matches(end):
            return c
    return None


Condition = str | Callable[[MotionEnd], bool]
