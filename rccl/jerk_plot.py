"""Figure: joint velocity, acceleration and jerk of the quartic and the Ruckig generators on one tour.

Runs the same tour (four positions 5-6 cm apart with small rotations, joint mode, the same
``settime``: 0.8 s travel, 0.2 s transitions) on a simula process in lockstep, once with each generator, and plots what was
commanded: velocity, acceleration and jerk of every joint, by finite differences of the
commanded samples at the sample period, each divided by that joint's limit (the model's
velocity and acceleration limits, the Ruckig mode's jerk limit), so +-1 is the limit. Prints each run's peak ratios to the limits and its duration.

    .venv/bin/python -m rccl.jerk_plot [--out docs/rccl-jerk.png]
"""
from __future__ import annotations

import argparse
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
START = np.radians([0.0, 80.0, -170.0, 10.0, -60.0, 0.0])   # the bench's and tests' start, away from singularities
RATE_HZ = 36
TRAVEL_S, TRANSITION_S = 0.8, 0.2        # settime for every move of the tour (s)


def tour_samples(url: str, trajectory: str, mode: str = "joint") -> np.ndarray:
    """Commanded joint angles (rad, (N, 6)) of the tour run with ``trajectory`` ('quartic' or 'ruckig')."""
    import rccl
    from rccl import EQ, T6, TL, Trsf, makeposition
    from rccl.transform import rot, trsl

    with rccl.open(url, robot="puma260", rate_hz=RATE_HZ, record=True, on_error="raise", timeout=2.0,
                   trajectory=trajectory) as arm:
        arm.setmod("joint")
        arm.setvel(0.2, 2.0)
        start = makeposition("start", T6, EQ, Trsf("S", arm.kinematics.fk(START)), TL, T6)
        arm.move(start)
        arm.waitfor(start.end)
        _settle(arm)
        base = arm.t6
        arm.setmod(mode)
        arm.settime(TRANSITION_S, TRAVEL_S)    # the same pace for both: quartic travel time, Ruckig minimum duration
        n0 = len(arm.trace)
        offsets = [trsl(0.05, 0.0, 0.0), trsl(0.05, 0.05, 0.02) @ rot("z", 0.2),
                   trsl(0.0, 0.05, 0.0) @ rot("x", 0.1), trsl(0.0, 0.0, 0.0)]
        last = None
        for i, o in enumerate(offsets):
            last = makeposition(f"p{i}", T6, EQ, Trsf(f"P{i}", o @ base), TL, T6)
            arm.move(last)
        arm.waitfor(last.end)
        _settle(arm)
        return np.array([x[1] for x in arm.trace[n0 - 3:]])


def _settle(arm, seconds: float = 0.3) -> None:
    n = len(arm.trace)
    arm.rci.wait(5.0, until=lambda: len(arm.trace) >= n + int(seconds * RATE_HZ))


def derivatives(q: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Velocity, acceleration and jerk (rad/s, rad/s^2, rad/s^3) by finite differences of samples ``q``."""
    v = np.diff(q, axis=0) / dt
    a = np.diff(v, axis=0) / dt
    return v, a, np.diff(a, axis=0) / dt


def plot(runs: dict[str, np.ndarray], out: Path) -> Path:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from rccl.jerk import JerkLimits
    from rccl.limits import load_limits

    lim = JerkLimits.from_limits(load_limits("puma260"))
    dt = 1.0 / RATE_HZ
    fig, axes = plt.subplots(3, len(runs), figsize=(12, 8.5), sharey="row", sharex=True)
    rows = (("velocity / limit", lim.joint_velocity), ("acceleration / limit", lim.joint_acceleration),
            ("jerk / Ruckig's jerk limit", lim.joint_jerk))
    for c, (name, q) in enumerate(runs.items()):
        v, a, j = derivatives(q, dt)
        for r, (data, (label, bound)) in enumerate(zip((v, a, j), rows)):
            ax = axes[r, c]
            t = (np.arange(len(data)) + 0.5 * (r + 1)) * dt
            for i in range(6):
                ax.plot(t, data[:, i] / bound[i], lw=1.0, label=f"joint {i + 1}")
            ax.axhline(1.0, color="k", ls="--", lw=0.8)
            ax.axhline(-1.0, color="k", ls="--", lw=0.8)
            if c == 0:
                ax.set_ylabel(label)
            if r == 0:
                ax.set_title(f"{name}: peak jerk {(np.abs(j).max(0) / lim.joint_jerk).max():.2f} x limit, "
                             f"{len(q) * dt:.2f} s")
            ax.grid(alpha=0.3)
        axes[-1, c].set_xlabel("time (s)")
    axes[0, 0].legend(fontsize=7, ncol=3, loc="upper left")
    fig.suptitle(f"PUMA 260 on simula, the same joint-mode tour (settime {TRANSITION_S} s, {TRAVEL_S} s per move): "
                 f"commanded samples at {RATE_HZ} Hz, per joint divided by its limit\n"
                 "(dashed: the limit; the quartic has no jerk limit, its jerk is scaled by Ruckig's for comparison)",
                 fontsize=10)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=100, metadata={"Software": None})
    plt.close(fig)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "docs" / "rccl-jerk.png"), help="PNG to write")
    args = ap.parse_args(argv)
    from rci.simula.process import SimulaProcess

    from rccl.jerk import JerkLimits
    from rccl.limits import load_limits

    lim = JerkLimits.from_limits(load_limits("puma260"))
    runs = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)   # Python kinematics when the C kernels are not built
        for name, trajectory in (("quartic (thesis, default)", "quartic"), ("Ruckig (jerk-limited)", "ruckig")):
            with SimulaProcess("-p", "--power-on", lockstep=True) as sim:
                runs[name] = tour_samples(sim.url, trajectory)
    for name, q in runs.items():
        v, a, j = derivatives(q, 1.0 / RATE_HZ)
        print(f"{name:28s} {len(q) / RATE_HZ:5.2f} s  peak/limit: velocity "
              f"{(np.abs(v).max(0) / lim.joint_velocity).max():.2f}, acceleration "
              f"{(np.abs(a).max(0) / lim.joint_acceleration).max():.2f}, jerk "
              f"{(np.abs(j).max(0) / lim.joint_jerk).max():.2f}")
    print(plot(runs, Path(args.out)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
