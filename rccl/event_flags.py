"""The event-flag API (thesis 5.6.3) as one protocol, implemented by its three forms.

A planning function written against :class:`EventFlags` (``plan(ev, puma, mic, pos)``)
runs unchanged against each form:

* the arms of this process: the module ``rccl.events`` itself (its functions);
* arms served by other processes or hosts: ``rccl.bus.planning.BusEvents``;
* no arms at all, recording the calls for the static Petri-net check:
  ``rccl.petri.FlagProgram``.

The rules every form applies the same way live once, in ``rccl.events``
(``check_start_code``, ``check_stop_code``; ``never_starts`` for a wait that cannot end);
``tests/test_event_flag_protocol.py`` checks that each form has every primitive with the
protocol's parameters. An EFT is whatever the form's ``move_ev`` returns (``rccl.events.EFT``,
``rccl.bus.remote.RemoteEFT``, ``rccl.petri.RecordedEFT``); codes are ints (start > 0,
stop < 0, NULL = 0 pending); times in seconds.
"""
from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

from .events import START


@runtime_checkable
class EventFlags(Protocol):
    """The planning level's event-flag primitives (thesis 5.6.3), one form per place the arms are."""

    def attach(self, arm: Any, name: str | None = None) -> str:
        """Prepare ``arm`` for event flag triples; its name."""

    def move_ev(self, arm: Any, position: Any, *, start: Any = START, after_code: int = START) -> Any:
        """Queue a motion of ``arm`` to ``position`` with an event flag triple; its EFT. ``start``:
        a start code (> 0: starts when ready), None (held until ``start_ev``) or another EFT
        (starts when that one ends, with ``after_code``)."""

    def start_ev(self, code: int, *efts: Any) -> None:
        """Set the start flag of every EFT given to ``code`` (> 0), as one act."""

    def stop_ev(self, code: int, *efts: Any) -> None:
        """Set the stop flag of every EFT given to ``code`` (< 0): each motion halts at its arm's next sample."""

    def wait_ev(self, eft: Any, *, started: bool = False, timeout: float | None = None, poll: float = 0.02) -> int:
        """Block until the motion has ended (``started``: begun); its status. ``timeout`` in s."""

    def status_ev(self, eft: Any) -> int:
        """NULL (0) pending, the start code running, the stop code ended."""

    def free_ev(self, *efts: Any) -> None:
        """Give ended EFTs back."""

    def stop_abort(self, arm: Any) -> None:
        """Flush ``arm``'s queue and halt it; every EFT not ended gets ABORTED."""


#: the primitives every form has, in the thesis's order
PRIMITIVES = ("attach", "move_ev", "start_ev", "stop_ev", "wait_ev", "status_ev", "free_ev", "stop_abort")
