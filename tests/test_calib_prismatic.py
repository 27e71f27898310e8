"""The Stanford arm's prismatic joint 3 calibrated on a hidden truth (rcci.calib.hidden_truth seed 2,
simula seed 6): its torque sensitivity from a 0.2 m stroke with and without a mass pulling the
slide (m g), its Coulomb (N) and viscous (N s/m) friction from sweeps with the axis horizontal;
every value within its printed interval of the truth. About 4 min of recording under load: `-m slow`."""
from __future__ import annotations

import numpy as np
import pytest
from hidden_truth_runs import HiddenTruth

from rcci.calib.experiments import friction_plans, sensitivity_plans
from rcci.calib.fitting import run_fit
from rcci.calib.hidden_truth import hidden_truth
from rcci.calib.lsq import coverage_factor

ROBOT, TRUTH_SEED, SIMULA_SEED = "stanford", 2, 6


@pytest.mark.slow
def test_prismatic_joint_sensitivity_and_friction(tmp_path):
    ht = HiddenTruth(ROBOT, TRUTH_SEED, SIMULA_SEED, tmp_path)
    data, info = ht.data, ht.info
    plans = (sensitivity_plans(None, 0.05, joints=[3], speeds_deg=(10, 20), trips=3, robot=info)
             + friction_plans([3], speeds_deg=(5, 10, 18, 25), trips=(1, 1, 2, 2), robot=info))
    # the pulley pulls the slide in the loaded sensitivity runs only (friction sweeps: no load)
    assert all(p.meta["joint"] == 3 for p in plans if p.meta.get("load", {"mass_kg": 0})["mass_kg"] > 0)
    traces, truth = ht.traces_and_truth(ht.record_with_loads(plans))
    (s,) = run_fit("sensitivity", [t for t in traces if t.experiment == "sensitivity"], info, {}).results
    assert abs(s.mean - truth.sigma[2]) <= coverage_factor(s.trials - 1) * s.std / np.sqrt(s.trials)
    sigma = list(data["motors"]["torque_sensitivity"])
    sigma[2] = s.mean
    params = {"calib": {"robot": ROBOT}, "motors": {"torque_sensitivity": sigma,
              "torque_sensitivity_std": [0, 0, s.std, 0, 0, 0], "torque_sensitivity_trials": [0, 0, s.trials, 0, 0, 0]}}
    (f,) = run_fit("friction", [t for t in traces if t.experiment == "friction"], info, params).results
    for fit, key in ((f.plus, "pos"), (f.minus, "neg")):
        assert abs(fit.coulomb - getattr(truth, f"coulomb_{key}")[2]) <= fit.coulomb_err, key
        assert abs(fit.viscous - getattr(truth, f"viscous_{key}")[2]) <= fit.viscous_err, key
    assert hidden_truth(ROBOT, TRUTH_SEED)["friction"]["coulomb_pos"][2] > 1.0     # newtons, not N m
