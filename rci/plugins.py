"""Modules found by what they declare: the one lookup behind ``rci.transports`` (a module per
kind of link, by its ``SCHEME``) and ``rci.simula.listeners`` (a module per endpoint, by its
``NAME``), so that adding a kind is adding one file."""
from __future__ import annotations

import importlib
import pkgutil
from types import ModuleType
from typing import Iterable


def declared(package: str, path: Iterable[str], attribute: str) -> dict[str, str]:
    """``value of attribute -> module name`` for every module of ``package`` (its ``__path__``
    ``path``) that declares ``attribute`` with a true value; the modules are imported."""
    found = {}
    for info in pkgutil.iter_modules(path):
        value = getattr(importlib.import_module(f"{package}.{info.name}"), attribute, None)
        if value:
            found[value] = info.name
    return found


def module(package: str, name: str) -> ModuleType:
    """The module ``name`` of ``package`` (already imported by :func:`declared`)."""
    return importlib.import_module(f"{package}.{name}")
