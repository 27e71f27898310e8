"""Ground truth of the simulated arm: thesis constants, fitted overrides, and disturbance settings.

The simulator's truth is the robot data file (thesis values, ``models``). A
parameter file written by ``calib`` (``--params``, schema ``rcci-calib-params/1``, see
docs/simula.md) replaces any of: the torque sensitivities (``[motors]``), the friction
coefficients of eq. 4.27 and the variation of Table 4.4 (``[friction]``), the gravity
loading coefficients of eq. 4.24 (``[gravity_coeffs]``), the typical static friction of
Table 4.6 (``[static_friction]``), errors of the Denavit-Hartenberg table (``[kinematics]``,
thesis 3.83: the simulated arm's links differ from the nominal model the controller
uses), the links' inertials (``[inertials]``: per-link factors on the URDF's masses and
rotational inertias, and per-motor factors on the data file's rotor inertias, so that the
dynamics' base parameters differ from the data file's),
and simula's own disturbance settings (``[simula]``).
A NaN entry (a joint calib did not fit) keeps the data-file value.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

import numpy as np

from rcci.models import JointFriction, ModelError
from rcci.models.params import SCHEMA, check_schema, read_toml

from .exceptions import ParamsError

PARAMS_SCHEMA = SCHEMA   # the one schema, rcci.models.params


@dataclass(frozen=True)
class Disturbances:
    """Realistic imperfections of the measured signals and of the friction (all ``estimate``
    unless noted; each value's reasoning is in docs/simula.md)."""

    filter_tau: float = 0.015          # s, current-sense low-pass time constant (thesis Appendix C)
    servo_rate_hz: float = 1000.0      # joint microcontroller rate (thesis Appendix C: 1000 Hz)
    ripple_pos: float = 0.5            # PID current fluctuation (uniform, +- this x mean current; thesis 4.5.1 says "as high as the average", i.e. peaks near 1x)
    ripple_cur: float = 0.05           # current-mode fluctuation, relative
    ripple_floor: float = 0.05         # A, fluctuation present even at zero mean current
    adc_noise: float = 1.0             # ADC counts (1 sigma), sensor noise after the filter
    pot_noise: float = 1.0             # ADC counts (1 sigma) on the potentiometer channels
    cold_excess: float = 0.20          # friction excess of a cold joint (thesis 4.5.3: "as much as 20%")
    warmup_time: float = 20.0          # s of motion to warm a joint (e-folding)
    cooldown_time: float = 600.0       # s of rest to cool it again (e-folding)
    pulley_friction: float = 0.01      # N*m, Coulomb friction of the measurement pulley (same both ways, 4.5.2)
    start_warm: bool = False           # start with warmed-up joints (no cold excess)


@dataclass(frozen=True)
class Truth(JointFriction):
    """Per-joint ground-truth constants the simulated arm uses (SI, joint level): the friction
    of eq. 4.27 (Tables 4.2, 4.3, 4.5; the fields of ``JointFriction``) and the following."""

    sigma: np.ndarray                  # N*m/A, motor torque sensitivities (Table 4.1)
    variation: np.ndarray              # relative (Table 4.4)
    hold_mean: np.ndarray              # typical static friction at a halt (Table 4.6 mean)
    hold_std: np.ndarray               # (Table 4.6 standard deviation)
    gravity_coeffs: dict[str, float]   # eq. 4.24 coefficients (N*m / N) the URDF is tuned to
    disturbances: Disturbances = field(default_factory=Disturbances)
    source: str = "data file"
    # (n, 4) errors of each joint's DH parameters (d theta rad, d d m, d a m, d alpha rad),
    # added to the data file's table (thesis 3.83); zero: the arm is the nominal model
    dh_errors: np.ndarray | None = None
    # per-link factors on the URDF's inertials ([inertials]): the mass (centre of mass kept,
    # the rotational inertia about it scaled alike) and, on top, the rotational inertia about
    # the centre of mass; None: the URDF's
    mass_scale: np.ndarray | None = None
    inertia_scale: np.ndarray | None = None
    # per-motor factors on the data file's rotor inertias J_m ([inertials] rotor_scale; the
    # data file's joint ``rotor_inertia`` / G_jj^2); None: the data file's
    rotor_scale: np.ndarray | None = None


def motor_inertia(model, truth: Truth) -> np.ndarray:
    """J_m per motor (n,), kg*m^2, of the simulated arm: the data file's (``RobotModel.motor_inertia``)
    times ``truth.rotor_scale``; ``model.rotor_matrix(motor_inertia(model, truth))`` reflects them."""
    jm = np.asarray(model.motor_inertia, dtype=float)
    return jm if truth.rotor_scale is None else jm * np.asarray(truth.rotor_scale, dtype=float)


def truth_from_model(model) -> Truth:
    """The data file's values (thesis tables for the PUMA, estimates for the Microbo)."""
    fr = model.friction
    n = model.n_joints
    if fr.static_typical_mean is not None and fr.static_typical_std is not None:
        hold_mean = np.array(fr.static_typical_mean.values, dtype=float)
        hold_std = np.array(fr.static_typical_std.values, dtype=float)
    else:
        # estimate: Table 4.6 is PUMA-only; there the std is 0.13-0.47 of Fs (Table 4.5)
        hold_mean = np.zeros(n)
        hold_std = 0.3 * 0.5 * (np.asarray(fr.static_pos.values) + np.asarray(fr.static_neg.values))
    variation = np.array(fr.variation.values, dtype=float) if fr.variation is not None else np.zeros(n)
    return Truth(
        sigma=np.array(model.motors.torque_sensitivity.values, dtype=float),
        **JointFriction.arrays(fr),
        variation=variation,
        hold_mean=hold_mean,
        hold_std=hold_std,
        gravity_coeffs={k: float(v.value) for k, v in model.gravity_coeffs.items()},
    )


def _vector(path: str, section: str, key: str, raw: Any, base: np.ndarray, *, nonneg: bool) -> np.ndarray:
    """A per-joint vector from a parameter file; NaN entries keep ``base``."""
    where = f"{path}: [{section}] {key}"
    if not isinstance(raw, list) or len(raw) != len(base):
        raise ParamsError(f"{where}: expected a list of {len(base)} numbers, got {raw!r}")
    out = base.copy()
    for i, x in enumerate(raw):
        if isinstance(x, bool) or not isinstance(x, (int, float)):
            raise ParamsError(f"{where}[{i}]: {x!r} is not a number")
        if math.isnan(x):
            continue
        if math.isinf(x) or (nonneg and x < 0):
            raise ParamsError(f"{where}[{i}]: {x!r} is not a valid value (finite{', >= 0' if nonneg else ''})")
        out[i] = float(x)
    return out


def read_params_file(path: str | Path) -> dict[str, Any]:
    """A parameter file's TOML as a dict (``rcci.models.params``, the one reader); ParamsError
    names the file when it is not readable TOML."""
    try:
        return read_toml(path)
    except ModelError as exc:
        raise ParamsError(str(exc)) from None


def load_params(path: str | Path, robot: str, truth: Truth) -> Truth:
    """``truth`` with the values of a calib parameter file applied; ParamsError names file and field."""
    return apply_params(read_params_file(path), str(path), robot, truth)


DH_ERROR_KEYS = ("dtheta", "dd", "da", "dalpha")   # [kinematics]: rad, m, m, rad per joint


def apply_params(data: dict[str, Any], path: str, robot: str, truth: Truth) -> Truth:
    """``truth`` with the values of a parsed parameter file ``data`` applied (``path`` names
    it in errors); the same checks as ``load_params``."""
    try:
        head = check_schema(data, path)
    except ModelError as exc:
        raise ParamsError(str(exc)) from None
    if head.get("robot") != robot:
        raise ParamsError(f"{path}: parameters are for robot {head.get('robot')!r}, simula runs {robot!r}")
    # [dynamics] (calib's identified base parameters) describes the arm too, but as combinations
    # simula cannot build links from: it is accepted and not used
    known = {"calib", "motors", "friction", "gravity_coeffs", "static_friction", "simula", "kinematics",
             "inertials", "dynamics"}
    unknown = set(data) - known
    if unknown:
        raise ParamsError(f"{path}: unknown section(s) {sorted(unknown)} (known: {sorted(known)})")
    kw: dict[str, Any] = {}
    motors = data.get("motors", {})
    if "torque_sensitivity" in motors:
        sigma = _vector(path, "motors", "torque_sensitivity", motors["torque_sensitivity"], truth.sigma, nonneg=True)
        if np.any(sigma <= 0):
            raise ParamsError(f"{path}: [motors] torque_sensitivity must be positive")
        kw["sigma"] = sigma
    fr = data.get("friction", {})
    for key in ("coulomb_pos", "coulomb_neg", "viscous_pos", "viscous_neg", "static_pos", "static_neg", "variation"):
        if key in fr:
            kw[key] = _vector(path, "friction", key, fr[key], getattr(truth, key), nonneg=True)
    st = data.get("static_friction", {})
    if "mean" in st:
        kw["hold_mean"] = _vector(path, "static_friction", "mean", st["mean"], truth.hold_mean, nonneg=False)
    if "std" in st:
        kw["hold_std"] = _vector(path, "static_friction", "std", st["std"], truth.hold_std, nonneg=True)
    gc = data.get("gravity_coeffs", {})
    coeffs = dict(truth.gravity_coeffs)
    for name in truth.gravity_coeffs:
        if name in gc:
            x = gc[name]
            if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x):
                raise ParamsError(f"{path}: [gravity_coeffs] {name} = {x!r} is not a finite number")
            coeffs[name] = float(x)
    extra = [k for k in gc if k.startswith("c") and "_" not in k and k not in truth.gravity_coeffs]
    if extra:
        raise ParamsError(f"{path}: [gravity_coeffs] {extra} are not coefficients of robot {robot!r}")
    kw["gravity_coeffs"] = coeffs
    kin = data.get("kinematics", {})
    if any(k in kin for k in DH_ERROR_KEYS):
        n = len(truth.sigma)
        base = np.zeros((n, 4)) if truth.dh_errors is None else np.array(truth.dh_errors, dtype=float)
        for c, key in enumerate(DH_ERROR_KEYS):
            if key in kin:
                # NaN (an error the fit could not identify) adds nothing to the nominal table
                col = _vector(path, "kinematics", key, kin[key], np.full(n, np.nan), nonneg=False)
                base[:, c] = np.where(np.isfinite(col), col, base[:, c])
        kw["dh_errors"] = base
    inert = data.get("inertials", {})
    bad = set(inert) - {"mass_scale", "inertia_scale", "rotor_scale"}
    if bad:
        raise ParamsError(f"{path}: [inertials] unknown key(s) {sorted(bad)} "
                          "(known: inertia_scale, mass_scale, rotor_scale)")
    for key in ("mass_scale", "inertia_scale", "rotor_scale"):
        if key in inert:
            v = _vector(path, "inertials", key, inert[key], np.ones(len(truth.sigma)), nonneg=True)
            if np.any(v <= 0):
                raise ParamsError(f"{path}: [inertials] {key} must be positive factors")
            kw[key] = v
    sim = data.get("simula", {})
    if sim:
        names = {f.name: f for f in fields(Disturbances)}
        dk: dict[str, Any] = {}
        for key, x in sim.items():
            if key not in names:
                raise ParamsError(f"{path}: [simula] unknown setting {key!r} (known: {sorted(names)})")
            if key == "start_warm":
                if not isinstance(x, bool):
                    raise ParamsError(f"{path}: [simula] start_warm must be true or false")
                dk[key] = x
                continue
            if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x) or x < 0:
                raise ParamsError(f"{path}: [simula] {key} = {x!r} must be a finite number >= 0")
            dk[key] = float(x)
        kw["disturbances"] = replace(truth.disturbances, **dk)
    return replace(truth, source=path, **kw)


