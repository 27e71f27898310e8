"""rcci.calib.paths: a path kept within every joint's velocity limit (a move whose largest change
is in radians can drive a slide, in metres, past its limit: the Stanford arm's and the Microbo's
breakaway ramps stopped on R_REQVEL before Path.within)."""
from __future__ import annotations

import numpy as np

from rcci.calib.paths import Path, PathSegment


def _peak_speeds(path: Path, rate: float = 1000.0) -> np.ndarray:
    return np.max(np.abs(np.diff(path.sample(rate), axis=0)), axis=0) * rate


def test_within_caps_the_joint_nearest_its_limit_and_leaves_the_rest() -> None:
    start = np.array([0.0, 0.0, 0.3, 0.0])
    end = np.array([1.0, -0.5, 1.2, 0.0])              # joint 3 a slide: 0.9 m against 1 rad
    vmax = np.array([2.0, 2.0, 0.5, 2.0])
    raw = Path((PathSegment(start, end, 0.6, 1.5, 0.1),))
    assert _peak_speeds(raw)[2] > 0.5                       # 0.54 m/s: past the slide's limit
    capped = raw.within(vmax)
    peak = _peak_speeds(capped)
    assert np.all(peak <= 0.8 * vmax + 1e-6) and peak[2] >= 0.8 * 0.5 - 0.01
    np.testing.assert_allclose(capped.sample(1000.0)[-1], end)
    slow = Path((PathSegment(start, end, 0.3, 1.5, 0.1),))
    assert slow.within(vmax).segments == slow.segments       # already within: unchanged


def test_breakaway_moves_of_an_arm_with_a_slide_stay_within_its_limits() -> None:
    """Every step of the Stanford arm's joint-3 ramps (before the ramps themselves) within 0.8 x limits."""
    from rcci.calib.breakaway_program import _sweep
    from rcci.models import load_robot

    m = load_robot("stanford")
    vmax = np.asarray(m.max_velocity, float)
    q = 0.5 * (np.asarray(m.lower) + np.asarray(m.upper))
    sp = _sweep(q, 2, 0.1, 6.0, 500, vmax)
    assert np.max(np.abs(np.diff(sp[:, 2]))) * 500 <= 0.8 * vmax[2] + 1e-6
