"""Robot models: load a robot data file (``models/<name>.toml``) into frozen SI records.

A robot model is everything the rest of the system knows about one arm: the
Denavit-Hartenberg table of thesis Tables 3.1/3.2 (with the signs the A matrices
3.4-3.15 require), joint kinds and ranges, named poses, link inertials, the gravity
loading coefficients of eq. 4.24 (Table 4.9), the friction model of eq. 4.27
(Tables 4.2-4.6), motor torque sensitivities (Table 4.1) and the conversion constants
of section 4.4.3 / Appendix D.  Each robot has one TOML data file and one URDF.

Usage::

    from rci.robot_model import load_robot
    puma = load_robot("puma260")          # or "microbo", or a path to a .toml file
    puma.n_joints, puma.lower, puma.upper, puma.max_velocity    # SI numpy arrays
    puma.joints[2].kind, puma.joints[2].d, puma.joints[2].alpha  # joint 3 (0-based list)
    puma.poses["ready"]                   # (6,) joint values, rad / m
    puma.gravity_coeffs["c12"].value      # N*m
    puma.friction.coulomb_pos.values      # (6,) N*m or N
    puma.conversion.gear_ratio.values     # (6, 6) G of eq. 4.28
    puma.source("joints.3.d")             # Source(tag='thesis Table 3.1', why=...)
    puma.base_to_link(q)                  # (6, 4, 4) T_1..T_6 from the DH table (eq. 3.3, 4.9)

Conventions (SI, radians):

* DH convention of thesis eq. 3.3 (Paul's standard DH): ``A_i = Rz(theta_i) Tz(d_i)
  Tx(a_i) Rx(alpha_i)``.  For a revolute joint ``theta_i = joint.theta + q_i`` (``d``
  fixed); for a prismatic joint ``d_i = joint.d + q_i`` (``theta`` fixed).  Limits,
  velocities and poses are on ``q``.
* Frame 0 (URDF ``base_link``) has z0 up along the joint 1 axis; frames ``link1`` ..
  ``link6`` of the URDF coincide with DH frames 1..6.
* Joint numbers in source paths are the thesis's (1-based): ``"joints.3.d"`` is d3;
  ``model.joints`` is a 0-based tuple, ``model.joints[i].index == i + 1``.

Data-file schema (full description with examples in ``models/README.md``): every number
is a record ``{value = ..., unit = "...", source = "...", why = "...", uncertainty = ...}``
(or ``values = [...]`` with ``unit`` or per-entry ``units`` for vectors and matrices).
``source`` is ``"thesis <table/equation/section>"`` or ``"estimate"``; an estimate must
say ``why``.  Units are converted to SI on loading; a unit of the wrong dimension is an
error.  Any malformed or inconsistent file (missing field, wrong unit, NaN, lower >
upper, unknown joint kind, value without source, wrong number of joints, pose outside the
ranges, missing URDF or a URDF whose joints/limits/link frames/inertials disagree with the
data file)
raises :class:`rci.exceptions.ModelError` naming the file, the field and the problem.

Models are looked up in ``$RCCI_MODELS`` if set, else in ``models/`` next to the package.
"""
from __future__ import annotations

import math
import os
import tomllib
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import Any, Mapping

import numpy as np

from rci.exceptions import ModelError

__all__ = [
    "Source", "Value", "Vector", "Matrix", "Joint", "LinkInertial", "Friction", "Motors",
    "Conversion", "RobotModel", "load_robot", "models_dir", "available_robots", "UNITS",
]

# unit -> (dimension, factor to SI)
UNITS: Mapping[str, tuple[str, float]] = MappingProxyType({
    "m": ("length", 1.0), "mm": ("length", 1e-3),
    "rad": ("angle", 1.0), "deg": ("angle", math.pi / 180.0),
    "m/s": ("linear_velocity", 1.0), "mm/s": ("linear_velocity", 1e-3),
    "rad/s": ("angular_velocity", 1.0), "deg/s": ("angular_velocity", math.pi / 180.0),
    "m/s^2": ("acceleration", 1.0),
    "N*m": ("torque", 1.0), "N": ("force", 1.0),
    "N*m*s/rad": ("rotary_viscous", 1.0), "N*s/m": ("linear_viscous", 1.0),
    "N*m/A": ("torque_sensitivity", 1.0),
    "A": ("current", 1.0), "ohm": ("resistance", 1.0), "V/count": ("volts_per_count", 1.0),
    "kg": ("mass", 1.0), "kg*m^2": ("inertia", 1.0),
    "counts": ("counts", 1.0), "counts/rad": ("counts_per_angle", 1.0),
    "counts/m": ("counts_per_length", 1.0), "rad/m": ("motor_angle_per_length", 1.0),
    "1": ("dimensionless", 1.0),
})

