"""What crosses the Zenoh bus between a planning process and its arm processes (``rccl.bus.planning``, ``rccl.bus.arm``).

Key expressions (``CELL``: the workcell's name; ``ARM``: the name an arm is served under):

``rcci/CELL/arm/ARM``              liveliness: the arm's process serves it
``rcci/CELL/arm/ARM/request``      queryable: move, info, free, abort, close (JSON in, JSON out)
``rcci/CELL/arm/ARM/fault``        publication: the arm's control ended with this fault
``rcci/CELL/flags/ARM/SERIAL``     publication (and queryable: the latest) of one EFT's flags
``rcci/CELL/flags/set``            publication: start_ev / stop_ev on EFTs of any arms (planner id, sequence number)
``rcci/CELL/arm/ARM/ack``          publication: the arm applied (or already had) that start_ev / stop_ev, its EFTs' flags
``rcci/CELL/arm/ARM/alive``        publication: the arm process's heartbeat, every ``HEARTBEAT_S``
                                   (``{"n", "t", "gone"}``: ``gone`` the last planning levels it gave up)
``rcci/CELL/arm/ARM/held``         publication: the arm process aborted a planning level's motions, and why
                                   (``{"arm", "why", "aborted", "t", "planner"}``)
``rcci/CELL/planner/ID``           liveliness: a planning level (``BusEvents``) is there
``rcci/CELL/planner/ID/alive``     publication: the planning level's heartbeat, every ``HEARTBEAT_S``
                                   (``{"n", "t", "silence"}``): an arm process gives up a planning level it
                                   has not heard for ``silence`` s

Positions cross as joint angles (``joint_position``: rebuilt with the arm process's own
kinematics) or as a T6 (any other position, evaluated when ``move_ev`` sends it: a
functional transform does not cross). Times in the flags (``t_started``, ``t_ended``) are
the arm process's ``time.monotonic()``, comparable between processes of one host.
Everything crosses as JSON (``rci.bus.encode``): an error an arm process refuses a request
with comes back as ``{"error", "type"}`` and is raised in the planning process as the class
it names (``EventError``, ``Deadlock``, ``MotionError``, ...; anything else as ``RemoteFault``).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from .. import exceptions as rccl_exceptions
from ..events import EFT, Deadlock, EventError, UnknownEvent
from ..position import EQ, TL, Position, joint_position, makeposition
from ..transform import T6, Trsf


# --- key expressions ------------------------------------------------------------------------
def arm_key(cell: str, arm: str, *parts: str) -> str:
    return "/".join(("rcci", cell, "arm", arm) + parts)


def flags_key(cell: str, arm: str, serial: int | str) -> str:
    return f"rcci/{cell}/flags/{arm}/{serial}"


def set_key(cell: str) -> str:
    return f"rcci/{cell}/flags/set"


def planner_key(cell: str, planner: str, *parts: str) -> str:
    """The liveliness token of one planning level (a ``BusEvents``), which the arm processes
    watch; with ``"alive"``, the key of its heartbeat."""
    return "/".join(("rcci", cell, "planner", planner) + parts)


def check_name(name: Any, what: str) -> str:
    if not isinstance(name, str) or not name or any(c in name for c in "/*$#? "):
        raise EventError(f"{what}: {name!r} is not a plain name (no '/', '*', '$', '#', '?', spaces)")
    return name


# --- the wire forms -------------------------------------------------------------------------
def flags_of(eft: EFT, arm: str) -> dict:
    """One EFT's flags as published (JSON)."""
    return {"arm": arm, "serial": eft.serial, "where": eft.where, "start": eft.start, "stop": eft.stop,
            "status": eft.status, "version": eft.version, "t_start_set": eft.t_start_set, "t_started": eft.t_started,
            "t_ended": eft.t_ended,
            "traj_started": eft.traj_started, "traj_ended": eft.traj_ended}


def position_to_wire(position: Any) -> dict:
    """A position as it crosses the bus: its joint angles if it has them, else its T6 now."""
    if not isinstance(position, Position):
        raise EventError(f"move_ev: {position!r} is not a Position (rccl.makeposition, rccl.joint_position)")
    joints = getattr(position, "joints", None)
    if joints is not None:
        return {"name": position.name, "joints": [float(x) for x in joints]}
    return {"name": position.name, "t6": np.asarray(position.solve(), dtype=float).tolist()}


def position_from_wire(data: Any, kinematics) -> Position:
    """The position ``position_to_wire`` sent, rebuilt with this arm's kinematics."""
    if not isinstance(data, dict) or not isinstance(data.get("name"), str):
        raise EventError(f"move request: the position must be {{'name', 'joints' | 't6'}}, got {data!r}")
    if "joints" in data:
        return joint_position(data["name"], kinematics, np.asarray(data["joints"], dtype=float))
    t6 = np.asarray(data.get("t6"), dtype=float)
    if t6.shape != (4, 4) or not np.all(np.isfinite(t6)):
        raise EventError(f"move request {data['name']!r}: t6 must be a finite 4x4 matrix")
    return makeposition(data["name"], T6, EQ, Trsf(data["name"].upper(), t6), TL, T6)


# --- the errors (raised in the planning process, ``rccl.bus.planning``) ---------------------------
class ArmLost(EventError):
    """The process serving an arm left the bus (died, or is unreachable), or does not answer."""


class PlannerLost(ArmLost):
    """An arm's process gave this planning level up: it did not hear it for longer than its
    silence (this process was stopped, hung or cut off) or its token ended; it aborted the
    motions this planning level queued there and holds the arm. Only a new planning level
    (a new ``BusEvents``) drives that arm again."""


class ArmHeld(EventError):
    """An arm process refused a request: another planning level holds the arm, or the
    request was not sealed by the planning level that holds it (``rccl.bus.hold``)."""


class RemoteFault(EventError):
    """An arm process's control ended with a fault, or it refused a request for a reason of its own."""


#: error classes an arm process's reply may name (anything else arrives as RemoteFault)
KNOWN_ERRORS = {cls.__name__: cls for cls in (EventError, UnknownEvent, Deadlock, PlannerLost, ArmHeld)}
KNOWN_ERRORS.update({name: cls for name, cls in vars(rccl_exceptions).items()
                      if isinstance(cls, type) and issubclass(cls, Exception)})


def error_reply(exc: BaseException) -> dict:
    return {"error": str(exc), "type": type(exc).__name__}
