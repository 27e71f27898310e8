"""Plots of RCCL trajectories: `python -m rccl.plots` writes reports/rccl-path.png and reports/rccl-transition.png.

Both come from real runs: a simula process in lockstep is started, RCCL programs run on it,
and the plots show what was commanded and what simula reported back (``how``), with the
tool path computed on the world side by Pinocchio on the URDF.

* ``rccl-path.png``: the program of thesis 5.3.4 (move(p0); move(park)) and a Cartesian
  square with one stop, as XY / XZ projections of the tool path;
* ``rccl-transition.png``: tool speed, joint velocities and joint accelerations across the
  transitions of a Cartesian tour, with each transition window shaded and the acceleration
  limits drawn;
* on stdout, the deviation of one Cartesian straight-line move from its line at 36 Hz
  (commanded, and as simula measured it), with Pinocchio's forward kinematics.

    .venv/bin/python -m rccl.plots [--out reports]
"""
from __future__ import annotations

import argparse
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent


def pinocchio_fk(robot: str = "puma260"):
    """T6 by Pinocchio on models/urdf/<robot>.urdf (the reference the measured paths are
    judged against): a function q (n,) -> (4, 4) base_link -> the last link (link6; link7 of
    a 7-joint arm), metres."""
    import pinocchio as pin
    model = pin.buildModelFromUrdf(str(ROOT / "models" / "urdf" / f"{robot}.urdf"))
    data = model.createData()
    fid = model.getFrameId(f"link{model.nq}")

    def fk(q):
        pin.framesForwardKinematics(model, data, np.asarray(q, dtype=float))
        return data.oMf[fid].homogeneous.copy()
    return fk


