"""The one way to load an arm's generated kinematics module (``rccl/kinematics/<robot>.py``,
written by ``make derive`` from ``models/<robot>.toml``)."""
from __future__ import annotations

import importlib
from types import ModuleType

PACKAGE = "rccl.kinematics"


class KinematicsNotFound(ValueError, ImportError):
    """No generated kinematics for a robot: the name is no robot's, or ``make derive`` has not
    written its module. A ValueError (a bad ``robot=`` argument) and an ImportError (a module
    that is not there), so callers that catch either keep working."""


def load(robot: str) -> ModuleType:
    """The generated kinematics module of ``robot`` (functions in SI units, base frame of
    the arm's DH table; the contract is ``rcci.models.kinematics``).

    Raises KinematicsNotFound naming the robot and the robots there are (a data file each in
    ``models/`` or ``$RCCI_MODELS``) for an unknown name, or saying that the robot's module
    has not been generated (``make derive``). An import error inside an existing generated
    module is not hidden.
    """
    from rcci.models import available_robots

    known = available_robots()
    if not isinstance(robot, str) or robot not in known:
        raise KinematicsNotFound(f"robot={robot!r}: no such robot; known: {', '.join(known)} (models/ROBOT.toml)")
    name = f"{PACKAGE}.{robot}"
    try:
        return importlib.import_module(name)
    except ModuleNotFoundError as exc:
        if exc.name != name:
            raise
        raise KinematicsNotFound(f"robot={robot!r}: no generated kinematics (rccl/kinematics/{robot}.py); "
                                 "run `make derive`") from None
