"""Friction against speed per joint and direction, as the thesis's Appendix B (PNG)."""
from __future__ import annotations

import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from calib.friction import FrictionPoint, FrictionResult  # noqa: E402


def friction_plots(results: list[FrictionResult], points: list[FrictionPoint],
                   folder: str, prefix: str = "calib-friction-j") -> list[str]:
    """One PNG per joint: o (+) and filled (-) points, N m against degrees/s, with the
    fitted lines of 4.27.  Returns the paths written."""
    os.makedirs(folder, exist_ok=True)
    written = []
    for r in results:
        fig, ax = plt.subplots(figsize=(5.5, 4.0), dpi=100)
        for d, fit, marker in ((1, r.plus, "o"), (-1, r.minus, "o")):
            pts = [p for p in points if p.joint == r.joint and p.direction == d]
            v = np.degrees([p.speed for p in pts])
            f = np.array([p.friction for p in pts])
            face = "none" if d > 0 else "k"
            ax.plot(v, f, marker, mfc=face, mec="k", ls="none",
                    label=f"({'+' if d > 0 else '-'}) direction")
            vs = np.linspace(0.0, max(v.max() if len(v) else 1.0, 1.0) * 1.05, 50)
            ax.plot(vs, fit.coulomb + fit.viscous * np.radians(vs), "k-" if d > 0 else "k--", lw=0.8)
        ax.set_xlabel("speed (degrees/s)")
        ax.set_ylabel("friction (N m)")
        ax.set_title(f"Friction against speed, joint {r.joint}")
        ax.set_xlim(left=0)
        ax.set_ylim(bottom=0)
        ax.legend(loc="lower right", fontsize=8)
        fig.tight_layout()
        path = os.path.join(folder, f"{prefix}{r.joint}.png")
        fig.savefig(path)
        plt.close(fig)
        written.append(path)
    return written
