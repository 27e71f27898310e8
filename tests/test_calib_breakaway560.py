"""Issue 30: the PUMA 560's breakaway ramps run to their end on a hidden truth (a heavy joint slides
degrees past its ramp's pose before the hold; the way back to the pose is a move, not a step that
trips R_REQVEL), and fit Table 4.5 within its tolerance. The campaign `calib record all --robot
puma560` on hidden truth 3 with simula seed 7 stopped here (joint 1: a 2.5 rad/s step against
2 rad/s). About two minutes of lockstep recording: `-m slow`."""
from __future__ import annotations

import numpy as np
import pytest

from rcci.calib.breakaway import TOLERANCE, fit_breakaway
from rcci.calib.breakaway_program import POSITIONS_DEG, breakaway_plans, run_breakaway
from rcci.calib.hidden_truth import write_hidden_truth
from rcci.calib.logs import load_traces
from rcci.calib.robot import robot_info
from rcci.calib.truth import truth_meta, truth_of

ROBOT, TRUTH_SEED, SIMULA_SEED = "puma560", 3, 7


@pytest.mark.slow
def test_puma560_breakaway_of_joint_1_runs_through_and_fits_table_4_5(tmp_path):
    from rci.simula.process import SimulaProcess

    truth_file = str(tmp_path / "truth.toml")
    data = write_hidden_truth(truth_file, ROBOT, TRUTH_SEED)
    info = robot_info(ROBOT)
    static = info.nominal["friction"]["static_pos"]["values"]
    (plan,) = breakaway_plans(static, info.drive.G, joints=[1])
    log = str(tmp_path / "breakaway-j1.rcilog")
    args = ["--params", truth_file]
    with SimulaProcess("-p", *args, robot=ROBOT, lockstep=True, seed=SIMULA_SEED) as sim:
        run_breakaway(sim.url, plan, log, ROBOT, extra_meta={"truth": truth_meta(SIMULA_SEED, truth_file, args)},
                      timeout=120.0)
    traces = load_traces([log])
    drive = info.drive.with_sigma(np.asarray(data["motors"]["torque_sensitivity"], dtype=float))  # the truth's
    (res,), points = fit_breakaway(traces, drive, lambda q: np.zeros(6))   # joint 1's axis is vertical
    assert len(points) == 2 * len(POSITIONS_DEG)                 # every ramp, both directions
    truth = truth_of(traces, info)
    for fit, key in ((res.plus, "static_pos"), (res.minus, "static_neg")):
        tv = float(getattr(truth, key)[0])
        assert abs(tv / static[0] - 1) > 0.05                     # not the data file's value
        assert abs(fit - tv) <= TOLERANCE[1] * tv, (key, fit, tv)
