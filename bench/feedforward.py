"""Tracking error of a fast Cartesian tour in three servo modes: position, gravity-only and computed torque.

    .venv/bin/python -m bench.feedforward                          # puma260, 250 Hz
    .venv/bin/python -m bench.feedforward --robot puma260 --robot microbo --robot puma560 --robot stanford \\
        --report reports/feedforward.md --plot reports/feedforward.png

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


def run_one(robot: str, mode: str, rate: int, seed: int, theta=None, gains=None, rotor=None) -> Run:
    """A fresh lockstep ``simula --dynamic`` for one tour (every mode starts from the same state)."""
    from rci.simula.process import SimulaProcess
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        with SimulaProcess("-p", "--power-on", "--dynamic", "--lockstep-watchdog", "20",
                           robot=robot, lockstep=True, seed=seed) as sim:
            run = tour(sim.url, robot, mode, rate, theta, gains, rotor)
    if rotor is not None:
        run.mode = f"{mode}, no rotor"
    return run


def table(runs: list[Run]) -> list[str]:
    """Markdown rows: per run the RMS/max of the wrist-centre error (mm) and of each joint (mrad, mm)."""
    out = ["| arm | mode | cart RMS (mm) | cart max (mm) | joint RMS, 1..6 (mrad / mm) | joint max, 1..6 | "
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
               "computed, no rotor": "tab:purple"}
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
             "and the rotor estimate (rccl.feedforward; simula holds the same estimate, so the rigid-body "
             "model is the simulator's own up to the seed's friction draw: what is left is friction and "
             "the loop's latency).", "",
             "Error of sample k: the plan q_k against the joints the next HOW reports. *cart*: the distance "
             "between the planned and the measured T6 origin. *DAC clipped*: samples whose current command hit "
             "the motor current limit. *no rotor*: computed torque with the data file's inertials only (the "
             "motor rotors, which no data file gives, left out: a model error).", "",
             "Reading it: simula's position servo is stiff and kinematic (docs/simula.md, Known limits): a POS "
             "joint reaches its count at the end of the period unless its current or speed limit is hit, so "
             "position mode's error is the encoder's rounding, not a servo's lag; it is the floor, not a rival. "
             "The two current-mode rows are the comparison: the same PD, with and without the model's inertial "
             "and Coriolis torques of the planned motion.", ""]
    lines += table(runs)
    lines += ["", "![tracking error](feedforward.png)", ""]
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
    ap.add_argument("--report", type=Path, help="write the markdown report here")
    ap.add_argument("--plot", type=Path, help="write the PNG here")
    a = ap.parse_args(argv)
    t0 = time.monotonic()
    from rccl.feedforward import Gains
    gains = Gains() if a.hz is None else Gains(natural_hz=a.hz)
    runs = []
    for robot in a.robot or ["puma260"]:
        for mode in a.mode or MODES:
            r = run_one(robot, mode, a.rate, a.seed, gains=gains)
            runs.append(r)
            print("\n".join(table([r])[2:]), flush=True)
        if a.no_rotor:
            r = run_one(robot, "computed", a.rate, a.seed, gains=gains, rotor=np.zeros(6))
            runs.append(r)
            print("\n".join(table([r])[2:]), flush=True)
    wall = time.monotonic() - t0
    command = "python -m bench.feedforward " + " ".join(argv if argv is not None else sys.argv[1:])
    if a.report:
        a.report.write_text(report(runs, command.strip(), a.rate, a.seed, wall, gains))
    if a.plot:
        plot(runs, a.plot)
    return 0


if __name__ == "__main__":
    sys.exit(main())
