"""Issue 30: the PUMA 560's friction on joints 2 and 3, whose windows gravity always works on (their
centres of mass lie off the links' lines: cy2, cx3), recorded on a lockstep simula of a hidden truth
(rcci.calib.hidden_truth seed 4: friction 10-30 %, gravity 3-10 % away from the data file) with
simula seed 8. The window is centred on the upright link (rcci.calib.friction_poses.
loaded_friction_pose), where the links' weight along them cancels and only the small off-line terms
work; the fit takes their mean off with the data file's gravity coefficients (none fitted here),
each given 10 % as its error (rcci.calib.window_gravity.GRAVITY_TOLERANCE), and carries that into
F_c's interval. Both directions' Coulomb and viscous coefficients must lie within their intervals,
and the correction is taken off both directions with opposite signs.
A few minutes of recording under load: `-m slow`."""
from __future__ import annotations

import numpy as np
import pytest
from hidden_truth_runs import HiddenTruth

from rcci.calib.experiments import friction_plans
from rcci.calib.fitting import run_fit

ROBOT, TRUTH_SEED, SIMULA_SEED = "puma560", 4, 8


@pytest.mark.slow
def test_puma560_friction_of_joints_2_3_with_gravity_taken_off(tmp_path):
    ht = HiddenTruth(ROBOT, TRUTH_SEED, SIMULA_SEED, tmp_path)
    data, info = ht.data, ht.info
    plans = []
    for j in (2, 3):
        (plan,) = friction_plans([j], speeds_deg=(20, 40, 70), trips=(1, 2, 3), robot=info)
        lo, hi = plan.meta["window"]
        assert plan.meta["gravity_loaded"] and info.lower[j - 1] < lo < hi < info.upper[j - 1]
        plans.append(plan)
    traces, truth = ht.traces_and_truth(ht.record_each_on_its_own_simula(plans))
    params = {"calib": {"robot": ROBOT}, "motors": {"torque_sensitivity": data["motors"]["torque_sensitivity"]}}
    out = run_fit("friction", traces, info, params)
    assert [r.joint for r in out.results] == [2, 3]
    assert any("gravity works over its friction window" in n for n in out.notes)
    for r in out.results:
        j = r.joint - 1
        for fit, key, d in ((r.plus, "pos", 1), (r.minus, "neg", -1)):
            fc, fv = getattr(truth, f"coulomb_{key}")[j], getattr(truth, f"viscous_{key}")[j]
            assert abs(fc / info.nominal["friction"][f"coulomb_{key}"]["values"][j] - 1) > 0.05   # not the data file
            assert d * fit.window_gravity == pytest.approx(r.plus.window_gravity) != 0.0   # +g_w up, -g_w down
            assert abs(fit.coulomb - fc) <= fit.coulomb_err, (r.joint, key, fit.coulomb, fit.coulomb_err, fc)
            assert abs(fit.viscous - fv) <= fit.viscous_err, (r.joint, key, fit.viscous, fit.viscous_err, fv)
            assert np.isfinite(fit.coulomb_err) and fit.coulomb_err < 0.2 * fc
            print(f"joint {r.joint} {key}: F_c {fit.coulomb:.3f} +- {fit.coulomb_err:.3f} (truth {fc:.3f}), "
                  f"F_v {fit.viscous:.2f} +- {fit.viscous_err:.2f} (truth {fv:.2f}), g_w {fit.window_gravity:+.3f} N m")
