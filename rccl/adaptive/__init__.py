"""RCCL's adaptive path control (thesis 5.4, appendix E.2): limits, monitors, compliance, functional transforms.

    import rccl
    with rccl.open("socket://127.0.0.1:7600") as arm:   # either generator: trajectory="ruckig" too
        arm.limit("fz", 10.0)          # 5.4.1, next motion only
        arm.evalfn(monitor)            # 5.4.2, next motion only
        arm.comply("fz", -5.0)         # 5.4.3, until lock("fz")
        t.bind(trace_circle)           # 5.4.4, functional transform (rccl.transform.Trsf.bind)

docs/adaptive.md describes each feature, its thesis source and its limits.
"""
from __future__ import annotations

from .comply import Compliance, select_joints, servo_dac
from ..ending import MotionEnd
from .exceptions import AdaptiveError, ForceEstimateError, FunctionalError, MonitorError, SpecError
from .force import ForceEstimator, JointModel
from .functional import FunctionalUpdater
from .limit import Limit
from .check import Estimate
from .monitor import Monitor, Sample


def open(url: str, robot: str = "puma260", **options):  # noqa: A001 - thesis name rccl_open
    """The same as ``rccl.open`` (every arm has the adaptive features); kept for existing programs."""
    from .session import open as _open
    return _open(url, robot, **options)


__all__ = ["open", "Estimate", "Limit", "Monitor", "Sample", "MotionEnd", "Compliance", "select_joints", "servo_dac",
           "ForceEstimator", "JointModel", "FunctionalUpdater", "AdaptiveError", "SpecError", "MonitorError",
           "ForceEstimateError", "FunctionalError"]
