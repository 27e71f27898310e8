"""Issue 30: the PUMA 560's friction on the joints with gravity-free windows inside its ranges
(1, 4, 5, 6; 2 and 3, whose windows gravity works on: tests/test_calib_friction560_loaded.py),
recorded on a lockstep simula
of a hidden truth (rcci.calib.hidden_truth seed 4: friction 10-30 % away from the data file) with
simula seed 8, and fitted as `calib fit friction` fits with the truth's own sensitivities: the
Coulomb and viscous coefficients of both directions within their printed intervals. Joint 1
sweeps +-150 deg about 0 (the PUMA 260's pose leaves its +-160 deg range), joint 4 +-102 deg.
A few minutes of recording under load: `-m slow`."""
from __future__ import annotations

import numpy as np
import pytest
from hidden_truth_runs import HiddenTruth

from rcci.calib.experiments import friction_plans
from rcci.calib.fitting import run_fit

ROBOT, TRUTH_SEED, SIMULA_SEED = "puma560", 4, 8


@pytest.mark.slow
def test_puma560_friction_of_joints_1_4_5_6_within_their_intervals(tmp_path):
    ht = HiddenTruth(ROBOT, TRUTH_SEED, SIMULA_SEED, tmp_path)
    data, info = ht.data, ht.info
    plans = []
    for j in (1, 4, 5, 6):
        (plan,) = friction_plans([j], speeds_deg=(20, 40, 70), trips=(1, 2, 3), robot=info)
        lo, hi = plan.meta["window"]
        assert info.lower[j - 1] < lo < hi < info.upper[j - 1]          # the window inside the range
        plans.append(plan)
    traces, truth = ht.traces_and_truth(ht.record_each_on_its_own_simula(plans))
    params = {"calib": {"robot": ROBOT}, "motors": {"torque_sensitivity": data["motors"]["torque_sensitivity"]}}
    res = run_fit("friction", traces, info, params).results
    assert [r.joint for r in res] == [1, 4, 5, 6]
    for r in res:
        j = r.joint - 1
        for fit, key in ((r.plus, "pos"), (r.minus, "neg")):
            fc, fv = getattr(truth, f"coulomb_{key}")[j], getattr(truth, f"viscous_{key}")[j]
            assert abs(fc / info.nominal["friction"][f"coulomb_{key}"]["values"][j] - 1) > 0.05   # not the data file
            assert abs(fit.coulomb - fc) <= fit.coulomb_err, (r.joint, key, fit.coulomb, fit.coulomb_err, fc)
            assert abs(fit.viscous - fv) <= fit.viscous_err, (r.joint, key, fit.viscous, fit.viscous_err, fv)
            assert np.isfinite(fit.coulomb_err) and fit.coulomb_err < 0.2 * fc
