"""RCI: the real-time control layer (thesis chapter 2, appendix A) - how/chg, the link, the control task.

Typical use::

    import rci
    from rci.chg import CUR
    with rci.open("socket://127.0.0.1:7600", "puma260", rate_hz=36) as s:
        s.control(None, weightless)     # weightless() reads s.how, writes s.chg
        s.chg.power_on.com = 1
        input("Type <CR> to exit: ")
        s.release()

See docs/rci.md for the thesis-primitive -> Python table.
"""
from __future__ import annotations

from .exceptions import RCIError, ModelError  # noqa: F401

__all__ = ["RCIError", "ModelError", "open", "Session"]


def __getattr__(name: str):
    # Lazy, so that importing rci.exceptions (e.g. from rci.robot_model) stays light.
    if name in ("open", "Session"):
        from . import session
        return getattr(session, name)
    raise AttributeError(f"module 'rci' has no attribute {name!r}")
