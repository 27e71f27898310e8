"""``python -m rci.plot LOG``: a picture of a recorded run (joint positions, rates, motor currents, timing, the Cartesian path).

    python -m rci.plot run.rcilog                         # writes run.png beside the log
    python -m rci.plot calib/logs/kinematics.rcilog.xz --out kin.png

Six panels from one ``.rcilog`` (docs/recording.md), every value in SI units through
``rci.log_units`` (the same numbers ``rci.export`` and ``rcci.view.replay`` show):

* joint positions, measured (solid) and commanded by POS (dashed), rad (m on a prismatic joint);
* joint rates, measured, rad/s (m/s);
* motor currents from the ADC, A (commanded CUR torques, where sent, are in the export);
* timing per cycle: the host's interval between records and the control's duration against the
  period, ms, and the lateness of the robot's HOW (its own axis);
* the path of T6 (link 6's origin, base frame) seen from above (x-y) and from the side (x-z), measured
  and, where every joint was commanded by position (an RCCL run), commanded.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from .exceptions import LogFormatError
from .log_units import LogSI, log_in_si
from .recorder import Log, read_log

COLORS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b")


def default_out(log_path: str | Path) -> Path:
    """``run.rcilog`` (or ``run.rcilog.xz``) -> ``run.png`` beside it."""
    p = Path(log_path)
    name = p.name
    for suffix in (".xz", ".gz", ".rcilog"):
        name = name.removesuffix(suffix)
    return p.with_name(name + ".png")


def _joint_label(si: LogSI, j: int) -> str:
    return f"joint {j + 1}" + (" (m)" if si.prismatic[j] else "")


def plot_log(log: Log, out: str | Path, *, title: str | None = None, dpi: int = 110) -> Path:
    """Draw ``log`` into the PNG ``out`` (module docstring); returns its path."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    si = log_in_si(log)
    r = log.records
    t = si.t
    fig, ax = plt.subplots(3, 2, figsize=(13, 11), constrained_layout=True)
    (a_q, a_qd), (a_i, a_t), (a_xy, a_xz) = ax
    for j in range(si.q.shape[1]):
        c = COLORS[j % len(COLORS)]
        a_q.plot(t, si.q[:, j], color=c, lw=1.2, label=_joint_label(si, j))
        if np.isfinite(si.q_cmd[:, j]).any():
            a_q.plot(t, si.q_cmd[:, j], color=c, lw=1.0, ls="--")
        a_qd.plot(t, si.qd[:, j], color=c, lw=1.0, label=_joint_label(si, j))
        if si.current is not None:
            a_i.plot(t, si.current[:, j], color=c, lw=0.8, label=f"motor {j + 1}")
    a_q.set(title="joint positions: measured (solid), commanded by POS (dashed)", xlabel="time (s)",
            ylabel="rad (m for a prismatic joint)")
    a_q.legend(fontsize=8, ncol=2)
    a_qd.set(title="joint rates, measured (central differences)", xlabel="time (s)",
             ylabel="rad/s (m/s for a prismatic joint)")
    a_qd.legend(fontsize=8, ncol=2)
    if si.current is not None:
        a_i.set(title="motor currents from the ADC (eq. C.1)", xlabel="time (s)", ylabel="A")
        a_i.legend(fontsize=8, ncol=2)
    else:
        a_i.text(0.5, 0.5, "the log has fewer ADC channels than joints: no currents", ha="center",
                 transform=a_i.transAxes)
    rate = np.asarray(r["rate_hz"], float)
    host = np.asarray(r["t"], float)
    a_t.plot(t[1:], np.diff(host) * 1e3, lw=0.8, color="#1f77b4", label="interval between records (host)")
    a_t.plot(t, np.asarray(r["duration"], float) * 1e3, lw=0.8, color="#d62728", label="control duration")
    with np.errstate(divide="ignore"):
        a_t.plot(t, np.where(rate > 0, 1e3 / rate, np.nan), lw=1.2, ls=":", color="black", label="period")
    a_t.set(title="timing per cycle", xlabel="time (s)", ylabel="ms")
    a_t.set_ylim(bottom=0)
    # lateness on its own axis: against a lockstep simulator it drifts by seconds, which would
    # flatten the millisecond curves
    a_late = a_t.twinx()
    a_late.plot(t, np.asarray(r["lateness"], float) * 1e3, lw=0.8, color="#7f7f7f", alpha=0.7)
    a_late.set_ylabel("HOW lateness (ms, grey)", color="#555555")
    a_t.legend(fontsize=8, loc="center right")
    p = si.T6[:, :3, 3]
    pc = si.T6_cmd[:, :3, 3]
    for a, (i, k), names in ((a_xy, (0, 1), "xy"), (a_xz, (0, 2), "xz")):
        a.plot(p[:, i], p[:, k], color="#1f77b4", lw=1.5, label="T6 measured")
        if np.isfinite(pc).all(axis=1).any():
            a.plot(pc[:, i], pc[:, k], color="#ff7f0e", lw=1.0, ls="--", label="T6 commanded")
        a.plot(p[:1, i], p[:1, k], "o", ms=11, mfc="none", mew=2, color="#2ca02c", label="start")
        a.plot(p[-1:, i], p[-1:, k], "s", color="#d62728", label="end")
        a.set(title=f"path of T6, {'seen from above' if names == 'xy' else 'seen from the side'}",
              xlabel=f"{names[0]} (m, base frame)", ylabel=f"{names[1]} (m, base frame)")
        a.set_aspect("equal", adjustable="datalim")
        a.legend(fontsize=8)
    rate0 = log.meta.get("rate_hz")
    fig.suptitle(title or f"{Path(log.path).name}: {si.robot}, {len(r)} records, {t[-1] if len(t) else 0:.2f} s"
                 f"{f', {rate0} Hz' if rate0 else ''}" + ("" if log.complete else " (not closed: cut short)"))
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=dpi)
    plt.close(fig)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m rci.plot", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("log", help="a recorder log (.rcilog, or .rcilog.xz / .gz)")
    ap.add_argument("--out", metavar="PNG", help="the picture (default: the log's name with .png, beside it)")
    ap.add_argument("--title", help="the figure's title (default: the log's name, robot, records, duration)")
    ap.add_argument("--dpi", type=int, default=110, help="resolution (default 110: 1430x1210 pixels)")
    args = ap.parse_args(argv)
    try:
        log = read_log(args.log)
    except LogFormatError as exc:
        print(f"rci.plot: {exc}", file=sys.stderr)
        return 2
    if len(log) < 2:
        print(f"rci.plot: {args.log}: {len(log)} records, nothing to plot", file=sys.stderr)
        return 2
    out = Path(args.out) if args.out else default_out(args.log)
    try:
        plot_log(log, out, title=args.title, dpi=args.dpi)
    except OSError as exc:
        print(f"rci.plot: cannot write {out}: {exc.strerror or exc}", file=sys.stderr)
        return 2
    print(f"wrote {out}: {len(log)} records of {args.log}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