def line_deviation(pts: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance (m) of each point of ``pts`` (n x 3, base frame) from the line through ``a`` and ``b``."""
    u = (b - a) / np.linalg.norm(b - a)
    r = pts - a
    return np.linalg.norm(r - np.outer(r @ u, u), axis=1)


def _marks_in_view(marks, j: int, close_mm: float = 3.0) -> list[tuple[str, tuple[float, float]]]:
    """The marks ``(label, T)`` projected on (x, axis j) in mm, those that fall within ``close_mm``
    of an earlier one named together ("c0, c1"): in the XZ view of the tour c0 and c1 differ
    only in y, and two labels on one point overprinted each other."""
    out: list[tuple[str, tuple[float, float]]] = []
    for label, t in marks:
        here = (float(t[0, 3] * 1e3), float(t[j, 3] * 1e3))
        near = next((k for k, (_, at) in enumerate(out) if np.hypot(at[0] - here[0], at[1] - here[1]) < close_mm), None)
        if near is None:
            out.append((label, here))
        else:
            out[near] = (f"{out[near][0]}, {label}", out[near][1])
    return out


def path_plot(arm, marks, title: str, out: Path | None = None, extra=None) -> Path:
    """XY and XZ projections of the tool (T6) path of ``arm.trace`` (commanded and measured)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out or ROOT / "reports" / "rccl-path.png")
    fk = pinocchio_fk()
    runs = [(title, arm, marks)] + (extra or [])
    fig, axes = plt.subplots(len(runs), 2, figsize=(11, 4.8 * len(runs)), squeeze=False)
    for row, (name, a, mk) in enumerate(runs):
        qc = np.array([x[1] for x in a.trace])
        qm = np.array([x[2] for x in a.trace])
        pc = np.array([fk(q)[:3, 3] for q in qc]) * 1e3
        pm = np.array([fk(q)[:3, 3] for q in qm]) * 1e3
        for col, (i, j, lab) in enumerate(((0, 1, "y"), (0, 2, "z"))):
            ax = axes[row, col]
            ax.plot(pc[:, i], pc[:, j], "-", lw=2.5, color="tab:blue", alpha=0.45, label="commanded")
            ax.plot(pm[:, i], pm[:, j], ".", ms=3, color="tab:red", label="measured (simula how)")
            for label, (x, y) in _marks_in_view(mk, j):
                ax.plot(x, y, "k+", ms=12, mew=2)
                ax.annotate(label, (x, y), textcoords="offset points", xytext=(6, 6))
            ax.set_xlabel("x (mm)")
            ax.set_ylabel(f"{lab} (mm)")
            ax.set_aspect("equal", adjustable="datalim")
            ax.grid(alpha=0.3)
            ax.set_title(f"{name}: {'XY' if j == 1 else 'XZ'} projection", fontsize=9)
            ax.legend(fontsize=8, loc="best")
    fig.suptitle("RCCL tool paths (T6 origin, base frame), from `python -m rccl.plots`", fontsize=10)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def transition_plot(arm, windows, out: Path | None = None) -> Path:
    """Tool speed, joint velocities and accelerations (finite differences of the commands) across transitions."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out or ROOT / "reports" / "rccl-transition.png")
    fk = pinocchio_fk()
    t = np.array([x[0] for x in arm.trace])
    qc = np.array([x[1] for x in arm.trace])
    qm = np.array([x[2] for x in arm.trace])
    dt = float(np.median(np.diff(t)))
    v = np.diff(qc, axis=0) / dt
    a = np.diff(v, axis=0) / dt
    pc = np.array([fk(q)[:3, 3] for q in qc])
    pm = np.array([fk(q)[:3, 3] for q in qm])
    speed_c = np.linalg.norm(np.diff(pc, axis=0), axis=1) / dt
    speed_m = np.linalg.norm(np.diff(pm, axis=0), axis=1) / dt
    t0 = t[0]
    tv, ta = t[1:] - t0 - dt / 2, t[1:-1] - t0
    fig, axes = plt.subplots(3, 1, figsize=(11, 10), sharex=True)
    axes[0].plot(tv, speed_c * 1e3, "-", color="tab:blue", label="commanded")
    axes[0].plot(tv - dt, speed_m * 1e3, ".", color="tab:red", ms=3, label="measured (one cycle later)")
    axes[0].set_ylabel("tool speed (mm/s)")
    for i in range(6):
        axes[1].plot(tv, v[:, i], label=f"joint {i + 1}")
        axes[2].plot(ta, a[:, i], label=f"joint {i + 1}")
    lim = arm.limits.joint_acceleration
    axes[2].axhline(float(lim.min()), color="k", ls="--", lw=0.8, label=f"smallest limit {lim.min():.1f} rad/s^2")
    axes[2].axhline(-float(lim.min()), color="k", ls="--", lw=0.8)
    axes[1].set_ylabel("joint velocity (rad/s)")
    axes[2].set_ylabel("joint acceleration (rad/s^2)")
    axes[2].set_xlabel("time (s)")
    for ax in axes:
        for (s, e) in windows:
            ax.axvspan(s - t0, e - t0, color="0.85", zorder=0)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, ncol=4, loc="upper right")
    axes[0].set_title("Cartesian tour at 36 Hz on simula: Paul's quartic transitions (shaded); finite differences "
                      "of the commanded joint angles", fontsize=9)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


class _WindowLog:
    """Logs each transition window (t_start, t_end) in which something moves, through the
    generator's public ``on_transition`` listeners."""

    def __init__(self, gen) -> None:
        self.windows: list[tuple[float, float]] = []
        self.gen = gen
        gen.on_transition.append(self._log)

    def _log(self, event) -> None:
        if event.moving:                # hold-to-hold transitions move nothing
            self.windows.append((event.t_start, event.t_end))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="RCCL trajectory plots from simula runs")
    ap.add_argument("--out", default=str(ROOT / "reports"), help="output directory")
    args = ap.parse_args(argv)
    out = Path(args.out)
    import importlib.util

    import rccl
    from rccl import EQ, T6, TL, Trsf, makeposition
    from rccl.transform import rot, trsl
    from rci.simula.process import SimulaProcess

    spec = importlib.util.spec_from_file_location("rccl_program_534", ROOT / "examples" / "rccl_program_534.py")
    prog = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(prog)
    start_q = np.radians([0.0, 80.0, -170.0, 10.0, -60.0, 0.0])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        with SimulaProcess("-p", "--power-on", lockstep=True) as sim:
            arm534 = prog.main(sim.url, record=True)
            with rccl.open(sim.url, robot="puma260", record=True, timeout=2.0) as arm:
                arm.setmod("joint")
                arm.setvel(0.2, 2.0)
                s = makeposition("start", T6, EQ, Trsf("S", arm.kinematics.fk(start_q)), TL, T6)
                arm.move(s)
                arm.waitfor(s.end)
                base = arm.t6
                arm.trace.clear()
                log = _WindowLog(arm.gen)
                arm.setmod("cartesian")
                arm.setvel(0.1, 1.0)
                corners = [trsl(-0.06, 0.0, 0.0), trsl(-0.06, 0.06, 0.0), trsl(0.0, 0.06, 0.02) @ rot("z", 0.3),
                           trsl(0.0, 0.0, 0.0)]
                ps = [makeposition(f"c{i}", T6, EQ, Trsf(f"C{i}", c @ base), TL, T6) for i, c in enumerate(corners)]
                arm.move(ps[0])
                arm.move(ps[1])
                arm.move(ps[1])          # stop at c1: move to the same point twice
                arm.move(ps[2])
                arm.move(ps[3])
                arm.waitfor(ps[3].end)
                _settle(arm)
            line = straight_line(sim.url)
    marks534 = [("p0", prog.P0_T6), ("park", arm534.park.solve())]
    marks_sq = [(f"c{i}", p.solve()) for i, p in enumerate(ps)]
    p1 = path_plot(arm534, marks534, "thesis 5.3.4: move(p0); move(park) (joint mode)", out / "rccl-path.png",
                   extra=[("Cartesian tour, stop at c1", arm, marks_sq)])
    p2 = transition_plot(arm, [w for w in log.windows if w[0] < arm.trace[-1][0]], out / "rccl-transition.png")
    print("wrote", p1)
    print("wrote", p2)
    print(line)
    return 0


