"""Friction against speed per joint, one panel per direction, as the thesis's Appendix B (PNG)."""
from __future__ import annotations

import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from rcci.calib.exceptions import CalibError  # noqa: E402
from rcci.calib.friction import FrictionPoint, FrictionResult  # noqa: E402


def y_limits(friction: np.ndarray, fit, top_speed: float) -> tuple[float, float]:
    """The y-range (N m) of a direction's panel: the passes, the fitted line from 0 to
    ``top_speed`` (rad/s) and F_c's band, with 8 % to spare."""
    line = np.array([fit.coulomb, fit.coulomb + fit.viscous * top_speed])
    lo = min(friction.min() if len(friction) else line.min(), line.min() - fit.coulomb_err)
    hi = max(friction.max() if len(friction) else line.max(), line.max() + fit.coulomb_err)
    pad = 0.08 * (hi - lo) + 1e-6
    return float(lo - pad), float(hi + pad)


def friction_plots(results: list[FrictionResult], points: list[FrictionPoint],
                   folder: str, prefix: str = "calib-friction-j") -> list[str]:
    """One PNG per joint: for each direction its own panel (the two directions' frictions
    differ by more than the viscous rise, so on one axis either would be flat), the passes
    (N m against degrees/s, less gravity's mean over the window where the fit took it off),
    the fitted line of 4.27 and the band of F_c's printed uncertainty; each y-axis spans
    the points and the line, not zero. Returns the paths."""
    try:
        os.makedirs(folder, exist_ok=True)
    except OSError as exc:
        raise CalibError(f"{folder}: cannot create the plot folder: {exc.strerror}") from None
    written = []
    for r in results:
        fig, axes = plt.subplots(1, 2, figsize=(8.0, 3.6), dpi=100)
        for ax, (d, fit, name, face) in zip(axes, ((1, r.plus, "+", "none"), (-1, r.minus, "-", "k"))):
            pts = [p for p in points if p.joint == r.joint and p.direction == d]
            v = np.degrees([p.speed for p in pts])
            f = np.array([p.friction for p in pts]) - fit.window_gravity
            vs = np.linspace(0.0, max(v.max() if len(v) else 1.0, 1.0) * 1.05, 50)
            line = fit.coulomb + fit.viscous * np.radians(vs)
            ax.fill_between(vs, line - fit.coulomb_err, line + fit.coulomb_err, color="0.85", lw=0,
                            label=f"F_c +- {fit.coulomb_err:.3f} N m")
            # the line's slope in the axis's unit (N m per deg/s), and F_v as the fit gives it (per rad/s)
            ax.plot(vs, line, "k-", lw=0.9, label=f"{fit.coulomb:.3f} + {1e3 * np.radians(fit.viscous):.3f}e-3 v, "
                                                   f"v in deg/s (F_v {fit.viscous:.4f} N m s/rad)")
            label = f"passes ({len(pts)})" + (f", window gravity {fit.window_gravity:+.4f} N m taken off"
                                               if fit.window_gravity else "")
            ax.plot(v, f, "o", mfc=face, mec="k", ms=4, ls="none", label=label)
            ax.set_ylim(*y_limits(f, fit, np.radians(vs[-1])))
            ax.set_xlim(left=0)
            ax.set_xlabel("speed (degrees/s)")
            ax.set_ylabel("friction (N m)")
            ax.set_title(f"joint {r.joint}, ({name}) direction")
            ax.legend(loc="upper left", fontsize=7)
        fig.tight_layout()
        path = os.path.join(folder, f"{prefix}{r.joint}.png")
        fig.savefig(path)
        plt.close(fig)
        written.append(path)
    return written
