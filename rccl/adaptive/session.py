"""Former entry point of the adaptive features (thesis 5.4): every ``rccl.open`` arm has them now.

``rccl.adaptive.open(url, ...)`` is ``rccl.open(url, ...)``, and ``AdaptiveArm`` is
``rccl.session.Arm``: limit, evalfn, add_check, comply, lock and cond work with either
trajectory generator ("quartic" or "ruckig"). Kept as a thin alias for existing programs.
"""
from __future__ import annotations

from typing import Any

from ..session import Arm as AdaptiveArm

__all__ = ["AdaptiveArm", "open"]


def open(url: str, robot: str = "puma260", **options: Any) -> AdaptiveArm:  # noqa: A001 - thesis name rccl_open
    """The same as ``rccl.open``: an Arm with the trajectory generator and the adaptive features running."""
    return AdaptiveArm(url, robot, **options).open()
