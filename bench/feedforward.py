"""Tracking error of a fast Cartesian tour in three servo modes: position, gravity-only and computed torque.

    .venv/bin/python -m bench.feedforward                          # puma260, 250 Hz
    .venv/bin/python -m bench.feedforward --robot puma260 --robot microbo --robot puma560 --robot stanford --robot panda \\
        --report reports/feedforward.md --plot reports/feedforward.png
    .venv/bin/python -m bench.feedforward --robot puma260 --hidden-truth 5 \\
        --report reports/feedforward-identified.md --plot reports/feedforward-identified.png

With ``--hidden-truth SEED`` simula runs a hidden truth (``calib hidden-truth --seed SEED
--inertials``: link masses, inertias, rotors, friction and gravity away from the data file), calib
identifies it (``calib record dynamics`` + ``calib fit dynamics`` on that simula), and the tour runs
with computed torque from the data file's model and from the identified one (its base parameters,
rotor coupling and friction), beside gravity-only and position mode. The truth keeps the data file's
torque sensitivities and DH table: the session converts torque to current with the data file's
sensitivities and plans with the nominal kinematics (a calibrated sensitivity or DH table in the
session is not what this measures).

Each (arm, mode) runs on its own fresh lockstep ``simula --dynamic -p --power-on`` (full mass
matrix and Coriolis terms for the current-mode joints; deterministic, so a rerun gives the
same figures). The arm moves to its start pose in position mode, then ``arm.feedforward(mode)``
and a tour of ``TOUR`` Cartesian straight lines through poses near the start, at ``SPEED`` of the
arm's Cartesian limits. The tracking error of sample k is the plan ``q_k`` against the joints the
next HOW reports (the position the arm was to reach when it was sent): per joint (rad, m) and at
the wrist centre of T6 (m), RMS and max over the tour.
"""
from __future__ import annotations

import argparse
import datetime as _dt
import os
import sys
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import rccl
from rccl import EQ, T6, TL, Trsf, makeposition

MODES = ("position", "gravity", "computed")
# start pose per arm (rad, m): the composition matrix's, away from singularities and joint stops
from tests.composition import START  # noqa: E402 - one table of start poses for the project's runs

# the tour: joint offsets (rad; m for a prismatic joint) of its corners from the start pose; each leg a
# Cartesian straight line between the corners' T6
TOUR = {
    "revolute": [(0.35, -0.25, 0.3), (-0.3, 0.2, -0.25), (0.3, 0.25, 0.2), (0.0, 0.0, 0.0)],
    "prismatic": 0.06,
}
SPEED = 0.9        # of the arm's translational / rotational velocity limits (setvel)
WAIT = 120.0       # s of wall time for one motion on a loaded machine


@dataclass
class Run:
    """One (arm, mode) tour: time (s), plan and measured joints aligned sample by sample."""

    robot: str
    mode: str
    t: np.ndarray
    plan: np.ndarray
    meas: np.ndarray
    cart_err: np.ndarray
    saturated: int
    samples: int
    fault: str
    speed: float = 0.0          # peak planned T6 speed (m/s)

    @property
    def joint_err(self) -> np.ndarray:
        return self.meas - self.plan


def corners(kin, q0: np.ndarray) -> list[np.ndarray]:
    """T6 of each tour corner (4x4, m), from the joint offsets of ``TOUR`` at start pose ``q0``."""
    out = []
    for d in TOUR["revolute"]:
        q = np.array(q0, dtype=float)
        for j in range(3):
            prismatic = getattr(kin, "module", kin).JOINT_KINDS[j] == "prismatic"
            q[j] += (TOUR["prismatic"] * np.sign(d[j]) if prismatic and d[j] else d[j])
        out.append(kin.fk(q))
    return out


