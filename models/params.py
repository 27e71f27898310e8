"""The calibration parameter file: the one schema and reader (TOML; sections in docs/calib.md).

``calib`` writes it (``rcci.calib.params.update_params``) and three places read it: ``calib``
itself, ``simula --params`` (the simulated arm's truth) and control programs
(``rcci.calib.params.load_fitted``). All of them read through :func:`read_params`, so a file
one accepts the others accept too. A file starts with a ``[calib]`` table naming the
``schema`` (:data:`SCHEMA`) and the ``robot``; fits add their own sections.
"""
from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

from .exceptions import ModelError

#: the schema every parameter file names in ``[calib] schema``
SCHEMA = "rcci-calib-params/1"


class ParamsFileError(ModelError):
    """A parameter file is unreadable, not TOML, or not of :data:`SCHEMA` (names file and field)."""


def read_toml(path: str | Path) -> dict[str, Any]:
    """A parameter file's TOML as a dict, before any schema check."""
    try:
        with open(path, "rb") as f:
            return tomllib.load(f)
    except OSError as exc:
        raise ParamsFileError(path, "<file>", f"cannot read parameter file: {exc.strerror}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ParamsFileError(path, "<file>", f"not valid TOML: {exc}") from None
    except UnicodeDecodeError as exc:
        raise ParamsFileError(path, "<file>", f"not a text (UTF-8) TOML parameter file: byte {exc.start} "
                              f"is {exc.object[exc.start:exc.start + 1]!r}") from None


def check_schema(data: dict[str, Any], path: str | Path) -> dict[str, Any]:
    """The ``[calib]`` table of a parsed parameter file; ParamsFileError unless it names :data:`SCHEMA`."""
    head = data.get("calib")
    if not isinstance(head, dict) or head.get("schema") != SCHEMA:
        got = head.get("schema") if isinstance(head, dict) else None
        raise ParamsFileError(path, "calib.schema", f"is {got!r}, expected {SCHEMA!r}")
    return head


def read_params(path: str | Path) -> dict[str, Any]:
    """A parameter file as a dict, its schema checked; ParamsFileError names the file when it is not one."""
    data = read_toml(path)
    check_schema(data, path)
    return data
