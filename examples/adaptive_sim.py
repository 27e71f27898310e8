"""Helper of the adaptive examples: a simula process inside an environment (plane, box, conveyor).

``environment_simula("plane:z=0.12", "tool:z=0.05")`` is ``SimulaProcess`` started as
``python -m rci.simula --env plane:z=0.12 --env tool:z=0.05 -p --power-on --warm
--lockstep --port 0``: simula's own command line with its ``--env`` option.
"""
from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

from rci.simula.process import SimulaProcess


class EnvironmentSimula(SimulaProcess):
    """SimulaProcess (``python -m rci.simula``) with one ``--env`` option per environment word."""

    def __init__(self, *env: str, args: tuple[str, ...] = ("-p", "--power-on", "--warm"), **kw) -> None:
        words = [a for w in env for a in ("--env", w)]
        super().__init__(*args, *words, **kw)


def environment_simula(*env: str, **kw) -> EnvironmentSimula:
    warnings.filterwarnings("ignore", category=RuntimeWarning)   # Python kinematics without the C kernels
    return EnvironmentSimula(*env, **kw)


def example_args(doc: str, argv: list[str], plot: bool = False) -> argparse.Namespace:
    """The command line shared by the adaptive examples: an optional robot link URL (default:
    a simula started for the run) and, if the example draws one, ``--plot``.

    ``--help`` prints the example's docstring and exits; an unknown option is an error
    naming it (argparse), never taken for a link URL."""
    ap = argparse.ArgumentParser(description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("url", nargs="?", default=None,
                    help="robot link (pyserial URL or device, e.g. socket://127.0.0.1:7600); "
                         "default: start a lockstep simula in the example's environment")
    if plot:
        ap.add_argument("--plot", action="store_true", help="write the example's figure (reports/ unless --out)")
        ap.add_argument("--out", type=Path, metavar="PNG", help="with --plot: write the figure here instead")
    return ap.parse_args(argv)


def run_main(main, url: str | None, *env: str):
    """``main(url)`` on the robot at ``url``, else on an environment simula (``env`` words)
    started for the run and stopped after it; returns what ``main`` returns."""
    if url:
        return main(url)
    with environment_simula(*env) as sim:
        return main(sim.url)


def save_figure(fig, out: Path) -> Path:
    """Lay out ``fig``, write it to ``out`` (110 dpi; its folder made if missing), close it; returns ``out``."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    out.parent.mkdir(exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


if __name__ == "__main__":  # pragma: no cover - a quick check that the environment simula starts
    argparse.ArgumentParser(description=__doc__.splitlines()[0] + " Run alone: start one in front "
                            "of a plane and print its contact force.").parse_args()
    with environment_simula("plane:z=0.12", "tool:z=0.05") as sim:
        print(sim.url, sim.command("state")["state"]["contact_force"])
    sys.exit(0)
