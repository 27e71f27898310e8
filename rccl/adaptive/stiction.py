"""Static-friction correction of the force-servoed joints at rest (thesis 4.6): a dither at the servo rate.

Thesis 4.6: "to exert a desired torque when the joint is stationary, a correction equal to
the maximum static friction (Table 4.5) must be applied to permit torque transmission".
A force-servoed joint pressing on a stiff contact and at rest is stuck: any torque within
+-F_s of what holds it leaves it where it is, so the force held is wherever the joint
happened to stop (thesis 4.6, 5.5 (2)). The correction here is a square-wave dither added
to the joint's torque request (4.38): +A+ for ``half`` samples, then -A- for ``half``
samples, with A+- = F_C+- + D and D chosen so that both exceed the static friction of
Table 4.5 by ``MARGIN``. Every half period the joint breaks away and moves a little the
way the half pushes; with the net joint torque error b (requested minus held by the
contact), a push moves it by (A+- +- b - F_C+-) h^2 / I over its first servo tick, so
over a period it drifts by 2 (b - b*) h^2 / I, b* = ((A- - F_C-) - (A+ - F_C+)) / 2 = 0 by
the choice of A+-. The contact's torque error is driven to zero (to (k - 1)(F_C+ - F_C-)/2, k the
true/model Coulomb ratio: at most 0.018 N*m for joint 3, well inside Table 4.4), not just
to within the static band, and with half periods of a few milliseconds the motion per half period is a
few micrometres at the tool.

It needs the sample period to be short against the contact's own dynamics (tool and
fixture at 2e4 N/m through joint 3's 0.2 m lever and its 0.11 kg*m^2 of link and rotor
inertia in simula ring at ~14 Hz, a 74 ms period): with half periods longer than
``MAX_HALF_PERIOD`` each push swings the joint through a large part of a contact
oscillation and the dither becomes a limit cycle (measured: docs/adaptive.md). At such
rates (below 400 Hz) the dither is off and the joint keeps the Coulomb compensation of
4.27, sticking wherever it stops.
"""
from __future__ import annotations

import numpy as np

from .force import JointModel

# estimate: 2 ms half periods, two servo ticks of the joint controller's 1 kHz (Appendix C):
# a push must last at least a tick after the previous push's motion has been stopped by friction
HALF_PERIOD = 0.002
# measured on simula (docs/adaptive.md): 2 ms halves hold 10 N to +-0.03 N, 4 ms halves swing
# +-0.7 N (1 kHz) to +-2 N (250 Hz), 28 ms (36 Hz) a 0-15 N limit cycle; above 2.5 ms the dither is off
MAX_HALF_PERIOD = 0.0025
# estimate: 1.25 x Table 4.5 covers a cold joint's 20 % friction excess (4.5.3) with 5 % to spare
MARGIN = 1.25
# estimate: above 0.02 rad/s (4 mm/s at a 0.2 m lever) the joint is sliding, not dithering
# (one dither push moves it by ~1e-5 rad per 2 ms, ~0.005 rad/s)
MOVING_SPEED = 0.02


class Dither:
    """Square-wave static-friction correction for a control of period ``dt`` s; ``model`` the controller's joints.

    ``correction(j, qd_j, qd_path_j, t_a_j)`` is called once per sample for each
    force-servoed joint j: the friction term (N*m, joint level) that replaces the Coulomb
    compensation of 4.27, or None when the joint should keep that compensation (it slides,
    the path moves it, or the sample rate is too low to dither).

    ``half_period`` and ``max_half_period`` (s) override the estimates above (the
    measurements of docs/adaptive.md vary them). ``mode="breakaway"`` is the thesis's
    sentence read literally, for comparison: at rest, +-A (the Table 4.5 value with
    ``MARGIN``) in the direction of the requested torque t_a_j, at any sample rate.
    """

    MODES = ("dither", "breakaway")

    def __init__(self, model: JointModel, dt: float, *, half_period: float = HALF_PERIOD,
                 max_half_period: float = MAX_HALF_PERIOD, mode: str = "dither") -> None:
        if mode not in self.MODES:
            raise ValueError(f"static-friction correction mode {mode!r} is not one of {self.MODES}")
        self.dt = float(dt)
        self.mode = mode
        self.half = max(1, int(round(half_period / self.dt)))
        self.enabled = mode == "breakaway" or self.half * self.dt <= max_half_period * (1 + 1e-9)
        fs = MARGIN * np.maximum(model.static_pos, model.static_neg)
        d = np.maximum(fs - np.minimum(model.coulomb_pos, model.coulomb_neg), 0.0)
        self.amp_pos = (model.coulomb_pos + d).tolist()       # A+ (N*m)
        self.amp_neg = (model.coulomb_neg + d).tolist()       # A- (N*m)
        self.rest_speed = 1e-3
        self._k = 0                                           # sample counter of the square wave
        self.active: set[int] = set()                         # joints corrected in the last sample

    def tick(self) -> None:
        """Advance the square wave by one sample (once per control cycle)."""
        self._k += 1

    def sign(self) -> float:
        """+1 in the pushing-positive half of the period, -1 in the other."""
        return 1.0 if (self._k // self.half) % 2 == 0 else -1.0

    def correction(self, j: int, qd_j: float, qd_path_j: float, t_a_j: float = 0.0) -> float | None:
        """The static-friction correction of joint j this sample (N*m), or None (keep 4.27's Coulomb term)."""
        if not self.enabled or abs(qd_j) > MOVING_SPEED or abs(qd_path_j) > self.rest_speed:
            self.active.discard(j)
            return None
        self.active.add(j)
        sign = self.sign() if self.mode == "dither" else (1.0 if t_a_j >= 0.0 else -1.0)
        return self.amp_pos[j] if sign > 0 else -self.amp_neg[j]
