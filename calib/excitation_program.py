"""The excitation measurement program: a designed Fourier trajectory played in current mode.

Each plan (:func:`excitation_plans`: one trajectory to fit, a different one held out) takes the
arm with position commands (POS, not recorded) to the trajectory's start, then switches every
joint to current mode (CUR) and, each cycle, commands the motor torques of a computed-torque
controller around the planned motion: the data file's inverse dynamics (rccl.kinematics,
thesis 4.6) and Coulomb and viscous friction at the planned state, plus a PD on the measured
encoder angles (gains from the data file's inertia at the start and an estimate of the rotor
inertias, ``WN_HZ`` and ``ZETA``), through G^-T and K_dac. The controller only keeps the arm near
the plan; the fit reads what was measured (encoder counts and the motor currents of the ADC),
never the commands. The recorder runs from the first CUR cycle to the end of the last period;
then the joints go back to POS where they are (the trajectory's end, its start, at rest).

On simula this needs ``--dynamic`` (the full mass matrix and Coriolis terms in current mode);
``calib record dynamics --simula`` starts it so, with ``--warm`` standing for a warmed-up arm
(a real one is run for minutes before an identification; a cold joint's friction is up to
20 % higher, 4.5.3, and would drift during the log).
"""
from __future__ import annotations

import threading
from dataclasses import dataclass, field

import numpy as np

from rcci.calib.exceptions import CalibError
from rcci.calib.excitation import Excitation, design
from rcci.models import load_robot
from rcci.calib.experiments import ACCEL
from rcci.calib.paths import Path, PathSegment, approach_path
from rcci.calib.program import approach_speed, command_joints, drive_recorded, open_measurement
from rci import codes
from rci.chg import CUR
from rci.conversions import DAC_MAX, DAC_MIN, Conversions

EXCITATION_RATE_HZ = 200
PERIODS = 2                  # recorded periods of the trajectory to fit
HELDOUT_PERIODS = 1
WN_HZ = 4.0                  # Hz, the PD's natural frequency
ZETA = 0.9
VELOCITY_TAU = 0.01          # s, first-order filter of the encoder differences (the PD's speed)
MAX_TRACKING = 0.35          # rad: a larger error stops the program (the arm is not following)
FIT_SEED, HELDOUT_SEED = 0, 1


@dataclass
class ExcitationPlan:
    """One excitation log: the trajectory, how many periods are recorded, the log's metadata."""

    name: str
    excitation: Excitation
    periods: int
    meta: dict = field(default_factory=dict)
    rate_hz: int = EXCITATION_RATE_HZ


def excitation_plans(robot: str, seeds: tuple[int, int] = (FIT_SEED, HELDOUT_SEED),
                     designs: tuple[Excitation, Excitation] | None = None,
                     periods: tuple[int, int] = (PERIODS, HELDOUT_PERIODS)) -> list[ExcitationPlan]:
    """The trajectory to fit (``seeds[0]``, ``periods[0]`` periods) and the held-out one
    (``seeds[1]``), each designed by rcci.calib.excitation (CasADi + IPOPT) unless ``designs`` gives them."""
    excs = designs or tuple(design(robot, seed=s) for s in seeds)
    plans = []
    for role, exc, n in zip(("fit", "heldout"), excs, periods):
        meta = {"experiment": "dynamics", "role": role, "excitation": exc.as_meta(), "periods": n,
                "design_seconds": exc.seconds, "log_set": [f"dynamics-{r}" for r in ("fit", "heldout") if r != role]}
        plans.append(ExcitationPlan(f"dynamics-{role}", exc, n, meta))
    return plans


def _gains(robot: str, exc: Excitation, conv: Conversions) -> tuple[np.ndarray, np.ndarray]:
    """PD gains (N m/rad, N m s/rad) per joint from the data file's inertia at the start."""
    import rccl.kinematics as kin

    mod = kin.load(robot)
    q0 = exc.state(np.zeros(1))[0][0]
    # the data file's rotor inertias (its joints' rotor_inertia, G^T diag(J_m) G)
    d = np.diag(mod.inertia_matrix(q0)) + np.diag(load_robot(robot).rotor_matrix())
    wn = 2 * np.pi * WN_HZ
    return d * wn ** 2, 2 * ZETA * wn * d