def tour(url: str, robot: str, mode: str, rate: int, theta=None, gains=None, rotor=None) -> Run:
    """Run the tour in ``mode`` on the simula at ``url``; the recorded run."""
    with rccl.open(url, robot, rate_hz=rate, record=True, on_error="raise", timeout=10.0) as arm:
        kin = arm.kinematics
        q0 = START[robot]
        arm.setmod("joint")
        arm.setvel(0.1, 1.0)
        p = makeposition("start", T6, EQ, Trsf("START", kin.fk(q0)), TL, T6)
        arm.move(p)
        p.end.wait(fault=arm.check, timeout=WAIT)
        t_end = arm.gen.t + 0.3
        arm.rci.wait(WAIT, until=lambda: arm.gen.t >= t_end)
        arm.feedforward(mode, theta=theta, gains=gains, rotor=rotor)
        lim = arm.limits
        arm.setmod("cartesian")
        arm.setvel(SPEED * lim.translational_velocity, SPEED * lim.rotational_velocity)
        n0 = len(arm.trace)
        sat0 = arm.ff_control.saturated
        last = None
        for i, c in enumerate(corners(kin, q0)):
            last = makeposition(f"c{i}", T6, EQ, Trsf(f"C{i}", c), TL, T6)
            arm.move(last)
        fault = ""
        try:
            last.end.wait(fault=arm.check, timeout=WAIT)
            t_end = arm.gen.t + 0.3
            arm.rci.wait(WAIT, until=lambda: arm.gen.t >= t_end)
        except Exception as exc:        # noqa: BLE001 - a fault is a measured outcome here
            fault = f"{type(exc).__name__}: {exc}"
            with_suppressed(arm.recover)
        n1 = len(arm.trace)
        saturated = arm.ff_control.saturated - sat0
        arm.feedforward("position")
        trace = arm.trace[n0:n1]
    t = np.array([x[0] for x in trace[:-1]])
    plan = np.array([x[1] for x in trace[:-1]])
    meas = np.array([x[2] for x in trace[1:]])       # the HOW after the command: where the arm got to
    fk = kin.fk
    cart = np.linalg.norm(fk(plan)[:, :3, 3] - fk(meas)[:, :3, 3], axis=1)
    p = fk(plan)[:, :3, 3]
    speed = float((np.linalg.norm(np.diff(p, axis=0), axis=1) / np.diff(t)).max())
    return Run(robot, mode, t - t[0], plan, meas, cart, saturated, len(t), fault, speed)


def with_suppressed(fn) -> None:
    try:
        fn()
    except Exception:  # noqa: BLE001
        pass


def run_one(robot: str, mode: str, rate: int, seed: int, theta=None, gains=None, rotor=None,
            truth: str | None = None, label: str | None = None) -> Run:
    """A fresh lockstep ``simula --dynamic`` for one tour (every mode starts from the same state);
    ``truth``: a parameter file simula runs (``--params``); ``label`` names the run's mode."""
    from rci.simula.process import SimulaProcess
    extra = ("--params", truth, "--warm") if truth else ()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        with SimulaProcess("-p", "--power-on", "--dynamic", "--lockstep-watchdog", "20", *extra,
                           robot=robot, lockstep=True, seed=seed) as sim:
            run = tour(sim.url, robot, mode, rate, theta, gains, rotor)
    if rotor is not None:
        run.mode = f"{mode}, no rotor"
    if label:
        run.mode = label
    return run


def identified_truth(robot: str, truth_seed: int, sim_seed: int, folder: str) -> tuple[str, str, float]:
    """Write the hidden truth of ``truth_seed`` (data-file sensitivities and DH table, see the module
    docstring) into ``folder``, identify it on simula (record the dynamics excitations, fit) and write
    the fitted parameter file; (truth path, fitted path, wall seconds)."""
    from rcci.calib.fitting import run_fit
    from rcci.calib.hidden_truth import write_hidden_truth
    from rcci.calib.logs import load_trace
    from rcci.calib.params import atomic_write, dumps
    from rcci.calib.regen import regen
    from rcci.calib.robot import robot_info
    from rcci.models import load_robot
    from rcci.models.params import SCHEMA

    t0 = time.monotonic()
    truth = os.path.join(folder, "truth.toml")
    data = write_hidden_truth(truth, robot, truth_seed, inertials=True)
    data.pop("motors")
    data.pop("kinematics")
    atomic_write(truth, f"# hidden truth seed {truth_seed} of {robot} (--inertials), the data file's "
                        "sensitivities and DH table (bench.feedforward)\n\n" + dumps(data))
    regen(folder, sim_seed, ("dynamics",), truth, quiet=True, robot=robot)
    traces = [load_trace(os.path.join(folder, f"dynamics-{r}.rcilog.xz")) for r in ("fit", "heldout")]
    m = load_robot(robot)
    params = {"motors": {"torque_sensitivity": [float(x) for x in m.motors.torque_sensitivity.values]},
              "kinematics": {"dtheta": [0.0] * m.n_joints}}
    out = run_fit("dynamics", traces, robot_info(robot), params)
    fitted = os.path.join(folder, "fitted.toml")
    atomic_write(fitted, dumps({"calib": {"schema": SCHEMA, "robot": robot}, **out.sections}))
    return truth, fitted, time.monotonic() - t0


