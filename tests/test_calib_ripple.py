"""simula's servo ripple as the friction fits rely on it: large from tick to tick, but
averaged out by the current-sense filter (thesis 4.5.1, Appendix C, 4.5.3)."""
from __future__ import annotations

import numpy as np

from rcci.models import load_robot
from rci.simula.arm import SimulatedArm
from rci.simula.params import truth_from_model


def _held_arm() -> SimulatedArm:
    model = load_robot("puma260")
    arm = SimulatedArm(model, truth_from_model(model), seed=7, start="ready")
    arm.power = True
    arm.step(0.2)                       # let the 15 ms filter settle on the holding current
    return arm


def test_filtered_current_averages_to_the_true_current():
    arm = _held_arm()
    raw, filt, true = [], [], []
    for _ in range(1000):               # one second of 1 ms servo ticks
        arm.step(0.001)
        filt.append(arm.filtered.copy())
        true.append(arm.current.copy())
    filt, true = np.array(filt), np.array(true)
    i = 1                               # joint 2 holds the arm against gravity: about 1 A
    assert abs(true[:, i].mean()) > 0.3
    # white ripple of this size would leave about 0.9 % on a one-second mean
    assert abs(filt[:, i].mean() / true[:, i].mean() - 1) < 1e-3
    # yet each reading still carries some ripple (the filter does not remove it all)
    assert filt[:, i].std() > 1e-3 * abs(true[:, i].mean())