def _feedforward(robot: str, info, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
    """Joint torques (N, n) of the data file's model: inverse dynamics plus friction (4.27)."""
    import rccl.kinematics as kin

    mod = kin.load(robot)
    fr = info.nominal["friction"]
    v = lambda k: np.asarray(fr[k]["values"], float)   # noqa: E731
    tau = np.array([mod.inverse_dynamics(q[k], qd[k], qdd[k]) for k in range(len(q))])
    return tau + np.where(qd > 0, v("coulomb_pos") + v("viscous_pos") * qd,
                          np.where(qd < 0, -v("coulomb_neg") + v("viscous_neg") * qd, 0.0))


def run_excitation(url: str, plan: ExcitationPlan, log_path: str, robot: str = "puma260",
                   extra_meta: dict | None = None, timeout: float | None = 5.0) -> int:
    """Run ``plan`` on the robot (or simula) at ``url`` into ``log_path``; the records logged."""
    from rcci.calib.robot import robot_info

    info = robot_info(robot)
    conv = Conversions.for_robot(robot)
    rate = plan.rate_hz
    exc = plan.excitation
    steps = int(round(plan.periods * exc.period * rate)) + 1
    t = np.arange(steps) / rate
    q_d, v_d, a_d = exc.state(t)
    ff = _feedforward(robot, info, q_d, v_d, a_d)
    kp, kd = _gains(robot, exc, conv)
    # 1 % inside the current limit, whole DAC counts (the link's check refuses a count above it)
    dac_lim = np.floor(0.99 * np.abs(np.asarray(info.drive.sigma, float) * _max_current(robot) * conv.k_dac))
    meta = dict(plan.meta)
    meta.update(extra_meta or {})
    meta.update({"program": f"calib record {plan.name}", "log_name": plan.name, "rate_hz": rate,
                 "controller": {"wn_hz": WN_HZ, "zeta": ZETA, "kp": kp.tolist(), "kd": kd.tolist()}})
    state: dict = {"lead": None, "k": -1, "cur": -1, "q_prev": None, "v": np.zeros(len(kp)), "worst": 0.0}
    done = threading.Event()
    rec, session = open_measurement(url, robot, rate, log_path, meta, timeout)
    alpha = 1.0 - np.exp(-1.0 / (rate * VELOCITY_TAU))

    def f1() -> None:
        how = session.how
        q = conv.counts_to_angles(np.asarray(how.pos[:len(kp)], dtype=float))
        if state["lead"] is None:
            if not how.state & codes.POWER_ON:
                session.chg.power_on.issue()
            approach = approach_path(q, (), q_d[0], ACCEL, approach_speed(robot)).sample(rate)
            settle = Path((PathSegment(q_d[0], q_d[0], 0.5, ACCEL, 0.5),)).sample(rate)
            state["lead"] = np.vstack([approach, settle])
        state["k"] += 1
        lead = state["lead"]
        if state["k"] < len(lead):
            command_joints(session, conv, lead[state["k"]])
            return
        k = state["cur"] = state["cur"] + 1
        if k >= steps:
            if k == steps:                       # hand over to POS where the arm is (not where it
                session.record(None)             # was planned to be: a step there may be too fast)
                state["hold"] = q
            command_joints(session, conv, state["hold"])
            if k >= steps + int(0.5 * rate):
                done.set()
            return
        if k == 0:
            session.record(rec)
            state["q_prev"] = q
        diff = (q - state["q_prev"]) * rate
        state["v"] = state["v"] + alpha * (diff - state["v"])
        state["q_prev"] = q
        err = q_d[k] - q
        state["worst"] = max(state["worst"], float(np.abs(err).max()))
        if state["worst"] > MAX_TRACKING:
            if state.get("abort") is None:
                state["abort"] = (f"{plan.name}: joint {int(np.argmax(np.abs(err))) + 1} is {np.abs(err).max():.2f} "
                                  f"rad off the excitation at {k / rate:.2f} s: the arm does not follow it "
                                  f"(partial log: {rec.path})")
                session.record(None)
            command_joints(session, conv, q)
            done.set()
            return
        tau = ff[k] + kp * err + kd * (v_d[k] - state["v"])
        dac = np.clip(np.rint(conv.joint_to_motor_torques(tau) * conv.k_dac), -dac_lim, dac_lim)
        dac = np.clip(dac, DAC_MIN, DAC_MAX).astype(int)
        for j in range(len(kp)):
            session.chg.motion[j].issue(CUR, int(dac[j]))

    drive_recorded(session, f1, done, rec, plan.name, url,
                   lambda: f"at cycle {max(state['cur'], 0)} of {steps} of the excitation")
    if state.get("abort"):
        raise CalibError(state["abort"])
    return rec.written


def _max_current(robot: str) -> np.ndarray:
    from rcci.models import load_robot

    return np.asarray(load_robot(robot).max_current, float)
