"""What a log was recorded against, and the ground truth the report compares the fits with.

Every log of ``calib record`` / ``calib regen-logs`` carries ``meta.truth`` (docs/calib.md):

* ``{"kind": "simula", "seed": N, "params_file": path or null, "params_toml": the file's
  text or null, "simula_args": [...]}`` for a simula, which is then rebuilt exactly: the
  robot data file with the parameter file applied (rci.simula.params), the gravity
  coefficients recovered by fitting its Pinocchio gravity (URDF tuned to the file, DH
  errors applied) to the regressor of 4.24, not copied from a table;
* ``{"kind": "robot"}`` for a real arm (or a simula calib was not told about): there is
  no truth, and the report says so instead of scoring.

Logs recorded before the truth travelled with them (``simula_seed`` but no ``truth``) were
all recorded against the data file; they are read as such and the report says it assumed so.
"""
from __future__ import annotations

import hashlib
import json
import tomllib
from dataclasses import dataclass

import numpy as np

from rcci.calib.exceptions import CalibError, LogError
from rcci.calib.robot import RobotInfo
from rcci.models import FRICTION_KEYS, JointFriction


@dataclass(frozen=True)
class GroundTruth(JointFriction):
    """Ground truth in SI units (the friction of eq. 4.27: the fields of ``JointFriction``);
    ``gravity_fit_residual`` (N m) says how exactly the simulated arm's gravity follows 4.24
    (DH errors bend it a little)."""

    sigma: np.ndarray
    variation: np.ndarray
    hold_mean: np.ndarray
    hold_std: np.ndarray
    gravity: np.ndarray
    gravity_fit_residual: float
    dh_errors: np.ndarray        # (n, 4): d theta, d d, d a, d alpha
    source: str                  # what the logs say they were recorded against
    seeds: tuple[int, ...] = ()


def truth_meta(seed: int | None = None, params: str | None = None,
               simula_args: list[str] | None = None) -> dict:
    """``meta.truth`` for a log: of a simula (``seed`` given) or of a robot (``seed`` None)."""
    if seed is None:
        return {"kind": "robot"}
    text = None
    if params:
        try:
            with open(params, encoding="utf-8") as f:
                text = f.read()
        except (OSError, UnicodeDecodeError) as exc:
            raise CalibError(f"{params}: cannot read the simula parameter file: {exc}") from None
    return {"kind": "simula", "seed": int(seed), "params_file": params, "params_toml": text,
            "params_sha256": hashlib.sha256(text.encode()).hexdigest() if text else None,
            "simula_args": list(simula_args or [])}


def parse_against(spec: str) -> dict:
    """``--against`` of calib record: ``robot`` or ``simula:seed=N[,params=FILE]``."""
    spec = spec.strip()
    if spec == "robot":
        return truth_meta()
    kind, _, rest = spec.partition(":")
    if kind != "simula":
        raise CalibError(f"--against {spec!r}: say 'robot' or 'simula:seed=N[,params=FILE]'")
    kv = dict(item.partition("=")[::2] for item in rest.split(",") if item)
    if "seed" not in kv or set(kv) - {"seed", "params"}:
        raise CalibError(f"--against {spec!r}: simula needs seed=N and at most params=FILE")
    try:
        seed = int(kv["seed"])
    except ValueError:
        raise CalibError(f"--against {spec!r}: seed {kv['seed']!r} is not an integer") from None
    return truth_meta(seed, kv.get("params"))


def log_truth(trace) -> dict:
    """The ``truth`` a log says it was recorded against (legacy logs: the data file)."""
    t = trace.meta.get("truth")
    if t is None:
        if "simula_seed" in trace.meta:
            return {"kind": "simula", "seed": int(trace.meta["simula_seed"]), "params_file": None,
                    "params_toml": None, "legacy": True}
        return {"kind": "robot"}
    if not isinstance(t, dict) or t.get("kind") not in ("simula", "robot"):
        raise LogError(trace.path, None, f"metadata 'truth' = {t!r} is neither a simula's nor 'robot'")
    return t


def truth_label(trace) -> str:
    """What a log was recorded against, in one line that also identifies it: ``robot``, or
    ``simula seed N on FILE (sha256 0123456789ab)`` (``the data file`` when no parameter file).
    Two logs of the same label were recorded against the same truth."""
    t = log_truth(trace)
    if t["kind"] != "simula":
        return f"robot {trace.robot}"
    text = t.get("params_toml")
    digest = t.get("params_sha256") or (hashlib.sha256(text.encode()).hexdigest() if text else None)
    where = f"{t.get('params_file')} (sha256 {digest[:12]})" if digest else "the data file"
    return f"simula {trace.robot} seed {int(t['seed'])} on {where}"


