"""bench.condition (reports/condition.md): thesis 4.7's condition number and 4.53-4.55, recomputed."""
from __future__ import annotations

import numpy as np

import rccl.kinematics.puma260 as kin
from bench.condition import force_limit_rows, frame_jacobians, render, scaled


def test_frames_0_4_6_share_the_condition_number_at_every_length_scale():
    q = np.random.default_rng(3).uniform(kin.LOWER, kin.UPPER, size=(200, 6))
    jacs = frame_jacobians(q)
    for length in (1.0, 0.12, 0.001):
        c = [np.linalg.cond(scaled(j, length)) for j in jacs.values()]
        assert np.allclose(c[0], c[1], rtol=1e-8) and np.allclose(c[0], c[2], rtol=1e-8)


def test_the_report_reproduces_4_5_newtons_and_not_1_8():
    text = render(2000, 0, "python -m bench.condition --samples 2000")
    assert "smallest condition number **2.293**" in text          # the 3x3 arm block
    assert "= **4.48 N**" in text                                  # section 6.2's "about 4.5 Newtons"
    best = float(text.split("Refined from the best sampled pose")[1].split("**")[1])
    assert 3.3 < best < 3.5                                        # the 6x6 at its best length scale


def test_the_force_limit_readings():
    fx, fy = force_limit_rows()
    assert fx.endswith("| (1, 0) F_l | 1.50 | 1.50 |")            # the print's t_l; y alone crosses it
    assert fy.endswith("| (1, 1) F_l | 0.75 | 1.50 |")
