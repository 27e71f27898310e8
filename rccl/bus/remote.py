"""The planning process's view of an arm served by another process, and of the EFTs of the
motions queued there (what ``rccl.bus.planning.BusEvents.arm`` and ``move_ev`` return)."""
from __future__ import annotations

from typing import Any, Protocol

import numpy as np

from ..events import NULL, code_name
from ..kinematics import load
from ..segments import Kinematics


class Planning(Protocol):
    """What a remote arm and its EFTs ask of the planning level (``rccl.bus.planning.BusEvents``):
    the cell's name, a request to an arm's process, and the latest flags of a motion."""

    cell: str

    def request(self, arm: str, payload: dict, where: str) -> dict: ...

    def flags(self, arm: str, serial: int) -> dict: ...


class RemoteArm:
    """An arm served by another process, as the planning level sees it: ``name``, ``robot``,
    ``rate_hz``, ``kinematics`` (this process's generated module of the robot, to build
    positions) and ``q`` (the arm's last commanded joint angles, rad, asked for each time)."""

    def __init__(self, events: Planning, name: str, info: dict) -> None:
        self.events = events
        self.name = name
        self.robot = str(info["robot"])
        self.rate_hz = int(info["rate_hz"])
        self.kinematics = Kinematics(load(self.robot))

    @property
    def q(self) -> np.ndarray:
        return np.asarray(self.events.request(self.name, {"op": "info"}, "q")["q"], dtype=float)

    def close(self) -> None:
        """Ask the arm's process to finish its motions, release the arm and end."""
        self.events.request(self.name, {"op": "close"}, "close")

    def __repr__(self) -> str:
        return f"RemoteArm({self.name!r}, {self.robot}, {self.rate_hz} Hz, cell {self.events.cell!r})"


class RemoteEFT:
    """An EFT of a motion queued on an arm of another process; its flags are the latest the
    arm's process published. Reads like ``rccl.events.EFT`` (start, stop, status, state, t_started, ...)."""

    def __init__(self, events: Planning, arm: str, serial: int, where: str) -> None:
        self.events = events
        self.arm = arm
        self.serial = serial
        self._where = where
        self.after: RemoteEFT | None = None
        self.start_sent = NULL           # set here by start_ev before the arm's publication comes back
        self.stop_sent = NULL
        self.freed = False
        self.final: dict | None = None   # its last flags, kept by free_ev

    def _flag(self, name: str) -> Any:
        flags = self.final if self.final is not None else self.events.flags(self.arm, self.serial)
        return flags.get(name)

    @property
    def start(self) -> int:
        return self._flag("start") or self.start_sent

    @property
    def stop(self) -> int:
        return self._flag("stop") or self.stop_sent

    @property
    def status(self) -> int:
        return self._flag("status") or NULL

    @property
    def state(self) -> str:
        s = self.status
        return "pending" if s == NULL else ("active" if s > 0 else "completed")

    t_start_set = property(lambda self: self._flag("t_start_set"))
    t_started = property(lambda self: self._flag("t_started"))
    t_ended = property(lambda self: self._flag("t_ended"))
    traj_started = property(lambda self: self._flag("traj_started"))
    traj_ended = property(lambda self: self._flag("traj_ended"))

    @property
    def where(self) -> str:
        return self._where

    def describe(self) -> str:
        return f"motion #{self.serial} of arm {self.arm!r} to {self.where}"

    def __repr__(self) -> str:
        return (f"RemoteEFT(#{self.serial} arm {self.arm!r} to {self.where}: start {code_name(self.start)}, "
                f"stop {code_name(self.stop)}, status {code_name(self.status)})")