# Dimensions of per-joint quantities, (revolute, prismatic).
_JOINT_DIMS: Mapping[str, tuple[str, str]] = MappingProxyType({
    "position": ("angle", "length"),
    "velocity": ("angular_velocity", "linear_velocity"),
    "effort": ("torque", "force"),
    "viscous": ("rotary_viscous", "linear_viscous"),
    "gear": ("dimensionless", "motor_angle_per_length"),
    "encoder": ("counts_per_angle", "counts_per_length"),
})

JOINT_KINDS = ("revolute", "prismatic")
_LIMIT_TOL = 1e-6      # URDF vs data file: rad or m (URDFs are written with >= 7 digits)
_INERTIAL_TOL = 1e-9   # URDF vs data file: kg, m, kg*m^2


# ----------------------------------------------------------------------------- records

@dataclass(frozen=True)
class Source:
    """Where a value comes from: ``tag`` is ``"thesis ..."`` or ``"estimate"``."""

    tag: str
    why: str = ""

    @property
    def is_estimate(self) -> bool:
        return self.tag == "estimate"

    def __str__(self) -> str:
        return f"{self.tag}: {self.why}" if self.why else self.tag


@dataclass(frozen=True)
class Value:
    """A scalar in SI units with its source (``uncertainty`` in the same unit)."""

    value: float
    unit: str
    source: Source
    uncertainty: float | None = None


@dataclass(frozen=True)
class Vector:
    """A per-joint (or named) vector in SI units; ``units`` has one SI unit per entry."""

    values: np.ndarray
    units: tuple[str, ...]
    source: Source
    uncertainty: np.ndarray | None = None
    names: tuple[str, ...] | None = None


@dataclass(frozen=True)
class Matrix:
    """An (n, n) matrix in SI units; ``units`` has one SI unit per column."""

    values: np.ndarray
    units: tuple[str, ...]
    source: Source


@dataclass(frozen=True)
class Joint:
    """One DH joint (thesis eq. 3.3); lengths in m, angles in rad.

    ``theta`` is the offset added to q for a revolute joint and the fixed angle of a
    prismatic one; ``d`` likewise for prismatic joints.  Limits are on q.
    """

    index: int
    name: str
    kind: str
    a: float
    alpha: float
    d: float
    theta: float
    lower: float
    upper: float
    max_velocity: float
    max_current: float

    @property
    def variable(self) -> str:
        """Which DH parameter moves: ``"theta"`` (revolute) or ``"d"`` (prismatic)."""
        return "theta" if self.kind == "revolute" else "d"

    def dh(self, q: float) -> tuple[float, float, float, float]:
        """(theta, d, a, alpha) at joint value q (rad or m)."""
        if self.kind == "revolute":
            return self.theta + q, self.d, self.a, self.alpha
        return self.theta, self.d + q, self.a, self.alpha

    def transform(self, q: float) -> np.ndarray:
        """A_i(q), the (4, 4) transform from frame i-1 to frame i (thesis eq. 3.3)."""
        theta, d, a, alpha = self.dh(q)
        ct, st, ca, sa = math.cos(theta), math.sin(theta), math.cos(alpha), math.sin(alpha)
        return np.array([
            [ct, -st * ca, st * sa, a * ct],
            [st, ct * ca, -ct * sa, a * st],
            [0.0, sa, ca, d],
            [0.0, 0.0, 0.0, 1.0],
        ])


@dataclass(frozen=True)
class LinkInertial:
    """Mass (kg), centre of mass (m, in DH frame k) and inertia about it (kg m^2, frame-k axes)."""

    index: int
    mass: float
    com: np.ndarray
    inertia: np.ndarray


@dataclass(frozen=True)
class Friction:
    """Friction model of thesis eq. 4.27, joint level (N*m or N; N*m*s/rad or N*s/m).

    All magnitudes are positive: f = Fc+ + Fv+ qd (qd > 0), f = -Fc- + Fv- qd (qd < 0),
    |f| <= Fs (qd = 0).  The Table 4.6 statistics exist only for the PUMA.
    """

    coulomb_pos: Vector
    coulomb_neg: Vector
    viscous_pos: Vector
    viscous_neg: Vector
    static_pos: Vector
    static_neg: Vector
    variation: Vector | None = None
    static_typical_max: Vector | None = None
    static_typical_min: Vector | None = None
    static_typical_mean: Vector | None = None
    static_typical_std: Vector | None = None


@dataclass(frozen=True)
class Motors:
    """Motor constants: torque sensitivity sigma_i (eq. 4.3, N*m/A) and Table 4.1 extras."""

    torque_sensitivity: Vector
    torque_sensitivity_std: Vector | None = None
    torque_sensitivity_trials: Vector | None = None
    torque_sensitivity_manufacturer: Vector | None = None


@dataclass(frozen=True)
class Conversion:
    """Joint <-> motor <-> sensor conversions of thesis 4.4.3 (eqs. 4.28-4.38), Appendix D.

    ``gear_ratio`` G: motor angle = G q (4.28); ``encoder_ratio`` R: counts = R q (+
    ``encoder_offset``) (4.30) as printed; ``encoder_ratio_consistent``: R rebuilt as
    diag(counts per motor radian) G where the print is inconsistent (PUMA r65);
    ``adc_volts_per_count`` V_g, ``sense_resistance`` R_i, ``kappa`` kappa_i (4.32, 4.34).
    """

    gear_ratio: Matrix
    encoder_ratio: Matrix
    encoder_counts_per_motor_rev: Vector
    encoder_offset: Vector
    adc_volts_per_count: Value
    sense_resistance: Vector
    kappa: Vector
    encoder_ratio_consistent: Matrix | None = None


