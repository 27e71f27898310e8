"""Model-based feed-forward in current mode (thesis eq. 4.6, 4.38): gravity-only or computed torque, plus a joint PD.

Three servo modes a motion can run in (``arm.feedforward(mode, ...)``, for the motions moved
after it, like ``setvel``):

* ``"position"``: every joint position servoed (POS), the thesis's normal RCCL (default);
* ``"gravity"``: every joint in current mode (CUR) with ``t = t_g(q_p) + f(qd_p) + t_pd``,
  the thesis's gravity compensation (2.2.2, 4.38) of the *planned* joints plus friction;
* ``"computed"``: computed torque, ``t = D(q_p) qdd_p + c(q_p, qd_p) + t_g(q_p) + f(qd_p) + t_pd``.

``q_p, qd_p, qdd_p`` is the planned motion: the generator's joint angles (the contract's
``q``), differenced over the last three samples (neither generator exposes a joint
acceleration: in Cartesian mode the joints come from the inverse kinematics of each sample,
so differencing is the one definition that holds for both). Over the period that takes the
plan from ``q_{k-1}`` to ``q_k`` the feed-forward uses ``q_p = (q_k + q_{k-1}) / 2``,
``qd_p = (q_k - q_{k-1}) / dt`` and ``qdd_p`` the second difference of ``q_{k-2..k}``
(centred half a period early).

``t_pd`` is a joint PD on the tracking error at the measured sample, each joint scaled by
its own inertia so the gains are one natural frequency and one damping ratio for every
joint: ``t_pd_j = D_jj(q_p) (w^2 e_j + 2 zeta w e'_j)``, ``w = 2 pi natural_hz`` (rad/s),
``e = q_plan - q_measured`` (rad, m), ``e'`` its rate (rad/s). Units: N*m (N for a
prismatic joint). Friction ``f`` is eq. 4.27 of the data file (``JointModel.friction``,
Coulomb + viscous in the direction the plan moves the joint, 0 where the plan is at rest).

The torque becomes DAC values through 4.38 exactly as compliance does
(``JointModel.dac_per_joint_torque``, K_dac G^-T), clipped at the motor current limit
(A.5.1); clipped samples are counted (``FeedForwardControl.saturated``). A non-finite torque
raises ``FeedForwardError``: the control level freezes the generator and the arm holds,
position servoed where it was measured (``rccl.session``).
"""
from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from rci.conversions import DAC_MAX, friction_torque

from .adaptive.control import Command
from .adaptive.force import JointModel
from .exceptions import BadRequest, MotionError

MODES = ("position", "gravity", "computed")
# the default natural frequency, a fraction of the sample rate (12.5 Hz at 250 Hz), critically damped:
# the PD closes through about two periods (a period of link latency, the backward difference of the
# rate). Measured on the PUMA 260's tour at 250 Hz (bench/feedforward.py --hz): 2, 4, 8, 12 Hz give a
# computed-torque RMS error of 2.25, 0.60, 0.16, 0.08 mm; 20 Hz (rate/12.5) rings into the current limit
# (284 of 791 samples clipped, 0.18 mm); 30 Hz, 726 clipped
DEFAULT_HZ_PER_RATE = 1.0 / 20.0
# ...and at most 12.5 Hz: the damping term differences encoder counts, and at a high rate one count per
# period is a large rate; at 1 kHz (--rate 1000 --hz) 12 Hz clips no sample, 25 Hz clips 326 of 3158
# (10 %), the uncapped 50 Hz 2527 (80 %): the PD chatters on the counts into the current limit
DEFAULT_MAX_HZ = 12.5
DAMPING = 1.0
# refused above rate / 15 (see DEFAULT_HZ_PER_RATE: rate / 12.5 rings)
MAX_HZ_PER_RATE = 1.0 / 15.0


class FeedForwardError(MotionError):
    """The feed-forward torque could not be computed (a non-finite model output, a bad parameter vector)."""


