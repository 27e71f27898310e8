"""Helper of the adaptive examples: a simula process inside an environment (plane, box, conveyor).

``environment_simula("plane:z=0.12", "tool:z=0.05")`` is ``SimulaProcess`` started as
``python -m rci.simula --env plane:z=0.12 --env tool:z=0.05 -p --power-on --warm
--lockstep --port 0``: simula's own command line with its ``--env`` option.
"""
from __future__ import annotations

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


def url_from_argv(argv: list[str]) -> str | None:
    """A ``socket://`` or device argument, if the user gave one."""
    rest = [a for a in argv if not a.startswith("--")]
    return rest[0] if rest else None


def run_main(main, argv: list[str], *env: str):
    """``main(url)`` on the robot the user named in ``argv``, else on an environment simula
    (``env`` words) started for the run and stopped after it; returns what ``main`` returns."""
    url = url_from_argv(argv)
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
    with environment_simula("plane:z=0.12", "tool:z=0.05") as sim:
        print(sim.url, sim.command("state")["state"]["contact_force"])
    sys.exit(0)
