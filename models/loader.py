"""Parsing and validating one robot data file into a :class:`rcci.models.robot.RobotModel`;
every failure is a :class:`rcci.models.exceptions.ModelError` naming the file, the field and the problem."""
from __future__ import annotations

import math
import tomllib
from pathlib import Path
from types import MappingProxyType
from typing import Any, Mapping

import numpy as np

from .drive import Friction
from .exceptions import ModelError
from .modified_dh import CraigRow, frame_shifts, move_inertial, standard_rows
from .quantities import Matrix, Source, Value, Vector
from .robot import Conversion, GravityGrouping, Joint, LinkInertial, Motors, RobotModel
from .units import JOINT_DIMS, JOINT_KINDS, UNITS
from .urdf import check_urdf

def readonly(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=float)
    a.flags.writeable = False
    return a


class Loader:
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
        elif not (tag.startswith("thesis ") or tag.startswith("published ")):
            raise self.fail(field, f"source {tag!r} is neither 'thesis <reference>', "
                                   "'published <reference>' nor 'estimate'")
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
            pair = JOINT_DIMS[family]
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
            unc = readonly([self.number(u, f"{field}.uncertainty[{i}]") * f
                             for i, (u, f) in enumerate(zip(ur, factors))])
            if np.any(unc < 0):
                raise self.fail(field, "negative uncertainty")
        names = rec.get("names")
        if names is not None and (not isinstance(names, list) or len(names) != n
                                  or not all(isinstance(s, str) for s in names)):
            raise self.fail(field, f"'names' must be a list of {n} strings")
        src = self.source_of(rec, field)
        return Vector(readonly([x * f for x, f in zip(xs, factors)]), tuple(sis), src, unc,
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
        values = readonly(np.array(rows) * np.array(factors)[None, :])
        return Matrix(values, tuple(sis), self.source_of(rec, field))

    # -- the file ----------------------------------------------------------------------

    def load(self, check: bool = True) -> RobotModel:
        """The model of the data file; ``check=False`` skips the URDF check (for writing
        the URDF from the data file: rcci.models.urdf_write)."""
        try:
            with open(self.path, "rb") as fh:
                data = tomllib.load(fh)
        except tomllib.TOMLDecodeError as exc:
            raise self.fail("<file>", f"not valid TOML: {exc}") from None
        except OSError as exc:
            raise self.fail("<file>", f"cannot read: {exc}") from None
        self.check_keys(data, "<top level>", {"robot", "joints", "poses", "links", "gravity_coeffs",
                                              "gravity_friction_error", "gravity_grouping", "friction", "motors",
                                              "conversion", "flange"})

        robot = self.table(data, "robot", "robot")
        self.check_keys(robot, "robot", {"name", "title", "n_joints", "urdf", "gravity", "dh"})
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

        convention = robot.get("dh", "standard")
        if convention not in ("standard", "modified"):
            raise self.fail("robot.dh", f"unknown DH convention {convention!r} (expected 'standard' or 'modified')")
        joints = self.joints(data, n)
        links = self.links(data, n)
        shifts = np.broadcast_to(np.eye(4), (n, 4, 4))
        if convention == "modified":
            joints, links, shifts = self.from_modified(data, joints, links)
        elif "flange" in data:
            raise self.fail("flange", "a [flange] row belongs to a modified-DH table (robot.dh = 'modified')")
        lower = readonly([j.lower for j in joints])
        upper = readonly([j.upper for j in joints])
        poses = self.poses(data, joints)
        coeffs = self.gravity_coeffs(data)
        grouping = self.gravity_grouping(data, n, coeffs)
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
            max_velocity=readonly([j.max_velocity for j in joints]),
            max_current=readonly([j.max_current for j in joints]),
            gravity=gravity, poses=MappingProxyType(poses), links=links,
            gravity_coeffs=MappingProxyType(coeffs), gravity_friction_error=gfe,
            friction=friction, motors=motors, conversion=conversion,
            sources=MappingProxyType(dict(self.sources)), gravity_grouping=grouping,
            dh_convention=convention, data_frames=readonly(shifts),
            **self.optional_limits(joints),
        )
        if check:
            check_urdf(model)
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
                                         "upper", "max_velocity", "max_current", "max_acceleration",
                                         "max_jerk", "max_effort"})
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
            extra = {}
            for key, fam in (("max_acceleration", "acceleration"), ("max_jerk", "jerk"), ("max_effort", "effort")):
                if key in rec:
                    x = self.value(rec, key, f"{field}.{key}", JOINT_DIMS[fam][0 if kind == "revolute" else 1]).value
                    if x <= 0:
                        raise self.fail(f"{field}.{key}", "must be positive")
                    extra[key] = x
            out.append(Joint(i, jname, kind, a, alpha, d, theta, lo, hi, vmax, imax, **extra))
        return tuple(out)

    def optional_limits(self, joints: tuple[Joint, ...]) -> dict[str, np.ndarray | None]:
        """max_acceleration, max_jerk, max_effort as arrays: given for every joint or for none."""
        out: dict[str, np.ndarray | None] = {}
        for key in ("max_acceleration", "max_jerk", "max_effort"):
            vals = [getattr(j, key) for j in joints]
            given = [v is not None for v in vals]
            if any(given) and not all(given):
                missing = [j.index for j, g in zip(joints, given) if not g]
                raise self.fail(f"joints.{missing[0]}.{key}", f"missing: give {key} for every joint or for none "
                                                              f"(missing for joints {missing})")
            out[key] = readonly(vals) if all(given) else None
        return out

    def from_modified(self, data: Mapping[str, Any], joints: tuple[Joint, ...],
                      links: tuple[LinkInertial, ...]) -> tuple[tuple[Joint, ...], tuple[LinkInertial, ...], np.ndarray]:
        """A modified-DH (Craig) table, its [flange] row and links in Craig's frames, as the
        equivalent standard-DH joints and links and the frame shifts (rcci.models.modified_dh)."""
        first = joints[0]
        if first.a != 0.0 or first.alpha != 0.0:
            raise self.fail("joints.1.a", f"a modified-DH table must start with a0 = alpha0 = 0 (frame 0 is the "
                                          f"base frame), got a0 = {first.a:g} m, alpha0 = {first.alpha:g} rad")
        for j in joints:
            if j.kind != "revolute":
                raise self.fail(f"joints.{j.index}.kind", "the modified-DH conversion handles revolute joints only")
        rec = self.table(data, "flange", "flange")
        self.check_keys(rec, "flange", {"a", "alpha", "d"})
        fa = self.value(rec, "a", "flange.a", "length").value
        falpha = self.value(rec, "alpha", "flange.alpha", "angle").value
        fd = self.value(rec, "d", "flange.d", "length").value
        if falpha != 0.0:
            raise self.fail("flange.alpha", f"must be 0 (a flange twist has no standard-DH equivalent in the last "
                                            f"link frame; put it in the tool transform), got {falpha:g} rad")
        rows = [CraigRow(j.a, j.alpha, j.d, j.theta) for j in joints]
        std = standard_rows(rows, fa, fd)
        shifts = frame_shifts(rows, fa, fd)
        new_joints = tuple(Joint(j.index, j.name, j.kind, a, alpha, d, theta, j.lower, j.upper, j.max_velocity,
                                 j.max_current, j.max_acceleration, j.max_jerk, j.max_effort)
                           for j, (a, alpha, d, theta) in zip(joints, std))
        new_links = []
        for li, shift in zip(links, shifts):
            com, inertia = move_inertial(shift, li.com, li.inertia)
            new_links.append(LinkInertial(li.index, li.mass, readonly(com), readonly((inertia + inertia.T) / 2)))
        return new_joints, tuple(new_links), shifts

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
            out.append(LinkInertial(i, mass, com, readonly(inertia)))
        return tuple(out)

    def gravity_coeffs(self, data: Mapping[str, Any]) -> dict[str, Value]:
        if "gravity_coeffs" not in data:  # a new arm before its coefficients are known
            return {}
        raw = self.table(data, "gravity_coeffs", "gravity_coeffs")
        return {k: self.value(raw, k, f"gravity_coeffs.{k}", ("torque", "force")) for k in raw}

    def gravity_grouping(self, data: Mapping[str, Any], n: int,
                         coeffs: Mapping[str, Value]) -> GravityGrouping | None:
        """The optional [gravity_grouping] table: centre-of-mass form and coefficient meanings."""
        if "gravity_grouping" not in data:
            return None
        field = "gravity_grouping"
        raw = self.table(data, "gravity_grouping", field)
        self.check_keys(raw, field, {"com_form", "meanings", "source", "why"})
        form = raw.get("com_form")
        if not isinstance(form, list) or len(form) != n or not all(
                isinstance(r, list) and len(r) == 3 and all(isinstance(x, str) and x.strip() for x in r) for r in form):
            raise self.fail(f"{field}.com_form", f"must be a list of {n} lists of 3 expressions (strings)")
        meanings = self.table(raw, "meanings", f"{field}.meanings")
        if list(meanings) != list(coeffs):
            raise self.fail(f"{field}.meanings", f"names {list(meanings)} differ from gravity_coeffs {list(coeffs)}")
        if not all(isinstance(v, str) and v.strip() for v in meanings.values()):
            raise self.fail(f"{field}.meanings", "each meaning must be a non-empty expression string")
        src = self.source_of(raw, field)
        return GravityGrouping(tuple(tuple(r) for r in form), MappingProxyType(dict(meanings)), src)

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