@dataclass(frozen=True)
class Gains:
    """The joint PD of the current-mode servo: natural frequency (Hz) and damping ratio (1 = critical).

    ``natural_hz`` None (default): 1/20 of the sample rate, at most 12.5 Hz, following rate
    changes (12.5 Hz at 250 Hz and above, 1.8 Hz at the thesis's 36 Hz). Joint j's stiffness is
    ``D_jj (2 pi natural_hz)^2`` N*m/rad and its damping
    ``2 damping (2 pi natural_hz) D_jj`` N*m*s/rad, ``D_jj`` the model's inertia of joint j
    at the planned joints (kg*m^2; kg for a prismatic joint, then N/m and N*s/m).
    """

    natural_hz: float | None = None
    damping: float = DAMPING

    def __post_init__(self) -> None:
        for name in ("natural_hz", "damping"):
            v = getattr(self, name)
            if v is None and name == "natural_hz":
                continue
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
                raise BadRequest(f"feedforward gains: {name}={v!r} must be a positive finite number")

    def check_rate(self, rate_hz: float, where: str) -> None:
        """Refuse a natural frequency above ``MAX_HZ_PER_RATE`` x the sample rate (the loop would ring)."""
        top = MAX_HZ_PER_RATE * float(rate_hz)
        if self.natural_hz is not None and self.natural_hz > top:
            raise BadRequest(f"{where}: natural_hz={self.natural_hz:g} Hz is above {top:g} Hz, 1/15 of the "
                             f"{rate_hz:g} Hz sample rate: the PD closes through about two periods of "
                             "latency and would ring; lower it or raise rate_hz")

    def hz(self, rate_hz: float) -> float:
        """The natural frequency (Hz) at sample rate ``rate_hz``."""
        if self.natural_hz is None:
            return min(DEFAULT_HZ_PER_RATE * float(rate_hz), DEFAULT_MAX_HZ)
        return float(self.natural_hz)


