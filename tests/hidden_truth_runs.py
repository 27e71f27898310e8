"""Shared test helper: calib's programs recorded on lockstep simulas of a hidden truth.

The long calibration tests (test_calib_friction560, _friction560_loaded, _friction_stanford_loaded,
_sensitivity560_loaded, _breakaway560, _prismatic; all ``-m slow``) each write a hidden truth
(``rcci.calib.hidden_truth``), start real lockstep simula processes with it (``--params``),
record calib's measurement programs there as ``calib record`` does (``rcci.calib.program.run_plan``)
with the truth named in each log's meta, and fit the logs against that truth. ``HiddenTruth`` is
that set-up, written once::

    ht = HiddenTruth("puma560", truth_seed=4, simula_seed=8, folder=tmp_path)
    paths = ht.record_each_on_its_own_simula(plans)      # friction windows: a fresh simula each
    paths = ht.record_with_loads(plans)                  # sensitivity arcs: the pulley hung on and off
    traces, truth = ht.traces_and_truth(paths)

Imported by those tests (``from hidden_truth_runs import HiddenTruth``).
"""
from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

from rcci.calib.hidden_truth import write_hidden_truth
from rcci.calib.logs import load_trace
from rcci.calib.program import run_plan
from rcci.calib.robot import robot_info
from rcci.calib.truth import truth_meta, truth_of


class HiddenTruth:
    """A hidden truth of ``robot`` (seed ``truth_seed``) written into ``folder``, and the lockstep
    simulas (seed ``simula_seed``, ``--warm`` unless ``warm`` is False) that play it."""

    def __init__(self, robot: str, truth_seed: int, simula_seed: int, folder: Path, warm: bool = True) -> None:
        self.robot, self.simula_seed, self.folder = robot, simula_seed, Path(folder)
        self.truth_file = str(self.folder / "truth.toml")
        self.data: dict[str, Any] = write_hidden_truth(self.truth_file, robot, truth_seed)
        self.info = robot_info(robot)
        self.args = (["--warm"] if warm else []) + ["--params", self.truth_file]
        #: what each log's meta carries: the truth it was recorded against (rcci.calib.truth)
        self.meta = {"truth": truth_meta(simula_seed, self.truth_file, self.args)}

    def simula(self, *extra: str):
        """A lockstep simula of the truth, powered (``-p``), with ``extra`` arguments (use in ``with``)."""
        from rci.simula.process import SimulaProcess

        return SimulaProcess("-p", *self.args, *extra, robot=self.robot, lockstep=True, seed=self.simula_seed)

    def log_path(self, name: str) -> str:
        return str(self.folder / f"{name}.rcilog")

    def record(self, sim, plan) -> str:
        """Run ``plan`` on the running ``sim`` (warm: no warm-up) into its log; returns the log's path."""
        plan.warmup = None
        path = self.log_path(plan.name)
        run_plan(sim.url, plan, path, self.robot, rate_hz=plan.rate_hz, extra_meta=self.meta)
        return path

    def record_each_on_its_own_simula(self, plans: list, workers: int = 2) -> list[str]:
        """Each plan on a fresh simula, ``workers`` at a time (a lockstep pair keeps about one CPU
        busy); the logs' paths in the plans' order."""
        def one(plan) -> str:
            with self.simula() as sim:
                return self.record(sim, plan)

        with ThreadPoolExecutor(max_workers=workers) as pool:
            return list(pool.map(one, plans))

    def record_with_loads(self, plans: list) -> list[str]:
        """Every plan on one simula (``--test-channel``), with the pulley mass its ``meta["load"]``
        names hung on its ``meta["joint"]`` or taken off (none), as a lab would between runs."""
        paths = []
        with self.simula("--test-channel") as sim:
            for plan in plans:
                load = plan.meta.get("load", {"mass_kg": 0})
                spec = (f"pulley:joint={plan.meta['joint']},mass={load['mass_kg']},radius={load['radius_m']}"
                        if load["mass_kg"] > 0 else "none")
                reply = sim.command(f"load {spec}")
                assert reply["ok"], (spec, reply)
                paths.append(self.record(sim, plan))
        return paths

    def traces_and_truth(self, paths: list[str]) -> tuple[list, Any]:
        """The recorded logs and the truth they name (rcci.calib.truth.truth_of)."""
        traces = [load_trace(p) for p in paths]
        return traces, truth_of(traces, self.info)