def _settle(arm, seconds: float = 0.3) -> None:
    """Let ``arm`` run ``seconds`` more of trajectory time (s; the same cycles on every run of a lockstep simula)."""
    t_end = arm.gen.t + seconds
    arm.rci.wait(None, until=lambda: arm.gen.t >= t_end)


def straight_line(url: str, rate_hz: int = 36) -> str:
    """One Cartesian move (6 cm in x, y, z with a 0.3 rad turn) at ``rate_hz``; its deviation from the line."""
    import rccl
    from rccl import EQ, T6, TL, Trsf, makeposition
    from rccl.transform import rot, trsl

    fk = pinocchio_fk()
    with rccl.open(url, robot="puma260", rate_hz=rate_hz, record=True, timeout=2.0) as arm:
        arm.setmod("joint")
        s = makeposition("start", T6, EQ, Trsf("S", arm.kinematics.fk(np.radians([0.0, 80.0, -170.0, 10.0, -60.0, 0.0]))),
                         TL, T6)
        arm.move(s)
        arm.waitfor(s.end)
        base = arm.t6
        goal = trsl(-0.06, 0.05, 0.03) @ base @ rot("z", 0.3)
        p = makeposition("p", T6, EQ, Trsf("P", goal), TL, T6)
        arm.setmod("cartesian")
        arm.setvel(0.1, 1.0)
        n0 = len(arm.trace)
        arm.move(p)
        arm.waitfor(p.end)
        _settle(arm)
    a, b = base[:3, 3], goal[:3, 3]
    out = []
    for k, what in ((1, "commanded"), (2, "measured")):
        pts = np.array([fk(x[k])[:3, 3] for x in arm.trace[n0:]])
        dev = line_deviation(pts, a, b).max()
        out.append(f"{what} {dev * 1e3:.4f} mm (end error {np.linalg.norm(pts[-1] - b) * 1e3:.4f} mm)")
    return (f"straight line at {rate_hz} Hz on simula, {np.linalg.norm(b - a) * 1e3:.1f} mm with a 0.3 rad turn "
            "at 0.1 m/s, "
            f"{len(arm.trace) - n0} cycles; max deviation from the line: " + "; ".join(out))


if __name__ == "__main__":
    raise SystemExit(main())
