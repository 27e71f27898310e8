"""Issue 30: the PUMA 560's torque sensitivities of motors 2 and 3, whose arcs gravity works on (no
pose frees joints 2 and 3 of it: rcci.calib.friction_poses.loaded_friction_pose), recorded on a
lockstep simula of a hidden truth (rcci.calib.hidden_truth seed 4: sigma 10-30 % away from the data
file) with simula seed 8. Gravity's work cancels between the + and - passes and again between the
runs with and without the mass (4.43), so the arc about the upright link serves; each fitted
sensitivity must lie within its printed interval of the truth's. A few minutes of recording under
load: `-m slow`."""
from __future__ import annotations

import numpy as np
import pytest

from rcci.calib.experiments import sensitivity_plans
from rcci.calib.fitting import run_fit
from rcci.calib.hidden_truth import write_hidden_truth
from rcci.calib.logs import load_trace
from rcci.calib.lsq import coverage_factor
from rcci.calib.program import run_plan
from rcci.calib.robot import robot_info
from rcci.calib.truth import truth_meta, truth_of

ROBOT, TRUTH_SEED, SIMULA_SEED = "puma560", 4, 8


@pytest.mark.slow
def test_puma560_sensitivity_of_motors_2_3_on_gravity_loaded_arcs(tmp_path):
    from rci.simula.process import SimulaProcess

    truth_file = str(tmp_path / "truth.toml")
    data = write_hidden_truth(truth_file, ROBOT, TRUTH_SEED)
    info = robot_info(ROBOT)
    args = ["--warm", "--params", truth_file]
    meta = {"truth": truth_meta(SIMULA_SEED, truth_file, args)}
    plans = sensitivity_plans(None, 0.05, joints=[2, 3], speeds_deg=(15, 30), trips=3, robot=info)
    paths = []
    with SimulaProcess("-p", *args, "--test-channel", robot=ROBOT, lockstep=True, seed=SIMULA_SEED) as sim:
        for plan in plans:
            plan.warmup = None                    # a warm simula
            load = plan.meta["load"]
            spec = (f"pulley:joint={plan.meta['joint']},mass={load['mass_kg']},radius={load['radius_m']}"
                    if load["mass_kg"] > 0 else "none")
            assert sim.command(f"load {spec}")["ok"]
            paths.append(str(tmp_path / f"{plan.name}.rcilog"))
            run_plan(sim.url, plan, paths[-1], ROBOT, rate_hz=plan.rate_hz, extra_meta=meta)
    traces = [load_trace(p) for p in paths]
    truth = truth_of(traces, info)
    res = run_fit("sensitivity", traces, info, {}).results
    assert [s.joint for s in res] == [2, 3]
    for s in res:
        m = s.joint - 1
        tv = float(truth.sigma[m])
        assert abs(tv / info.drive.sigma[m] - 1) > 0.05 and tv == pytest.approx(data["motors"]["torque_sensitivity"][m])
        interval = coverage_factor(s.trials - 1) * s.std / np.sqrt(s.trials)
        print(f"motor {s.joint}: sigma {s.mean:.4f} +- {interval:.4f} N m/A ({s.trials} trials), truth {tv:.4f}")
        assert abs(s.mean - tv) <= interval, (s.joint, s.mean, interval, tv)
