"""Why a motion ended early (thesis 5.4.1, 5.4.2, 5.6.1, 5.6.3): the record a request carries after it finishes.

The trajectory generator's ``abort(end)`` ends the running motion and stores ``end`` in
the request's ``ended``: a limit or a monitor (``rccl.adaptive``), a stop flag or
``stop_abort`` (``rccl.events``).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class MotionEnd:
    """How a motion ended.

    ``reason``: "limit" (a force or deviation limit was passed), "monitor" (the evalfn
    function returned a code), "stop" (an event flag's stop code, or ``stop_abort``).
    ``what`` names the component ("fz", "dx", ...), the monitor or the primitive; ``value`` and ``bound`` are the observed value and the limit (SI), ``code``
    is the monitor's code, ``t`` the trajectory time (s) and ``sample`` the generator's
    sample count at which the motion was ended.
    """

    reason: str
    what: str
    value: float | None = None
    bound: float | None = None
    code: Any = None
    t: float = 0.0
    sample: int = 0

    def __str__(self) -> str:
        if self.reason == "limit":
            return f"limit {self.what}: |{self.value:.4g}| > {self.bound:.4g} at t = {self.t:.3f} s"
        if self.reason == "stop":
            return f"stopped by {self.what} (code {self.code!r}) at t = {self.t:.3f} s"
        return f"monitor {self.what} returned {self.code!r} at t = {self.t:.3f} s"