@dataclass(frozen=True)
class PulleyLoad:
    """A mass on a string wound on a drum of ``radius`` on joint ``joint`` (1-based), thesis Figure 4.2.

    The mass rises when the joint angle increases (``sign`` +1) or decreases (-1); its
    weight loads the joint with a constant torque -sign m g r (the drum keeps the lever
    arm constant), plus the pulley's own Coulomb friction.
    """

    joint: int
    mass: float
    radius: float
    sign: int = 1


def parse_load(spec: str, n_joints: int) -> PulleyLoad | None:
    """``pulley:joint=3,mass=2.0,radius=0.05[,sign=-1]`` or ``none``; ValueError says what is wrong."""
    spec = spec.strip()
    if spec in ("", "none"):
        return None
    kind, _, rest = spec.partition(":")
    if kind != "pulley":
        raise ValueError(f"load {spec!r}: unknown load kind {kind!r} (known: pulley, none)")
    values: dict[str, str] = {}
    for item in filter(None, (s.strip() for s in rest.split(","))):
        key, eq, val = item.partition("=")
        if not eq:
            raise ValueError(f"load {spec!r}: {item!r} is not key=value")
        values[key.strip()] = val.strip()
    missing = {"joint", "mass", "radius"} - set(values)
    if missing:
        raise ValueError(f"load {spec!r}: missing {sorted(missing)}")
    unknown = set(values) - {"joint", "mass", "radius", "sign"}
    if unknown:
        raise ValueError(f"load {spec!r}: unknown key(s) {sorted(unknown)}")
    try:
        joint = int(values["joint"])
        mass = float(values["mass"])
        radius = float(values["radius"])
        sign = int(values.get("sign", "1"))
    except ValueError as exc:
        raise ValueError(f"load {spec!r}: {exc}") from None
    if not 1 <= joint <= n_joints:
        raise ValueError(f"load {spec!r}: joint must be 1..{n_joints}")
    if not (math.isfinite(mass) and mass >= 0 and math.isfinite(radius) and radius > 0):
        raise ValueError(f"load {spec!r}: need mass >= 0 kg and radius > 0 m")
    if sign not in (1, -1):
        raise ValueError(f"load {spec!r}: sign must be 1 or -1")
    return PulleyLoad(joint, mass, radius, sign)