def _arm_key(t: dict) -> str:
    """What makes two simulas the same arm: the parameter file's content (seeds differ in noise)."""
    return json.dumps([t.get("kind"), t.get("params_toml")])


def truth_of(traces, info: RobotInfo) -> GroundTruth | None:
    """The ground truth shared by ``traces``; None when any was recorded against a robot.
    CalibError when they were recorded against simulas built from different parameter files."""
    metas = [log_truth(tr) for tr in traces]
    if any(m["kind"] == "robot" for m in metas):
        return None
    keys = {_arm_key(m) for m in metas}
    if len(keys) > 1:
        raise CalibError("the logs were recorded against simulas with different parameter files: "
                         + "; ".join(sorted({f"{tr.path}: {log_truth(tr).get('params_file')}" for tr in traces})))
    m = metas[0]
    data = tomllib.loads(m["params_toml"]) if m.get("params_toml") else None
    where = m.get("params_file") or "robot data file"
    legacy = any(x.get("legacy") for x in metas)
    source = (f"simula on {where}" + (" (log predates the truth metadata: the data file assumed)" if legacy else ""))
    seeds = tuple(sorted({int(x["seed"]) for x in metas}))
    return simulator_truth(info, data, source, seeds)


def simulator_truth(info: RobotInfo, params: dict | None = None, source: str = "simula on robot data file",
                    seeds: tuple[int, ...] = (), samples: int = 300, seed: int = 0) -> GroundTruth:
    """Ground truth of a simula built from the data file and the parsed parameter file ``params``."""
    import pinocchio as pin

    from rcci.models import load_robot
    from rci.simula.arm import SimulatedArm
    from rci.simula.exceptions import ParamsError
    from rci.simula.params import apply_params, truth_from_model

    model = load_robot(info.name)
    t = truth_from_model(model)
    if params is not None:
        try:
            t = apply_params(params, source, info.name, t)
        except ParamsError as exc:
            raise CalibError(f"the logs' truth: {exc}") from None
    arm = SimulatedArm(model, t, seed=0, start="ready")
    data = arm.pm.createData()
    rng = np.random.default_rng(seed)
    A, y = [], []
    for _ in range(samples):
        q = rng.uniform(info.lower, info.upper)
        A.append(info.regressor(q))
        y.append(pin.computeGeneralizedGravity(arm.pm, data, q))
    A, y = np.vstack(A), np.concatenate(y)
    c, *_ = np.linalg.lstsq(A, y, rcond=None)
    n = model.n_joints
    return GroundTruth(sigma=np.array(t.sigma), **{k: np.array(getattr(t, k)) for k in FRICTION_KEYS},
                 variation=np.array(t.variation), hold_mean=np.array(t.hold_mean), hold_std=np.array(t.hold_std),
                 gravity=c, gravity_fit_residual=float(np.abs(A @ c - y).max()),
                 dh_errors=np.zeros((n, 4)) if t.dh_errors is None else np.array(t.dh_errors),
                 source=source, seeds=seeds)


def simula_variation(robot: str, seed: int, joint: int, window: tuple[float, float],
                     params: dict | None = None) -> tuple[float, float]:
    """(peak, sqrt(2) x RMS) of the relative Coulomb variation simula applies to
    ``joint`` (1-based) over ``window`` (rad), for a simula started with ``seed`` (and
    the parameter file ``params``, which may change the amplitude).

    This reads the simulator's own friction pattern (rci.simula), so that the fitted
    Table 4.4 value can be compared with what the logs really contain, not only with
    the bound the simulator was given.
    """
    pattern = simula_pattern(robot, seed, joint, window, params)[1]
    return float(np.abs(pattern).max()), float(np.sqrt(2.0) * pattern.std())


def simula_pattern(robot: str, seed: int, joint: int, window: tuple[float, float],
                   params: dict | None = None, points: int = 4000) -> tuple[np.ndarray, np.ndarray]:
    """(angles, relative Coulomb variation v p(q)) of ``joint`` over ``window`` in a simula
    started with ``seed``."""
    from rcci.models import load_robot
    from rci.simula.arm import SimulatedArm
    from rci.simula.params import apply_params, truth_from_model

    model = load_robot(robot)
    truth = truth_from_model(model)
    if params is not None:
        truth = apply_params(params, "the logs' truth", robot, truth)
    arm = SimulatedArm(model, truth, seed=seed, start="ready")
    th = np.linspace(window[0], window[1], points)
    q = np.zeros((len(th), model.n_joints))
    q[:, joint - 1] = th
    pattern = np.array([arm.friction.pattern(x)[joint - 1] for x in q]) * truth.variation[joint - 1]
    return th, pattern
