"""Exceptions of the simulator package."""
from __future__ import annotations

from ..exceptions import RCIError


class SimulaError(RCIError):
    """Base of every error raised by ``rci.simula``."""


class ParamsError(SimulaError):
    """A ``--params`` file is unreadable or malformed; the message names the file and field."""


class StartError(SimulaError):
    """A simula process could not be started, or did not announce its address in time."""
