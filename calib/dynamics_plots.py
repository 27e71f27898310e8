"""Measured against predicted joint torque on a held-out excitation log, one panel per joint (PNG)."""
from __future__ import annotations

import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from rcci.calib.exceptions import CalibError  # noqa: E402


def heldout_plot(h, folder: str, name: str) -> str:
    """``folder/name.png``: measured (grey) and predicted (black) torque of each joint of the
    held-out log ``h`` (rcci.calib.dynamics.Heldout), with the RMS of their difference and the noise."""
    n = h.measured.shape[1]
    fig, axes = plt.subplots(n, 1, figsize=(8.0, 1.6 * n), dpi=100, sharex=True)
    for j, ax in enumerate(np.atleast_1d(axes)):
        ax.plot(h.t, h.measured[:, j], color="0.6", lw=0.6, label="measured")
        ax.plot(h.t, h.predicted[:, j], color="k", lw=0.9, label="predicted")
        ax.set_ylabel(f"joint {j + 1}\nN m", fontsize=8)
        ax.tick_params(labelsize=7)
        title = (f"RMS (moving) {h.rms_moving[j]:.4f} N m, noise {h.noise[j]:.4f} N m" if j in h.fitted
                 else "equation not fitted (rcci.calib.unmeasured): measured only")
        ax.set_title(title, fontsize=7, loc="right")
    axes[0].legend(fontsize=7, loc="upper left")
    axes[-1].set_xlabel("time (s)")
    fig.suptitle(f"held-out excitation {os.path.basename(h.path)}: measured vs predicted joint torque", fontsize=9)
    fig.tight_layout()
    path = os.path.join(folder, name + ".png")
    try:
        os.makedirs(folder, exist_ok=True)
        fig.savefig(path)
    except OSError as exc:
        raise CalibError(f"{path}: cannot write the plot: {exc.strerror}") from None
    finally:
        plt.close(fig)
    return path
