"""The force held at rest along a compliant axis (thesis 4.6 static-friction correction), on simula in lockstep.

Each case presses a probe on a table with ``comply("fz", F)`` and stands still; simula's
own contact model (control channel ``state``) gives the true force, which must lie within
Table 4.4's Coulomb-friction uncertainty of the force-servoed joint mapped through its
lever (``ForceEstimator.force_bound``), over every snapshot taken at rest.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pinocchio")
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "examples"))

from adaptive_sim import environment_simula           # noqa: E402
from rccl.adaptive.force import ForceEstimator, JointModel  # noqa: E402
from rccl.adaptive.stiction import MARGIN, Dither     # noqa: E402
from rccl.kinematics import puma260 as kin            # noqa: E402
from rccl.transform import trsl                       # noqa: E402

MODEL = JointModel.for_robot("puma260")


def _press(seed: int, dx: float, force: float, warm: bool, rate: int = 500):
    import adaptive_press as g

    args = ("-p", "--power-on") + (("--warm",) if warm else ())
    with environment_simula(*g.ENV, seed=seed, args=args) as sim:
        arm, truth = g.main(sim.url, force=force, dx=dx, rate=rate, hold=1.5,
                            state=lambda: sim.command("state")["state"])
    return g, arm, truth


def _band(joint: int, q: np.ndarray, probe: float) -> float:
    err = np.where(np.arange(6) == joint, MODEL.coulomb_uncertainty(), 0.0)
    return float(ForceEstimator(kin, MODEL).force_bound(kin.jacobian6(q), trsl(0, 0, probe), err)[2])


CASES = [  # seed, dx (m), force (N), warm joints
    (0, 0.0, 10.0, True),
    (3, 0.02, 5.0, False),
    (1, -0.02, 15.0, True),
]
SLOW_CASES = [(s, dx, f, w) for s in (2, 4) for dx, f, w in ((0.0, 10.0, False), (0.03, 8.0, True), (-0.03, 12.0, True))]


def _check(seed, dx, force, warm):
    g, arm, truth = _press(seed, dx, force, warm)
    joints = {j for x in arm.adaptive_trace for j in x[4]}
    assert len(joints) == 1
    joint = joints.pop()
    assert arm.adaptive.dither.enabled and joint in arm.adaptive.dither.active   # corrected, at rest
    held = np.array([s["contact_force"][2] for s in truth])
    q = np.array(truth[-1]["q"])
    assert np.ptp([s["q"][joint] for s in truth]) < 2e-4          # at rest: 40 um at the tool at most
    band = _band(joint, q, g.PROBE)
    assert 0.3 < band < 1.0                                        # Table 4.4 through a ~0.2 m lever
    assert np.all(np.abs(held - force) <= band), (held.min(), held.max(), force, band)
    return held, band


@pytest.mark.parametrize("seed,dx,force,warm", CASES)
def test_force_held_at_rest_is_within_the_table_4_4_band(seed, dx, force, warm):
    _check(seed, dx, force, warm)


@pytest.mark.slow
@pytest.mark.parametrize("seed,dx,force,warm", SLOW_CASES)
def test_force_held_at_rest_more_seeds_and_positions(seed, dx, force, warm):
    _check(seed, dx, force, warm)


def test_dither_amplitudes_break_static_friction_and_cancel_the_coulomb_asymmetry():
    d = Dither(MODEL, 1 / 500)
    a_pos, a_neg = np.array(d.amp_pos), np.array(d.amp_neg)
    assert np.all(a_pos >= MARGIN * MODEL.static_pos - 1e-12) and np.all(a_neg >= MARGIN * MODEL.static_neg - 1e-12)
    # equal excess over Coulomb friction both ways: the dither's drift has no bias of its own
    np.testing.assert_allclose(a_pos - MODEL.coulomb_pos, a_neg - MODEL.coulomb_neg)
    assert d.enabled and d.half == 1
    signs = []
    for _ in range(6):
        d.tick()
        signs.append(d.correction(2, 0.0, 0.0) > 0)
    assert signs == [False, True, False, True, False, True]
    assert d.correction(2, 0.05, 0.0) is None and 2 not in d.active      # sliding: Coulomb term
    assert d.correction(2, 0.0, 0.01) is None                             # the path moves it
    d1k = Dither(MODEL, 1 / 1000)
    assert d1k.enabled and d1k.half == 2
    assert not Dither(MODEL, 1 / 36).enabled and not Dither(MODEL, 1 / 250).enabled
    assert Dither(MODEL, 1 / 36).correction(2, 0.0, 0.0) is None
    forced = Dither(MODEL, 1 / 36, max_half_period=1.0)             # what the measurements force on
    assert forced.enabled and forced.half == 1
    lit = Dither(MODEL, 1 / 36, mode="breakaway")                  # 4.6 read literally
    assert lit.correction(2, 0.0, 0.0, 1.5) == d.amp_pos[2] and lit.correction(2, 0.0, 0.0, -1.5) == -d.amp_neg[2]
    with pytest.raises(ValueError, match="mode"):
        Dither(MODEL, 1 / 500, mode="wiggle")