def table(runs: list[Run]) -> list[str]:
    """Markdown rows: per run the RMS/max of the wrist-centre error (mm) and of each joint (mrad, mm)."""
    out = ["| arm | mode | cart RMS (mm) | cart max (mm) | joint RMS, 1..n (mrad / mm) | joint max, 1..n | "
           "peak speed (m/s) | samples | DAC clipped | fault |", "|---|---|---:|---:|---|---|---:|---:|---:|---|"]
    for r in runs:
        e = r.joint_err * 1e3
        rms = np.sqrt(np.mean(e ** 2, axis=0))
        mx = np.abs(e).max(axis=0)
        out.append(f"| {r.robot} | {r.mode} | {np.sqrt(np.mean(r.cart_err ** 2)) * 1e3:.2f} | "
                   f"{r.cart_err.max() * 1e3:.2f} | {' '.join(f'{x:.2f}' for x in rms)} | "
                   f"{' '.join(f'{x:.2f}' for x in mx)} | {r.speed:.2f} | {r.samples} | {r.saturated} | "
                   f"{r.fault or '-'} |")
    return out


def plot(runs: list[Run], path: Path) -> None:
    """Wrist-centre tracking error over time, one panel per arm, the three modes in each (log scale)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    robots = list(dict.fromkeys(r.robot for r in runs))
    fig, axes = plt.subplots(len(robots), 1, figsize=(11, 3.2 * len(robots)), squeeze=False)
    colours = {"position": "tab:green", "gravity": "tab:red", "computed": "tab:blue",
               "computed, no rotor": "tab:purple", "gravity (data file)": "tab:red",
               "computed, data file": "tab:blue", "computed, identified": "tab:orange"}
    for ax, robot in zip(axes[:, 0], robots):
        for r in runs:
            if r.robot == robot:
                ax.semilogy(r.t, np.maximum(r.cart_err * 1e3, 1e-3), color=colours.get(r.mode, "k"), lw=1.0,
                            label=f"{r.mode} (RMS {np.sqrt(np.mean(r.cart_err ** 2)) * 1e3:.2f} mm)")
        ax.set_title(f"{robot}: planned vs measured T6 position over a fast Cartesian tour")
        ax.set_ylabel("error (mm)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    axes[-1, 0].set_xlabel("time since the tour started (s)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def report(runs: list[Run], command: str, rate: int, seed: int, wall: float, gains) -> str:
    load = os.getloadavg()
    lines = ["# Feed-forward: tracking error of a fast Cartesian tour (issue 27, item 6)", "",
             f"Command: `{command}`", "",
             f"Date: {_dt.datetime.now(_dt.timezone.utc):%Y-%m-%d %H:%M} UTC; load average {load[0]:.1f} "
             f"{load[1]:.1f} {load[2]:.1f} (2 cores); wall time {wall:.0f} s. Lockstep `simula --dynamic -p "
             f"--power-on --seed {seed}` (a fresh one per run), {rate} Hz, the tour of bench/feedforward.py "
             f"({len(TOUR['revolute'])} Cartesian lines at {SPEED:.0%} of the arm's Cartesian speed limits), "
             f"PD natural frequency {gains.hz(rate):g} Hz, damping {gains.damping:g}; the data file's inertials "
             "and rotor inertias (its joints' rotor_inertia; simula reads the same ones, so the rigid-body "
             "model is the simulator's own up to the seed's friction draw: what is left is friction and "
             "the loop's latency). For the identified model on a hidden truth see "
             "reports/feedforward-identified.md (`--hidden-truth`).", "",
             "Error of sample k: the plan q_k against the joints the next HOW reports. *cart*: the distance "
             "between the planned and the measured T6 origin. *DAC clipped*: samples whose current command hit "
             "the motor current limit. *no rotor*: computed torque with the data file's link inertials only (the "
             "motor rotors left out: a model error).", "",
             "Reading it: simula's position servo is stiff and kinematic (docs/simula.md, Known limits): a POS "
             "joint reaches its count at the end of the period unless its current or speed limit is hit, so "
             "position mode's error is the encoder's rounding, not a servo's lag; it is the floor, not a rival. "
             "The two current-mode rows are the comparison: the same PD, with and without the model's inertial "
             "and Coriolis torques of the planned motion.", ""]
    lines += table(runs)
    lines += ["", "![tracking error](feedforward.png)", ""]
    return "\n".join(lines)


def hidden_truth_runs(robots: list[str], truth_seed: int, rate: int, seed: int, gains) -> tuple[list[Run], list[str]]:
    """Per arm: identify the hidden truth, then the tour in position, gravity, computed (data file) and
    computed (identified) on simula running that truth."""
    import tempfile
    runs, notes = [], []
    for robot in robots:
        with tempfile.TemporaryDirectory(prefix="bench-ff-") as folder:
            truth, fitted, secs = identified_truth(robot, truth_seed, seed + 7, folder)
            notes.append(f"{robot}: identification (two excitations recorded on the truth, fitted) {secs:.0f} s")
            for mode, theta, label in (("position", None, None), ("gravity", None, "gravity (data file)"),
                                       ("computed", None, "computed, data file"),
                                       ("computed", fitted, "computed, identified")):
                r = run_one(robot, mode, rate, seed, theta=theta, gains=gains, truth=truth, label=label)
                runs.append(r)
                print("\n".join(table([r])[2:]), flush=True)
    return runs, notes


def hidden_report(runs: list[Run], notes: list[str], command: str, rate: int, seed: int, wall: float, gains,
                  truth_seed: int) -> str:
    load = os.getloadavg()
    lines = ["# Feed-forward on a hidden truth: the data file's model against the identified one (issue 27)", "",
             f"Command: `{command}`", "",
             f"Date: {_dt.datetime.now(_dt.timezone.utc):%Y-%m-%d %H:%M} UTC; load average {load[0]:.1f} "
             f"{load[1]:.1f} {load[2]:.1f} (2 cores); wall time {wall:.0f} s. simula runs the hidden truth "
             f"`calib hidden-truth --seed {truth_seed} --inertials` (link masses 5-15 %, rotational inertias and "
             "rotors 10-30 %, friction 10-30 %, gravity 3-10 % away from the data file) with the data file's "
             "torque sensitivities and DH table (the session converts torque to current with the data file's "
             f"sensitivities and plans with the nominal kinematics), lockstep `--dynamic --warm --seed {seed}`, "
             f"{rate} Hz, PD {gains.hz(rate):g} Hz, damping {gains.damping:g}. *computed, data file*: "
             "inverse dynamics + rotor_torque + friction of the data file; *computed, identified*: the base "
             "parameters, rotor coupling and friction `calib fit dynamics` identified on two excitations "
             "recorded on that truth (`calib record dynamics`).", ""] + [f"- {n}" for n in notes] + [""]
    lines += table(runs)
    lines += ["", "![tracking error](feedforward-identified.png)", ""]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.feedforward", description=__doc__.splitlines()[0])
    ap.add_argument("--robot", action="append", choices=tuple(START))
    ap.add_argument("--mode", action="append", choices=MODES)
    ap.add_argument("--rate", type=int, default=250, help="sample rate, Hz (default 250)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--no-rotor", action="store_true",
                    help="add a computed-torque run per arm whose model leaves the motor rotors out")
    ap.add_argument("--hz", type=float, help="the PD's natural frequency, Hz (default: rccl.feedforward.Gains)")
    ap.add_argument("--hidden-truth", type=int, metavar="SEED",
                    help="simula runs this hidden truth; add computed torque with the model calib identifies on it")
    ap.add_argument("--report", type=Path, help="write the markdown report here")
    ap.add_argument("--plot", type=Path, help="write the PNG here")
    a = ap.parse_args(argv)
    t0 = time.monotonic()
    from rccl.feedforward import Gains
    gains = Gains() if a.hz is None else Gains(natural_hz=a.hz)
    runs = []
    if a.hidden_truth is not None:
        runs, notes = hidden_truth_runs(a.robot or ["puma260"], a.hidden_truth, a.rate, a.seed, gains)
    for robot in (a.robot or ["puma260"]) if a.hidden_truth is None else []:
        for mode in a.mode or MODES:
            r = run_one(robot, mode, a.rate, a.seed, gains=gains)
            runs.append(r)
            print("\n".join(table([r])[2:]), flush=True)
        if a.no_rotor:
            r = run_one(robot, "computed", a.rate, a.seed, gains=gains, rotor=np.zeros(len(START[robot])))
            runs.append(r)
            print("\n".join(table([r])[2:]), flush=True)
    wall = time.monotonic() - t0
    command = "python -m bench.feedforward " + " ".join(argv if argv is not None else sys.argv[1:])
    if a.report and a.hidden_truth is not None:
        a.report.write_text(hidden_report(runs, notes, command.strip(), a.rate, a.seed, wall, gains, a.hidden_truth))
    elif a.report:
        a.report.write_text(report(runs, command.strip(), a.rate, a.seed, wall, gains))
    if a.plot:
        plot(runs, a.plot)
    return 0


if __name__ == "__main__":
    sys.exit(main())