@dataclass(frozen=True)
class RobotModel:
    """One robot, SI units throughout.  Arrays are read-only."""

    name: str
    title: str
    path: Path
    urdf_path: Path
    n_joints: int
    joints: tuple[Joint, ...]
    lower: np.ndarray
    upper: np.ndarray
    max_velocity: np.ndarray
    max_current: np.ndarray
    gravity: float
    poses: Mapping[str, np.ndarray]
    links: tuple[LinkInertial, ...]
    gravity_coeffs: Mapping[str, Value]
    gravity_friction_error: Vector | None
    friction: Friction
    motors: Motors
    conversion: Conversion
    sources: Mapping[str, Source]

    @property
    def kinds(self) -> tuple[str, ...]:
        """Joint kinds in order, ``"revolute"`` or ``"prismatic"``."""
        return tuple(j.kind for j in self.joints)

    def source(self, field: str) -> Source:
        """The source of a value, by dotted path: ``"joints.3.d"``, ``"robot.gravity"``,
        ``"links.6.com"``, ``"poses.ready"``, ``"gravity_coeffs.c12"``,
        ``"friction.coulomb_pos"`` (a trailing entry number, ``"friction.coulomb_pos.2"``,
        gives the source of the whole vector)."""
        if field in self.sources:
            return self.sources[field]
        head, _, tail = field.rpartition(".")
        if tail.isdigit() and head in self.sources:
            return self.sources[head]
        raise KeyError(f"{self.name}: no value {field!r}; known fields include "
                       f"{', '.join(sorted(self.sources)[:8])}, ...")

    def base_to_link(self, q: np.ndarray) -> np.ndarray:
        """T_1..T_n (thesis eq. 4.9) from the DH table: (n, 4, 4), frame k in the base frame."""
        q = np.asarray(q, dtype=float)
        if q.shape != (self.n_joints,):
            raise ValueError(f"{self.name}: q must have shape ({self.n_joints},), got {q.shape}")
        out = np.empty((self.n_joints, 4, 4))
        base_to_k = np.eye(4)
        for k, joint in enumerate(self.joints):
            base_to_k = base_to_k @ joint.transform(float(q[k]))
            out[k] = base_to_k
        return out

    def within_limits(self, q: np.ndarray) -> bool:
        """True when every joint value lies in [lower, upper]."""
        q = np.asarray(q, dtype=float)
        return bool(np.all(q >= self.lower) and np.all(q <= self.upper))


# ----------------------------------------------------------------------------- lookup

def models_dir() -> Path:
    """Directory of the robot data files: ``$RCCI_MODELS`` or ``models/`` beside the package."""
    env = os.environ.get("RCCI_MODELS")
    if env:
        return Path(env)
    import rci
    return Path(rci.__file__).resolve().parents[1] / "models"


def available_robots() -> list[str]:
    """Names of the data files found in :func:`models_dir`."""
    return sorted(p.stem for p in models_dir().glob("*.toml"))


def _resolve(name_or_path: str | os.PathLike[str]) -> Path:
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
    path = _resolve(name_or_path)
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
    model = _Loader(path).load()
    _cache[key] = ((stat.st_mtime_ns, stat.st_size, model.urdf_path.stat().st_mtime_ns), model)
    return model


# ----------------------------------------------------------------------------- parsing

def _readonly(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=float)
    a.flags.writeable = False
    return a


