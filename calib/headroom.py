"""Current headroom of a measurement plan: will the arm carry it on a truth calib does not know yet?

A plan is recorded on an arm whose torque sensitivities, friction and gravity are what
calib is about to measure, so a plan sized on the data file's values alone can exceed a
motor's current limit (R_MAXCUR) on a valid arm: a sensitivity 9 % low needs 10 % more
current. :func:`peak_currents` predicts each motor's current (A) along a plan's setpoints
with the data file's model and MARGINS for what is being measured (the current limit is
``max_current`` of the data file, checked by rci.checks on the filtered ADC reading); a plan
is carried when every motor stays under HEADROOM of its limit. The torque is gravity
(4.24) plus the pulley's constant load plus Coulomb and viscous friction of the moving
joints, mapped to the motors through G (t_s = G^-T tau_j) and divided by sigma (4.36);
accelerations are ignored (the plans' 1.5 rad/s^2 turns ask little of the motors).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rcci.calib.robot import RobotInfo

#: relative uncertainty allowed for, per quantity the campaign measures: a truth may be this
#: far from the data file (the sensitivity down, friction and gravity up) and still be carried
MARGINS = {"sigma": 0.15, "friction": 0.30, "gravity": 0.10}
HEADROOM = 0.95         # of max_current: the filtered reading's ripple and noise on top of the mean


@dataclass(frozen=True)
class Headroom:
    """The worst motor of a plan: its predicted current (A, margins included), its limit (A),
    and the setpoint index where it peaks."""

    motor: int           # 0-based
    current: float
    limit: float
    index: int

    @property
    def ok(self) -> bool:
        return self.current <= HEADROOM * self.limit

    def describe(self) -> str:
        return (f"motor {self.motor + 1} would need up to {self.current:.2f} A of its {self.limit:.2f} A limit "
                f"(sensitivity {100 * MARGINS['sigma']:.0f} % low, friction {100 * MARGINS['friction']:.0f} % "
                f"and gravity {100 * MARGINS['gravity']:.0f} % high; calib keeps {100 * (1 - HEADROOM):.0f} % "
                "to spare)")


def max_current(robot: str) -> np.ndarray:
    """Each motor's current limit (A) from the data file."""
    from rcci.models import load_robot

    return np.asarray(load_robot(robot).max_current, dtype=float)


def start_pose(robot: str) -> np.ndarray:
    """Where a freshly started arm stands (simula -p: the ``ready`` pose), rad / m."""
    from rcci.models import load_robot

    return np.asarray(load_robot(robot).poses["ready"], dtype=float)


def peak_currents(info: RobotInfo, q: np.ndarray, rate_hz: float, load: np.ndarray | None = None,
                  margins: dict[str, float] | None = None) -> np.ndarray:
    """Predicted motor currents (A), (N, n), along setpoints ``q`` (N, n) sampled at ``rate_hz``,
    with the joint torque ``load`` (n,) N m added (the pulley: -sign m g r on its joint),
    each term enlarged by ``margins`` (default MARGINS) in the direction that needs more current."""
    m = dict(MARGINS if margins is None else margins)
    nom = info.nominal
    fr = nom["friction"]
    coeffs = np.array([float(nom["gravity_coeffs"][n]["value"]) for n in info.gravity_names])
    q = np.asarray(q, dtype=float)
    v = np.gradient(q, 1.0 / rate_hz, axis=0) if len(q) > 1 else np.zeros_like(q)
    tau_g = np.array([info.regressor(x) @ coeffs for x in q])
    fc_pos, fc_neg = (np.asarray(fr[k]["values"], float) for k in ("coulomb_pos", "coulomb_neg"))
    fv_pos, fv_neg = (np.asarray(fr[k]["values"], float) for k in ("viscous_pos", "viscous_neg"))
    moving = np.abs(v) > 1e-6
    f = np.where(v > 0, fc_pos + fv_pos * v, -(fc_neg + fv_neg * -v)) * moving
    ext = np.zeros(q.shape[1]) if load is None else np.asarray(load, dtype=float)
    tau = tau_g - ext + f                                  # what the motors must give, nominal
    spread = m["gravity"] * np.abs(tau_g) + m["friction"] * np.abs(f)   # what the truth may add
    Ginv_T = np.linalg.inv(np.asarray(info.drive.G, dtype=float).T)
    motor_torque = np.abs(tau @ Ginv_T.T) + spread @ np.abs(Ginv_T).T
    sigma = np.asarray(info.drive.sigma, dtype=float) * (1 - m["sigma"])
    return motor_torque / sigma


def worst(info: RobotInfo, q: np.ndarray, rate_hz: float, load: np.ndarray | None = None) -> Headroom:
    """The motor closest to (or furthest over) HEADROOM of its limit along ``q``."""
    cur = peak_currents(info, q, rate_hz, load)
    lim = max_current(info.name)
    ratio = cur / lim
    k, m = np.unravel_index(int(np.argmax(ratio)), ratio.shape)
    return Headroom(int(m), float(cur[k, m]), float(lim[m]), int(k))


def approach_routes(here: np.ndarray, first: np.ndarray) -> list[tuple[np.ndarray, ...]]:
    """Candidate ``via`` poses from ``here`` to ``first``: straight; the wrist (joints 4..n)
    first, then the arm; the arm (joints 1-3) first, then the wrist."""
    here, first = np.asarray(here, float), np.asarray(first, float)
    wrist_first, arm_first = here.copy(), here.copy()
    wrist_first[3:] = first[3:]
    arm_first[:3] = first[:3]
    return [(), (wrist_first,), (arm_first,)]


def plan_setpoints(plan, here: np.ndarray, accel: float, rate_hz: float | None = None) -> np.ndarray:
    """Every setpoint (N, n) rcci.calib.program.run_plan commands for ``plan`` from the pose ``here``:
    the approach, the warm-up, the settle and the recorded path (``accel``: the moves'
    acceleration, rad/s^2, rcci.calib.experiments.ACCEL)."""
    from rcci.calib.paths import Path, PathSegment, approach_path

    rate = rate_hz or plan.rate_hz
    body = plan.path.sample(rate)
    parts = [] if plan.warmup is None else [plan.warmup.sample(rate)]
    first = parts[0][0] if parts else body[0]
    last = parts[0][-1] if parts else first
    approach = approach_path(here, plan.via, first, accel).sample(rate)
    settle = Path((PathSegment(last, body[0], 0.6, accel, 0.5),)).sample(rate)
    return np.vstack([approach, *parts, settle, body])
