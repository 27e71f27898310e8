"""One measurement run (:class:`MeasurementPlan`): a joint path for the controller to follow,
the log metadata its fit needs (docs/calib.md) and the log's name. :mod:`rcci.calib.experiments`
makes them, :mod:`rcci.calib.program` and :mod:`rcci.calib.regen` run them, :mod:`rcci.calib.registry` names them."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rcci.calib.paths import Path


@dataclass
class MeasurementPlan:
    """One measurement run: where to go, what to log with it, and the log's name."""

    name: str
    path: Path
    meta: dict[str, Any]
    simula_args: list[str] = field(default_factory=list)
    warmup: Path | None = None
    rate_hz: int = 36
    # poses the approach passes through on its way to the first setpoint (rcci.calib.headroom
    # chooses them where the straight joint move would ask a motor for too much current)
    via: tuple[np.ndarray, ...] = ()
