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

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from rcci.calib.experiments import friction_plans
from rcci.calib.fitting import run_fit
from rcci.calib.hidden_truth import write_hidden_truth
from rcci.calib.logs import load_trace
from rcci.calib.program import run_plan
from rcci.calib.robot import robot_info
from rcci.calib.truth import truth_meta, truth_of

ROBOT, TRUTH_SEED, SIMULA_SEED = "puma560", 4, 8


@pytest.mark.slow
def test_puma560_friction_of_joints_2_3_with_gravity_taken_off(tmp_path):
    from rci.simula.process import SimulaProcess

    truth_file = str(tmp_path / "truth.toml")
    data = write_hidden_truth(truth_file, ROBOT, TRUTH_SEED)
    info = robot_info(ROBOT)
    args = ["--warm", "--params", truth_file]

    def record(j: int) -> str:
        (plan,) = friction_plans([j], speeds_deg=(20, 40, 70), trips=(1, 2, 3), robot=info)
        lo, hi = plan.meta["window"]
        assert plan.meta["gravity_loaded"] and info.lower[j - 1] < lo < hi < info.upper[j - 1]
        plan.warmup = None                                               # a warm simula
        path = str(tmp_path / f"{plan.name}.rcilog")
        with SimulaProcess("-p", *args, robot=ROBOT, lockstep=True, seed=SIMULA_SEED) as sim:
            run_plan(sim.url, plan, path, ROBOT, rate_hz=plan.rate_hz,
                     extra_meta={"truth": truth_meta(SIMULA_SEED, truth_file, args)})
        return path

    with ThreadPoolExecutor(max_workers=2) as pool:
        paths = list(pool.map(record, (2, 3)))
    traces = [load_trace(p) for p in paths]
    truth = truth_of(traces, info)
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