class _Loader:
    """Validates one data file; every failure is a ModelError(path, field, problem)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.sources: dict[str, Source] = {}
        self.kinds: list[str] = []

    def fail(self, field: str, problem: str) -> ModelError:
        return ModelError(self.path, field, problem)

    # -- generic records ---------------------------------------------------------------

    def table(self, data: Mapping[str, Any], key: str, field: str) -> Mapping[str, Any]:
        if key not in data:
            raise self.fail(field, "missing field")
        value = data[key]
        if not isinstance(value, Mapping):
            raise self.fail(field, f"expected a table, got {type(value).__name__}")
        return value

    def source_of(self, rec: Mapping[str, Any], field: str) -> Source:
        tag = rec.get("source")
        if not isinstance(tag, str) or not tag.strip():
            raise self.fail(field, "value without a source tag (need source = \"thesis ...\" or \"estimate\")")
        why = rec.get("why", "")
        if not isinstance(why, str):
            raise self.fail(field, "'why' must be a string")
        if tag == "estimate":
            if not why.strip():
                raise self.fail(field, "estimate without 'why' (the reasoning behind the value)")
        elif not tag.startswith("thesis "):
            raise self.fail(field, f"source {tag!r} is neither 'thesis <reference>' nor 'estimate'")
        src = Source(tag, why)
        self.sources[field] = src
        return src

    def check_keys(self, rec: Mapping[str, Any], field: str, allowed: set[str]) -> None:
        extra = set(rec) - allowed
        if extra:
            raise self.fail(field, f"unknown key(s) {sorted(extra)} (allowed: {sorted(allowed)})")

    def number(self, x: Any, field: str) -> float:
        if isinstance(x, bool) or not isinstance(x, (int, float)):
            raise self.fail(field, f"expected a number, got {x!r}")
        x = float(x)
        if not math.isfinite(x):
            raise self.fail(field, f"value is {x} (NaN or infinite)")
        return x

    def unit_factor(self, unit: Any, dims: str | tuple[str, ...], field: str) -> tuple[float, str]:
        """SI factor and SI unit name for ``unit``, which must have one of ``dims``."""
        if not isinstance(unit, str):
            raise self.fail(field, "missing unit")
        if unit not in UNITS:
            raise self.fail(field, f"unknown unit {unit!r} (known: {', '.join(UNITS)})")
        dim, factor = UNITS[unit]
        dims = (dims,) if isinstance(dims, str) else dims
        if dim not in dims:
            raise self.fail(field, f"wrong unit {unit!r}: a {dim} unit, expected a {' or '.join(dims)} unit")
        si = next(u for u, (d, f) in UNITS.items() if d == dim and f == 1.0)
        return factor, si

    def value(self, data: Mapping[str, Any], key: str, field: str, dims: str | tuple[str, ...]) -> Value:
        rec = self.table(data, key, field)
        self.check_keys(rec, field, {"value", "unit", "source", "why", "uncertainty"})
        if "value" not in rec:
            raise self.fail(field, "missing 'value'")
        x = self.number(rec["value"], field)
        factor, si = self.unit_factor(rec.get("unit"), dims, field)
        unc = None
        if "uncertainty" in rec:
            unc = self.number(rec["uncertainty"], field + ".uncertainty") * factor
            if unc < 0:
                raise self.fail(field, "negative uncertainty")
        return Value(x * factor, si, self.source_of(rec, field), unc)

    def entry_dims(self, family: str | None, dims: str | None, n: int) -> list[tuple[str, ...]]:
        if family is not None:
            pair = _JOINT_DIMS[family]
            return [(pair[0],) if k == "revolute" else (pair[1],) for k in self.kinds]
        assert dims is not None
        return [(dims,)] * n

    def vector(self, data: Mapping[str, Any], key: str, field: str, *, family: str | None = None,
               dims: str | None = None, n: int | None = None) -> Vector:
        """A per-joint vector (``family`` picks the dimension by joint kind) or a plain one."""
        rec = self.table(data, key, field)
        self.check_keys(rec, field, {"values", "unit", "units", "source", "why", "uncertainty", "names"})
        n = len(self.kinds) if n is None else n
        raw = rec.get("values")
        if not isinstance(raw, list):
            raise self.fail(field, "missing 'values' list")
        if len(raw) != n:
            raise self.fail(field, f"has {len(raw)} values, expected {n}")
        xs = [self.number(x, f"{field}[{i}]") for i, x in enumerate(raw)]
        factors, sis = self.units_for(rec, field, self.entry_dims(family, dims, n))
        unc = None
        if "uncertainty" in rec:
            ur = rec["uncertainty"]
            if not isinstance(ur, list) or len(ur) != n:
                raise self.fail(field, f"'uncertainty' must be a list of {n} numbers")
            unc = _readonly([self.number(u, f"{field}.uncertainty[{i}]") * f
                             for i, (u, f) in enumerate(zip(ur, factors))])
            if np.any(unc < 0):
                raise self.fail(field, "negative uncertainty")
        names = rec.get("names")
        if names is not None and (not isinstance(names, list) or len(names) != n
                                  or not all(isinstance(s, str) for s in names)):
            raise self.fail(field, f"'names' must be a list of {n} strings")
        src = self.source_of(rec, field)
        return Vector(_readonly([x * f for x, f in zip(xs, factors)]), tuple(sis), src, unc,
                      tuple(names) if names is not None else None)

    def units_for(self, rec: Mapping[str, Any], field: str,
                  dims: list[tuple[str, ...]]) -> tuple[list[float], list[str]]:
        n = len(dims)
        if "units" in rec:
            units = rec["units"]
            if "unit" in rec:
                raise self.fail(field, "give either 'unit' or 'units', not both")
            if not isinstance(units, list) or len(units) != n:
                raise self.fail(field, f"'units' must be a list of {n} unit strings")
        elif "unit" in rec:
            units = [rec["unit"]] * n
        else:
            raise self.fail(field, "missing unit")
        pairs = [self.unit_factor(u, d, f"{field}[{i}]") for i, (u, d) in enumerate(zip(units, dims))]
        return [p[0] for p in pairs], [p[1] for p in pairs]

    def matrix(self, data: Mapping[str, Any], key: str, field: str, family: str) -> Matrix:
        rec = self.table(data, key, field)
        self.check_keys(rec, field, {"values", "unit", "units", "source", "why"})
        n = len(self.kinds)
        raw = rec.get("values")
        if not isinstance(raw, list) or len(raw) != n or not all(isinstance(r, list) and len(r) == n for r in raw):
            raise self.fail(field, f"'values' must be a {n} x {n} list of lists")
        rows = [[self.number(x, f"{field}[{i}][{j}]") for j, x in enumerate(r)] for i, r in enumerate(raw)]
        factors, sis = self.units_for(rec, field, self.entry_dims(family, None, n))
        values = _readonly(np.array(rows) * np.array(factors)[None, :])
        return Matrix(values, tuple(sis), self.source_of(rec, field))

    # -- the file ----------------------------------------------------------------------

    def load(self) -> RobotModel:
        try:
            with open(self.path, "rb") as fh:
                data = tomllib.load(fh)
        except tomllib.TOMLDecodeError as exc:
            raise self.fail("<file>", f"not valid TOML: {exc}") from None
        except OSError as exc:
            raise self.fail("<file>", f"cannot read: {exc}") from None
        self.check_keys(data, "<top level>", {"robot", "joints", "poses", "links", "gravity_coeffs",
                                              "gravity_friction_error", "friction", "motors", "conversion"})

        robot = self.table(data, "robot", "robot")
        self.check_keys(robot, "robot", {"name", "title", "n_joints", "urdf", "gravity"})
        name = robot.get("name")
        if not isinstance(name, str) or not name:
            raise self.fail("robot.name", "missing field")
        title = robot.get("title", name)
        n = robot.get("n_joints")
        if isinstance(n, bool) or not isinstance(n, int) or n < 1:
            raise self.fail("robot.n_joints", f"missing or not a positive integer: {n!r}")
        urdf_rel = robot.get("urdf")
        if not isinstance(urdf_rel, str) or not urdf_rel:
            raise self.fail("robot.urdf", "missing field")
        gravity = self.value(robot, "gravity", "robot.gravity", "acceleration").value
        if gravity <= 0:
            raise self.fail("robot.gravity", "must be positive (the magnitude of g)")

        joints = self.joints(data, n)
        lower = _readonly([j.lower for j in joints])
        upper = _readonly([j.upper for j in joints])
        poses = self.poses(data, joints)
        links = self.links(data, n)
        coeffs = self.gravity_coeffs(data)
        gfe = None
        if "gravity_friction_error" in data:
            names_n = len(self.table(data, "gravity_friction_error", "gravity_friction_error").get("values", []))
            gfe = self.vector(data, "gravity_friction_error", "gravity_friction_error", dims="torque", n=names_n)
        friction = self.friction(data)
        motors = self.motors(data)
        conversion = self.conversion(data)

        urdf_path = (self.path.parent / urdf_rel)
        model = RobotModel(
            name=name, title=str(title), path=self.path, urdf_path=urdf_path, n_joints=n,
            joints=joints, lower=lower, upper=upper,
            max_velocity=_readonly([j.max_velocity for j in joints]),
            max_current=_readonly([j.max_current for j in joints]),
            gravity=gravity, poses=MappingProxyType(poses), links=links,
            gravity_coeffs=MappingProxyType(coeffs), gravity_friction_error=gfe,
            friction=friction, motors=motors, conversion=conversion,
            sources=MappingProxyType(dict(self.sources)),
        )
        _check_urdf(model)
        return model

    def joints(self, data: Mapping[str, Any], n: int) -> tuple[Joint, ...]:
        raw = data.get("joints")
        if not isinstance(raw, list):
            raise self.fail("joints", "missing field ([[joints]] tables)")
        if len(raw) != n:
            raise self.fail("joints", f"wrong number of joints: {len(raw)} [[joints]] tables, robot.n_joints = {n}")
        out = []
        for i, rec in enumerate(raw, start=1):
            field = f"joints.{i}"
            if not isinstance(rec, Mapping):
                raise self.fail(field, "expected a table")
            self.check_keys(rec, field, {"index", "name", "kind", "a", "alpha", "d", "theta", "lower",
                                         "upper", "max_velocity", "max_current"})
            if rec.get("index") != i:
                raise self.fail(f"{field}.index", f"expected {i} (joints in order, numbered from 1), got {rec.get('index')!r}")
            kind = rec.get("kind")
            if kind not in JOINT_KINDS:
                raise self.fail(f"{field}.kind", f"unknown joint kind {kind!r} (expected one of {JOINT_KINDS})")
            self.kinds.append(kind)
            jname = rec.get("name", f"joint{i}")
            if jname != f"joint{i}":
                raise self.fail(f"{field}.name", f"must be 'joint{i}' (the URDF joint name), got {jname!r}")
            pos_dim = "angle" if kind == "revolute" else "length"
            vel_dim = "angular_velocity" if kind == "revolute" else "linear_velocity"
            a = self.value(rec, "a", f"{field}.a", "length").value
            alpha = self.value(rec, "alpha", f"{field}.alpha", "angle").value
            d = self.value(rec, "d", f"{field}.d", "length").value
            theta = self.value(rec, "theta", f"{field}.theta", "angle").value
            lo = self.value(rec, "lower", f"{field}.lower", pos_dim).value
            hi = self.value(rec, "upper", f"{field}.upper", pos_dim).value
            if not lo < hi:
                raise self.fail(f"{field}.lower", f"lower {lo:g} is not below upper {hi:g} (SI units)")
            vmax = self.value(rec, "max_velocity", f"{field}.max_velocity", vel_dim).value
            imax = self.value(rec, "max_current", f"{field}.max_current", "current").value
            if vmax <= 0:
                raise self.fail(f"{field}.max_velocity", "must be positive")
            if imax <= 0:
                raise self.fail(f"{field}.max_current", "must be positive")
            out.append(Joint(i, jname, kind, a, alpha, d, theta, lo, hi, vmax, imax))
        return tuple(out)

    def poses(self, data: Mapping[str, Any], joints: tuple[Joint, ...]) -> dict[str, np.ndarray]:
        raw = self.table(data, "poses", "poses")
        for required in ("ready", "nest"):
            if required not in raw:
                raise self.fail(f"poses.{required}", "missing field (simula -p/-c start poses)")
        out = {}
        for pname in raw:
            field = f"poses.{pname}"
            vec = self.vector(raw, pname, field, family="position")
            for j, x in zip(joints, vec.values):
                if not j.lower - 1e-12 <= x <= j.upper + 1e-12:
                    raise self.fail(field, f"joint {j.index} value {x:g} outside [{j.lower:g}, {j.upper:g}] (SI units)")
            out[pname] = vec.values
        return out

    def links(self, data: Mapping[str, Any], n: int) -> tuple[LinkInertial, ...]:
        raw = data.get("links")
        if not isinstance(raw, list):
            raise self.fail("links", "missing field ([[links]] tables)")
        if len(raw) != n:
            raise self.fail("links", f"wrong number of links: {len(raw)}, robot.n_joints = {n}")
        out = []
        for i, rec in enumerate(raw, start=1):
            field = f"links.{i}"
            if not isinstance(rec, Mapping) or rec.get("index") != i:
                raise self.fail(f"{field}.index", f"expected a table with index = {i}")
            self.check_keys(rec, field, {"index", "mass", "com", "inertia"})
            mass = self.value(rec, "mass", f"{field}.mass", "mass").value
            if mass <= 0:
                raise self.fail(f"{field}.mass", "must be positive")
            com = self.vector(rec, "com", f"{field}.com", dims="length", n=3).values
            ixx, iyy, izz, ixy, ixz, iyz = self.vector(rec, "inertia", f"{field}.inertia", dims="inertia", n=6).values
            inertia = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
            eig = np.linalg.eigvalsh(inertia)
            if eig[0] <= 0 or 2 * eig.max() > eig.sum() + 1e-15:
                raise self.fail(f"{field}.inertia", f"not a physical inertia (principal moments {eig})")
            out.append(LinkInertial(i, mass, com, _readonly(inertia)))
        return tuple(out)

    def gravity_coeffs(self, data: Mapping[str, Any]) -> dict[str, Value]:
        raw = self.table(data, "gravity_coeffs", "gravity_coeffs")
        return {k: self.value(raw, k, f"gravity_coeffs.{k}", ("torque", "force")) for k in raw}

    def friction(self, data: Mapping[str, Any]) -> Friction:
        raw = self.table(data, "friction", "friction")
        required = ("coulomb_pos", "coulomb_neg", "viscous_pos", "viscous_neg", "static_pos", "static_neg")
        optional = ("static_typical_max", "static_typical_min", "static_typical_mean", "static_typical_std")
        self.check_keys(raw, "friction", set(required) | set(optional) | {"variation"})
        fam = {"viscous_pos": "viscous", "viscous_neg": "viscous"}
        kw: dict[str, Any] = {}
        for key in required + optional:
            if key in raw or key in required:
                kw[key] = self.vector(raw, key, f"friction.{key}", family=fam.get(key, "effort"))
        for key in required:
            if np.any(kw[key].values < 0):
                raise self.fail(f"friction.{key}", "friction magnitudes must be >= 0 (eq. 4.27 signs are in the model)")
        if "variation" in raw:
            kw["variation"] = self.vector(raw, "variation", "friction.variation", dims="dimensionless")
        return Friction(**kw)

    def motors(self, data: Mapping[str, Any]) -> Motors:
        raw = self.table(data, "motors", "motors")
        self.check_keys(raw, "motors", {"torque_sensitivity", "torque_sensitivity_std",
                                        "torque_sensitivity_trials", "torque_sensitivity_manufacturer"})
        kw: dict[str, Any] = {"torque_sensitivity": self.vector(raw, "torque_sensitivity", "motors.torque_sensitivity",
                                                                dims="torque_sensitivity")}
        for key, dim in (("torque_sensitivity_std", "torque_sensitivity"), ("torque_sensitivity_trials", "dimensionless"),
                         ("torque_sensitivity_manufacturer", "torque_sensitivity")):
            if key in raw:
                kw[key] = self.vector(raw, key, f"motors.{key}", dims=dim)
        if np.any(kw["torque_sensitivity"].values <= 0):
            raise self.fail("motors.torque_sensitivity", "must be positive")
        return Motors(**kw)

    def conversion(self, data: Mapping[str, Any]) -> Conversion:
        raw = self.table(data, "conversion", "conversion")
        self.check_keys(raw, "conversion", {"gear_ratio", "encoder_ratio", "encoder_ratio_consistent",
                                            "encoder_counts_per_motor_rev", "encoder_offset",
                                            "adc_volts_per_count", "sense_resistance", "kappa"})
        g = self.matrix(raw, "gear_ratio", "conversion.gear_ratio", "gear")
        r = self.matrix(raw, "encoder_ratio", "conversion.encoder_ratio", "encoder")
        for fld, m in (("conversion.gear_ratio", g), ("conversion.encoder_ratio", r)):
            if abs(np.linalg.det(m.values)) < 1e-9:
                raise self.fail(fld, "matrix is singular")
        rc = self.matrix(raw, "encoder_ratio_consistent", "conversion.encoder_ratio_consistent", "encoder") \
            if "encoder_ratio_consistent" in raw else None
        return Conversion(
            gear_ratio=g, encoder_ratio=r, encoder_ratio_consistent=rc,
            encoder_counts_per_motor_rev=self.vector(raw, "encoder_counts_per_motor_rev",
                                                     "conversion.encoder_counts_per_motor_rev", dims="dimensionless"),
            encoder_offset=self.vector(raw, "encoder_offset", "conversion.encoder_offset", dims="counts"),
            adc_volts_per_count=self.value(raw, "adc_volts_per_count", "conversion.adc_volts_per_count",
                                           "volts_per_count"),
            sense_resistance=self.vector(raw, "sense_resistance", "conversion.sense_resistance", dims="resistance"),
            kappa=self.vector(raw, "kappa", "conversion.kappa", dims="dimensionless"),
        )


# ----------------------------------------------------------------------------- URDF check

def _floats(text: str | None, n: int, path: Path, field: str) -> np.ndarray:
    try:
        xs = [float(t) for t in (text or "").split()]
    except ValueError:
        raise ModelError(path, field, f"not numbers: {text!r}") from None
    if len(xs) != n:
        raise ModelError(path, field, f"expected {n} numbers, got {text!r}")
    return np.array(xs)


def _check_urdf(model: RobotModel) -> None:
    """The URDF must exist, parse, and agree with the data file on joints, limits, inertials."""
    path = model.urdf_path
    if not path.is_file():
        raise ModelError(model.path, "robot.urdf", f"URDF {path} does not exist")
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise ModelError(path, "<file>", f"not valid XML: {exc}") from None
    if root.tag != "robot":
        raise ModelError(path, "<file>", f"root element is <{root.tag}>, expected <robot>")
    joints = {j.get("name"): j for j in root.findall("joint")}
    links = {lk.get("name"): lk for lk in root.findall("link")}
    if "base_link" not in links:
        raise ModelError(path, "link base_link", "missing (DH frame 0)")
    movable = [n for n, j in joints.items() if j.get("type") not in ("fixed",)]
    if len(movable) != model.n_joints:
        raise ModelError(path, "joints", f"{len(movable)} movable joints, data file has {model.n_joints}")
    for j in model.joints:
        el = joints.get(j.name)
        if el is None:
            raise ModelError(path, f"joint {j.name}", "missing")
        if el.get("type") != j.kind:
            raise ModelError(path, f"joint {j.name}", f"type {el.get('type')!r}, data file says {j.kind!r}")
        lim = el.find("limit")
        if lim is None:
            raise ModelError(path, f"joint {j.name}.limit", "missing")
        for attr, want, src in (("lower", j.lower, f"joints.{j.index}.lower"),
                                ("upper", j.upper, f"joints.{j.index}.upper"),
                                ("velocity", j.max_velocity, f"joints.{j.index}.max_velocity")):
            got = _floats(lim.get(attr), 1, path, f"joint {j.name}.limit.{attr}")[0]
            if abs(got - want) > _LIMIT_TOL:
                raise ModelError(path, f"joint {j.name}.limit.{attr}",
                                 f"{got!r} disagrees with the data file {model.path.name} {src} = {want!r} (SI)")
    _check_urdf_frames(model, root)
    for li in model.links:
        lname = f"link{li.index}"
        el = links.get(lname)
        if el is None:
            raise ModelError(path, f"link {lname}", "missing (DH frame)")
        inertial = el.find("inertial")
        if inertial is None:
            raise ModelError(path, f"link {lname}.inertial", "missing")
        mass_el, inertia_el, origin = inertial.find("mass"), inertial.find("inertia"), inertial.find("origin")
        if mass_el is None or inertia_el is None:
            raise ModelError(path, f"link {lname}.inertial", "needs <mass> and <inertia>")
        mass = _floats(mass_el.get("value"), 1, path, f"link {lname}.inertial.mass")[0]
        xyz = _floats(origin.get("xyz", "0 0 0") if origin is not None else "0 0 0", 3, path,
                      f"link {lname}.inertial.origin")
        rpy = _floats(origin.get("rpy", "0 0 0") if origin is not None else "0 0 0", 3, path,
                      f"link {lname}.inertial.origin")
        if np.any(rpy != 0):
            raise ModelError(path, f"link {lname}.inertial.origin", "rpy must be 0 (inertia given in DH-frame axes)")
        names = ("ixx", "iyy", "izz", "ixy", "ixz", "iyz")
        vals = [_floats(inertia_el.get(k), 1, path, f"link {lname}.inertial.inertia.{k}")[0] for k in names]
        want = li.inertia
        want_vals = [want[0, 0], want[1, 1], want[2, 2], want[0, 1], want[0, 2], want[1, 2]]
        if abs(mass - li.mass) > _INERTIAL_TOL:
            raise ModelError(path, f"link {lname}.inertial.mass", f"{mass!r} disagrees with links.{li.index}.mass = {li.mass!r}")
        if np.max(np.abs(xyz - li.com)) > _INERTIAL_TOL:
            raise ModelError(path, f"link {lname}.inertial.origin", f"{xyz} disagrees with links.{li.index}.com = {li.com}")
        if max(abs(a - b) for a, b in zip(vals, want_vals)) > _INERTIAL_TOL:
            raise ModelError(path, f"link {lname}.inertial.inertia", f"{vals} disagrees with links.{li.index}.inertia")


def _rpy_matrix(rpy: np.ndarray) -> np.ndarray:
    """URDF fixed-axis roll-pitch-yaw: R = Rz(yaw) Ry(pitch) Rx(roll)."""
    (cr, cp, cy), (sr, sp, sy) = np.cos(rpy), np.sin(rpy)
    return np.array([
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ])


def _joint_motion(kind: str, axis: np.ndarray, q: float) -> np.ndarray:
    """The (4, 4) motion of a URDF joint at value q (rotation about / slide along axis)."""
    motion = np.eye(4)
    if kind == "prismatic":
        motion[:3, 3] = axis * q
    elif kind in ("revolute", "continuous"):
        k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
        motion[:3, :3] = np.eye(3) + math.sin(q) * k + (1.0 - math.cos(q)) * (k @ k)
    return motion


def _check_urdf_frames(model: RobotModel, root: ET.Element) -> None:
    """URDF links link1..linkN must be the DH frames 1..N of the data file (a few q)."""
    path = model.urdf_path
    by_child: dict[str, ET.Element] = {}
    for el in root.findall("joint"):
        child = el.find("child")
        if child is None or el.find("parent") is None:
            raise ModelError(path, f"joint {el.get('name')}", "needs <parent> and <child>")
        by_child[child.get("link", "")] = el
    index = {j.name: i for i, j in enumerate(model.joints)}
    span = model.upper - model.lower
    for q in (np.zeros(model.n_joints), model.lower + 0.31 * span, model.lower + 0.77 * span):
        dh = model.base_to_link(q)
        for k in range(model.n_joints):
            link, base_to_link, seen = f"link{k + 1}", np.eye(4), 0
            while link != "base_link":
                el = by_child.get(link)
                seen += 1
                if el is None or seen > 4 * model.n_joints + 4:
                    raise ModelError(path, f"link link{k + 1}", "not connected to base_link")
                origin = el.find("origin")
                step = np.eye(4)
                if origin is not None:
                    step[:3, :3] = _rpy_matrix(_floats(origin.get("rpy", "0 0 0"), 3, path, f"joint {el.get('name')}.origin.rpy"))
                    step[:3, 3] = _floats(origin.get("xyz", "0 0 0"), 3, path, f"joint {el.get('name')}.origin.xyz")
                axis_el = el.find("axis")
                axis = _floats(axis_el.get("xyz") if axis_el is not None else "1 0 0", 3, path, f"joint {el.get('name')}.axis")
                if not np.linalg.norm(axis) > 0:
                    raise ModelError(path, f"joint {el.get('name')}.axis", "zero axis")
                qi = float(q[index[el.get("name")]]) if el.get("name") in index else 0.0
                base_to_link = step @ _joint_motion(el.get("type", ""), axis / np.linalg.norm(axis), qi) @ base_to_link
                link = el.find("parent").get("link", "")
            diff = float(np.max(np.abs(base_to_link - dh[k])))
            if diff > 1e-9:
                raise ModelError(path, f"link link{k + 1}",
                                 f"frame differs from DH frame {k + 1} of {model.path.name} by {diff:.3g} "
                                 f"at q = {np.round(q, 4).tolist()} (URDF origins/axes disagree with the DH table)")