class DynamicsModel:
    """Joint torques of the arm's rigid-body model (eq. 4.6): D qdd + c + t_g, SI, joint level.

    ``theta`` None: the data file's inertials (the generated ``inverse_dynamics``) plus the motor
    rotors reflected to the joints, ``rotor @ qdd`` (``rotor``: (n, n) kg*m^2, default
    ``data_file_rotor(robot)``: the data file's ``rotor_inertia``, what the generated
    ``rotor_torque`` carries; zeros to leave them out). Else a base parameter vector
    (``kin.BASE_PARAMETERS`` order, a mapping name -> value, or the path of a parameter file that
    ``calib fit dynamics`` wrote: the identified model, issue 27 item 5): the
    torque is ``kin.base_regressor(q, qd, qdd) @ theta``, rotor inertias included as its IA
    terms (``rotor`` must then be None). From a parameter file, the columns calib fits beside the
    base parameters come too: the coupled wrist motors' rotor inertias (``JM<m>``, their
    off-diagonal G_m^T G_m qdd) and, when every joint has them, the friction of eq. 4.27
    (``FC<j>+-``, ``FV<j>+-``), which then replaces the data file's (``friction``).
    """

    def __init__(self, kin, theta=None, rotor=None) -> None:
        kin = getattr(kin, "module", kin)        # rccl.segments.Kinematics wraps the generated module
        for name in ("inverse_dynamics", "inertia_matrix", "base_regressor", "BASE_PARAMETERS"):
            if not hasattr(kin, name):
                raise FeedForwardError(f"feedforward: the kinematics module {getattr(kin, 'ROBOT', kin)!r} "
                                       f"has no {name} (regenerate it: make derive)")
        self.kin = kin
        self.theta = None if theta is None else base_vector(kin, theta)
        n = len(kin.JOINT_KINDS)
        if rotor is not None and self.theta is not None:
            raise BadRequest("feedforward: rotor inertias are part of a base-parameter vector (its IA terms); "
                             "give theta or rotor, not both")
        if rotor is None and self.theta is None:
            rotor = data_file_rotor(kin.ROBOT)
        self.rotor = None if self.theta is not None else _rotor_matrix(rotor, n)
        self._unit = np.eye(n)
        self.coupling = np.zeros((n, n))            # the fitted JM columns' G_m^T G_m off the diagonal
        self.fitted_friction: tuple[np.ndarray, ...] | None = None
        if isinstance(theta, (str, os.PathLike)):
            self.coupling, self.fitted_friction = fitted_drive_terms(theta, kin)

    @property
    def source(self) -> str:
        return "data file inertials" if self.theta is None else f"base parameters ({len(self.theta)})"

    def torques(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
        """D(q) qdd + c(q, qd) + t_g(q) (N*m / N) at joints q (rad, m), rates qd, accelerations qdd."""
        if self.theta is None:
            return np.asarray(self.kin.inverse_dynamics(q, qd, qdd), dtype=float) + self.rotor @ qdd
        return np.asarray(self.kin.base_regressor(q, qd, qdd), dtype=float) @ self.theta + self.coupling @ qdd

    def friction(self, qd: np.ndarray) -> np.ndarray | None:
        """The fitted friction of eq. 4.27 at rates qd (N*m / N), or None: the model has none (the
        control law then uses the data file's)."""
        if self.fitted_friction is None:
            return None
        return friction_torque(qd, *self.fitted_friction)

    def gravity(self, q: np.ndarray) -> np.ndarray:
        """t_g(q): the same model at rest."""
        z = np.zeros_like(q)
        return self.torques(q, z, z)

    def inertia_diagonal(self, q: np.ndarray) -> np.ndarray:
        """D_jj(q) (kg*m^2 / kg) of this model, rotors included (the PD's scale)."""
        if self.theta is None:
            return np.diag(np.asarray(self.kin.inertia_matrix(q), dtype=float)) + np.diag(self.rotor)
        z = np.zeros_like(q)
        y0 = np.asarray(self.kin.base_regressor(q, z, z), dtype=float) @ self.theta
        return np.array([float((np.asarray(self.kin.base_regressor(q, z, e), dtype=float) @ self.theta)[j] - y0[j])
                         for j, e in enumerate(self._unit)])


def data_file_rotor(robot: str) -> np.ndarray:
    """G^T diag(J_m) G (n, n, kg*m^2 at the joints; kg on prismatic rows) of the data file's
    ``rotor_inertia`` (``RobotModel.rotor_matrix``; simula's and calib's one source)."""
    from rcci.models import load_robot

    return load_robot(robot).rotor_matrix()


def _rotor_matrix(rotor, n: int) -> np.ndarray:
    """``rotor`` as an (n, n) matrix (a vector is its diagonal); a BadRequest if not finite or not that shape."""
    try:
        r = np.asarray(rotor, dtype=float)
    except (TypeError, ValueError):
        raise BadRequest(f"feedforward: rotor inertias {rotor!r} are not numbers") from None
    if r.shape == (n,):
        r = np.diag(r)
    if r.shape != (n, n) or not np.all(np.isfinite(r)):
        raise BadRequest(f"feedforward: rotor inertias must be ({n},) or ({n}, {n}) finite kg*m^2, got shape "
                         f"{r.shape}")
    return r


def fitted_base_parameters(path: str | os.PathLike, kin) -> dict[str, float]:
    """The base parameters of ``kin``'s arm that ``calib fit dynamics`` wrote into the parameter file
    ``path`` (its ``[dynamics]`` table: ``names``, ``values``; the friction and rotor-coupling columns
    it fits beside them: ``fitted_drive_terms``), by name. A BadRequest names the file and what it lacks."""
    fitted = fitted_columns(path, kin)
    missing = [n for n in kin.BASE_PARAMETERS if n not in fitted]
    if missing:
        raise BadRequest(f"feedforward: parameter file {os.fspath(path)!r}: [dynamics] lacks the base parameters "
                         f"{missing} of the {kin.ROBOT} (and does not name them in not_identified)")
    return {n: fitted[n] for n in kin.BASE_PARAMETERS}


def fitted_columns(path: str | os.PathLike, kin) -> dict[str, float]:
    """Every column of calib's ``[dynamics]`` in the parameter file ``path``, by name; a BadRequest
    names the file and what it lacks."""
    from rcci.models.params import read_params
    from rcci.models.exceptions import ModelError

    try:
        data = read_params(path)
    except (OSError, ModelError) as exc:
        raise BadRequest(f"feedforward: parameter file {os.fspath(path)!r}: {exc}") from None
    robot = data.get("calib", {}).get("robot")
    if robot is not None and robot != kin.ROBOT:
        raise BadRequest(f"feedforward: parameter file {os.fspath(path)!r} is of the {robot}, not the {kin.ROBOT}")
    dyn = data.get("dynamics")
    if not isinstance(dyn, Mapping) or "names" not in dyn or "values" not in dyn:
        raise BadRequest(f"feedforward: parameter file {os.fspath(path)!r} has no [dynamics] names and values "
                         "(run calib fit dynamics LOGS -p FILE first: docs/calib.md)")
    fitted = dict(zip(dyn["names"], dyn["values"]))
    unfitted = [k for k in dyn.get("not_identified", []) if k not in fitted]
    if unfitted:        # equations the fit left out (rcci.calib.unmeasured): the data file's values
        fitted.update(data_file_columns(kin.ROBOT, unfitted))
    if not dyn.get("grouped"):
        return fitted
    try:
        grouped = {name: dict(zip(of, coef, strict=True))
                   for name, of, coef in zip(dyn["grouped"], dyn["grouped_of"], dyn["grouped_coefficients"], strict=True)}
    except (KeyError, TypeError, ValueError):
        raise BadRequest(f"feedforward: parameter file {os.fspath(path)!r}: [dynamics] grouped, grouped_of and "
                         "grouped_coefficients must be lists of one length (what calib fit dynamics writes)") from None
    return ungrouped(fitted, grouped, kin, os.fspath(path))


def ungrouped(fitted: Mapping, grouped: Mapping, kin, where: str) -> dict[str, float]:
    """``fitted`` with the values calib grouped split again (rcci.calib.grouping: e.g. the
    Microbo's ``FC2+R = FC2+ + 9.81 M2 + 9.81 M3R``): a parameter fitted in a column of its own
    (M3R) keeps its fitted value; one left with none (M2) takes the data file's, since no motion
    determines it apart from the others; each grouped column gives its own parameter the rest.
    The torques in motion are the grouped fit's either way; at rest the weight of M2 is the data
    file's."""
    prior = dict(zip(kin.BASE_PARAMETERS, data_file_base_parameters(kin.ROBOT)))
    out = {k: float(v) for k, v in fitted.items() if k not in grouped}
    for name, part in grouped.items():
        own = name[:-1] if name.endswith("R") and name[:-1] in part else name
        folded = [k for k in part if k != own]
        if name not in fitted or own not in part or any(k not in prior for k in folded):
            raise BadRequest(f"feedforward: parameter file {where!r}: [dynamics] grouped {name} = {dict(part)} "
                             f"does not match its names (expected {name} among them, made of {own} and base "
                             f"parameters of the {kin.ROBOT})")
        value = {k: float(fitted[k]) if k in fitted else prior[k] for k in folded}   # fitted in its own column, or not
        out.update(value)
        out[own] = (float(fitted[name]) - sum(float(part[k]) * value[k] for k in folded)) / float(part[own])
    return out


def data_file_columns(robot: str, names: list[str]) -> dict[str, float]:
    """The data file's values of calib's columns ``names``: base parameters (``BASE_PARAMETERS``)
    and friction (``FC<j>+-``, ``FV<j>+-``); a BadRequest for another name."""
    from rcci.models import load_robot
    import rccl.kinematics as kinematics

    values = dict(zip(kinematics.load(robot).BASE_PARAMETERS, data_file_base_parameters(robot)))
    fr = load_robot(robot).friction
    for key, field in (("FC", "coulomb"), ("FV", "viscous")):
        for sign, part in (("+", "pos"), ("-", "neg")):
            for j, v in enumerate(getattr(fr, f"{field}_{part}").values):
                values[f"{key}{j + 1}{sign}"] = float(v)
    bad = [n for n in names if n not in values]
    if bad:
        raise BadRequest(f"feedforward: the data file of the {robot} has no value for the columns {bad}")
    return {n: values[n] for n in names}


def data_file_base_parameters(robot: str) -> np.ndarray:
    """The base parameters (``BASE_PARAMETERS`` order) of the data file's inertials and rotors."""
    from rcci.models import load_robot
    import rccl.kinematics as kinematics

    rm = load_robot(robot)
    masses = np.array([li.mass for li in rm.links])
    coms = np.array([li.com for li in rm.links])
    inertia = np.array([[i[0, 0], i[1, 1], i[2, 2], i[0, 1], i[0, 2], i[1, 2]]
                        for i in (np.asarray(li.inertia, dtype=float) for li in rm.links)])
    rotor = np.diag(data_file_rotor(robot))
    return np.asarray(kinematics.load(robot).base_parameters(masses, coms, inertia, rotor), dtype=float)


def fitted_drive_terms(path: str | os.PathLike, kin) -> tuple[np.ndarray, tuple[np.ndarray, ...] | None]:
    """From calib's ``[dynamics]`` of ``path``: the rotor coupling matrix (n, n; sum over the fitted
    ``JM<m>`` of J_m (G_m^T G_m - its diagonal), zeros if none) and the fitted friction (Coulomb +,
    Coulomb -, viscous +, viscous -: (n,) each, magnitudes) or None when a joint lacks it."""
    from rcci.models import load_robot

    fitted = fitted_columns(path, kin)
    G = np.asarray(load_robot(kin.ROBOT).conversion.gear_ratio.values, dtype=float)
    n = G.shape[0]
    coupling = np.zeros((n, n))
    for m in range(n):
        if f"JM{m + 1}" in fitted:
            full = np.outer(G[m], G[m])
            coupling += float(fitted[f"JM{m + 1}"]) * (full - np.diag(np.diag(full)))
    keys = [[f"{k}{j + 1}{s}" for j in range(n)] for k, s in (("FC", "+"), ("FC", "-"), ("FV", "+"), ("FV", "-"))]
    if not all(name in fitted for row in keys for name in row):
        return coupling, None
    return coupling, tuple(np.array([float(fitted[x]) for x in row]) for row in keys)


def base_vector(kin, theta) -> np.ndarray:
    """``theta`` as a float array in ``kin.BASE_PARAMETERS`` order (a sequence, a mapping name -> value,
    or the path of a parameter file with calib's ``[dynamics]``); a BadRequest names what is wrong."""
    names = tuple(kin.BASE_PARAMETERS)
    if isinstance(theta, (str, os.PathLike)):
        theta = fitted_base_parameters(theta, kin)
    if isinstance(theta, Mapping):
        missing = [n for n in names if n not in theta]
        extra = [k for k in theta if k not in names]
        if missing or extra:
            raise BadRequest(f"feedforward: base parameters of {kin.ROBOT}: missing {missing}, unknown {extra} "
                             f"(expected the names of kin.BASE_PARAMETERS)")
        theta = [theta[n] for n in names]
    try:
        arr = np.asarray(theta, dtype=float)
    except (TypeError, ValueError):
        raise BadRequest(f"feedforward: base parameters {theta!r} are not numbers") from None
    if arr.shape != (len(names),):
        raise BadRequest(f"feedforward: base parameters of {kin.ROBOT} have shape {arr.shape}, "
                         f"expected ({len(names)},) in the order of BASE_PARAMETERS")
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        raise BadRequest(f"feedforward: base parameter {names[bad[0]]} is {arr[bad[0]]}, not finite")
    return arr


@dataclass(frozen=True)
class FeedForward:
    """One motion's servo mode (``MODES``), the model and the PD gains; ``position`` needs neither."""

    mode: str = "position"
    model: DynamicsModel | None = None
    gains: Gains = Gains()

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise BadRequest(f"feedforward: mode {self.mode!r} is not one of {MODES}")
        if self.mode != "position" and not isinstance(self.model, DynamicsModel):
            raise BadRequest(f"feedforward: mode {self.mode!r} needs a DynamicsModel, got {self.model!r}")
        if not isinstance(self.gains, Gains):
            raise BadRequest(f"feedforward: gains {self.gains!r} is not an rccl.feedforward.Gains")

    @property
    def current(self) -> bool:
        """True when the joints run in current mode."""
        return self.mode != "position"


class FeedForwardControl:
    """The per-sample law for one arm: planned-motion history, torque, DAC values (control level, no I/O)."""

    def __init__(self, joint_model: JointModel) -> None:
        self.joint_model = joint_model
        self._dac_limit = np.minimum(joint_model.max_dac, DAC_MAX)
        self._plan: list[tuple[float, np.ndarray]] = []   # (trajectory time s, planned q) of the last 3 samples
        self.saturated = 0                                 # samples whose DAC value was clipped
        self.last_torque: np.ndarray | None = None         # N*m of the last current-mode sample
        self.last_terms: dict[str, np.ndarray] = {}        # its parts: model, friction, pd
        self.rate_hz = 36.0                                # of the plan's last period (the PD's default)

    def reset(self) -> None:
        """Forget the planned history (after a fault: the plan starts again from the held arm)."""
        self._plan.clear()

    def observe(self, t: float, q: np.ndarray) -> None:
        """Record a position-mode sample of the plan, so a switch to current mode mid-motion starts with
        the plan's rate and acceleration, not from rest."""
        self.planned(t, q)

    def planned(self, t: float, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
        """Record the plan's sample (t s, q rad) and return (q_p, qd_p, qdd_p, q_prev) over the last period."""
        plan = self._plan
        if plan and t <= plan[-1][0]:            # a repeated time (a held sample): replace it
            plan.pop()
        plan.append((float(t), np.array(q, dtype=float)))
        if len(plan) > 3:
            plan.pop(0)
        q = plan[-1][1]
        if len(plan) < 2:
            z = np.zeros_like(q)
            return q, z, z, None
        (t1, q1), (t2, q2) = plan[-2], plan[-1]
        h2 = t2 - t1
        self.rate_hz = 1.0 / h2
        qd = (q2 - q1) / h2
        qdd = np.zeros_like(q)
        if len(plan) == 3:
            t0, q0 = plan[0]
            h1 = t1 - t0
            qdd = 2.0 * ((q2 - q1) / h2 - (q1 - q0) / h1) / (h1 + h2)
        return 0.5 * (q1 + q2), qd, qdd, q1

    def command(self, ff: FeedForward, t: float, q_plan: np.ndarray, q_meas: np.ndarray,
                qd_meas: np.ndarray) -> Command:
        """This sample's CUR command for every joint (``Command.current``), q_plan kept for the record.

        ``t`` the trajectory time of ``q_plan`` (s); ``q_meas``/``qd_meas`` what the HOW of this
        cycle reports (rad, rad/s), compared with the plan of the previous sample (the position
        the arm was to reach when that HOW was sent).
        """
        q_p, qd_p, qdd_p, q_prev = self.planned(t, q_plan)
        model = ff.model
        if ff.mode == "computed":
            rigid = model.torques(q_p, qd_p, qdd_p)
        else:
            rigid = model.gravity(q_p)
        fric = model.friction(qd_p)
        if fric is None:
            fric = self.joint_model.friction(qd_p)
        w = 2.0 * math.pi * ff.gains.hz(self.rate_hz)
        target = q_plan if q_prev is None else q_prev
        qd_target = np.zeros_like(q_plan) if q_prev is None else self._previous_rate()
        scale = model.inertia_diagonal(q_p)
        pd = scale * (w * w * (target - q_meas) + 2.0 * ff.gains.damping * w * (qd_target - qd_meas))
        torque = rigid + fric + pd
        if not np.all(np.isfinite(torque)):
            bad = int(np.flatnonzero(~np.isfinite(torque))[0])
            part = "model" if not np.isfinite(rigid[bad]) else ("pd" if not np.isfinite(pd[bad]) else "friction")
            raise FeedForwardError(f"feedforward ({ff.mode}, {model.source}): joint {bad + 1}'s torque is "
                                   f"{torque[bad]} (its {part} term) at planned q = {np.round(q_p, 4).tolist()}")
        dac = self.joint_model.dac_per_joint_torque @ torque
        lim = self._dac_limit
        clipped = np.clip(dac, -lim, lim)
        if np.any(clipped != dac):
            self.saturated += 1
        self.last_torque = torque
        self.last_terms = {"model": rigid, "friction": fric, "pd": pd}
        return Command(np.array(q_plan, dtype=float),
                       {j: int(round(float(v))) for j, v in enumerate(clipped.tolist())})

    def _previous_rate(self) -> np.ndarray:
        """The plan's rate over the period before the last (rad/s): the rate at the measured sample."""
        plan = self._plan
        if len(plan) < 3:
            return np.zeros_like(plan[-1][1])
        (t0, q0), (t1, q1) = plan[0], plan[1]
        return (q1 - q0) / (t1 - t0)


def make(kin, mode: str, theta=None, gains: Gains | None = None, rotor=None) -> FeedForward:
    """A validated ``FeedForward`` for the generated module ``kin`` (``theta``: see ``DynamicsModel``)."""
    if not isinstance(mode, str) or mode not in MODES:
        raise BadRequest(f"feedforward: mode {mode!r} is not one of {MODES}")
    if gains is not None and not isinstance(gains, Gains):
        raise BadRequest(f"feedforward: gains {gains!r} is not an rccl.feedforward.Gains")
    if mode == "position":
        if theta is not None or rotor is not None:
            raise BadRequest("feedforward('position'): a model given, but position mode uses none")
        return FeedForward("position", None, gains or Gains())
    return FeedForward(mode, DynamicsModel(kin, theta, rotor), gains or Gains())
