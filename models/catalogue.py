"""Where robot data files are found (``$RCCI_MODELS`` or the package's own files) and the
cached :func:`load_robot`."""
from __future__ import annotations

import os
from pathlib import Path

from .exceptions import ModelError
from .loader import Loader
from .robot import RobotModel

def models_dir() -> Path:
    """Directory of the robot data files: ``$RCCI_MODELS`` if set, else this package's own
    directory (the ``<robot>.toml`` files and ``urdf/`` ship in it as package data)."""
    env = os.environ.get("RCCI_MODELS")
    if env:
        return Path(env)
    return Path(__file__).resolve().parent


def available_robots() -> list[str]:
    """Names of the data files found in :func:`models_dir`."""
    return sorted(p.stem for p in models_dir().glob("*.toml"))


def data_file(name_or_path: str | os.PathLike[str]) -> Path:
    """The data file of a robot name (in :func:`models_dir`) or the given ``.toml`` path."""
    text = os.fspath(name_or_path)
    if text.endswith(".toml") or os.sep in text or "/" in text:
        return Path(text)
    return models_dir() / f"{text}.toml"


_cache: dict[str, tuple[tuple[int, int, int], RobotModel]] = {}


def load_robot(name_or_path: str | os.PathLike[str]) -> RobotModel:
    """Load a robot model by name (``"puma260"``, ``"microbo"``) or data-file path.

    Raises ModelError for a missing, malformed or inconsistent data file or URDF.
    Results are cached per file and reloaded when the data file or its URDF changes.
    """
    path = data_file(name_or_path)
    if not path.is_file():
        known = ", ".join(available_robots()) or "none"
        raise ModelError(path, "<file>", f"no such robot data file (robots in {models_dir()}: {known})")
    key = str(path.resolve())
    stat = path.stat()
    hit = _cache.get(key)
    if hit is not None:
        (mtime, size, urdf_mtime), model = hit
        if (mtime, size) == (stat.st_mtime_ns, stat.st_size) and model.urdf_path.is_file() \
                and model.urdf_path.stat().st_mtime_ns == urdf_mtime:
            return model
    model = Loader(path).load()
    _cache[key] = ((stat.st_mtime_ns, stat.st_size, model.urdf_path.stat().st_mtime_ns), model)
    return model
