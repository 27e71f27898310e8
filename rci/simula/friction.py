"""Joint friction as the simulated arm feels it: eq. 4.27 plus the effects of thesis 4.5.3-4.5.5.

* Coulomb and viscous friction per direction (eq. 4.27, Tables 4.2 and 4.3);
* the Coulomb value varies along the joint's travel by up to the Table 4.4 fraction
  (a fixed, seeded pattern of a few spatial harmonics: gear irregularities);
* a joint that has been idle is "cold": all its friction is higher, by up to
  ``cold_excess`` (20 %, 4.5.3), and it warms up while it moves;
* at rest the joint sticks until the net torque exceeds the static friction F_s
  (Table 4.5), per direction;
* a position-servoed joint brought to a halt keeps a residual static friction drawn from
  the Table 4.6 distribution (mean, standard deviation), clipped to [-F_s-, F_s+].
"""
from __future__ import annotations

import numpy as np

from .params import Disturbances, Truth

# spatial frequencies (cycles per joint radian) of the variation pattern: high enough
# that a window of a few tens of degrees averages it out, as the thesis's path averages did
_HARMONICS = np.array([5.0, 11.0, 23.0, 41.0])


class FrictionState:
    """Friction state of all joints (vectorised over the joints)."""

    def __init__(self, truth: Truth, rng: np.random.Generator) -> None:
        self.truth = truth
        self.dist: Disturbances = truth.disturbances
        n = len(truth.sigma)
        self.rng = rng
        self.phase = rng.uniform(0, 2 * np.pi, size=(n, len(_HARMONICS)))
        w = rng.uniform(0.5, 1.0, size=(n, len(_HARMONICS)))
        self.weight = w / w.sum(axis=1, keepdims=True)      # |pattern| <= 1
        self.warmth = np.ones(n) if self.dist.start_warm else np.zeros(n)
        self._h, self._up, self._down = -1.0, 0.0, 0.0

    def pattern(self, q: np.ndarray) -> np.ndarray:
        """Position-dependent relative deviation of the Coulomb friction, in [-1, 1] per joint."""
        return np.einsum("ij,ij->i", self.weight, np.sin(q[:, None] * _HARMONICS + self.phase))

    def cold_factor(self) -> np.ndarray:
        """Multiplier of all friction terms: 1 + cold_excess (1 - warmth)."""
        return 1.0 + self.dist.cold_excess * (1.0 - self.warmth)

    def kinetic(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """Friction torque opposing motion at velocity qd (sign of qd), 0 where qd == 0."""
        t = self.truth
        vary = 1.0 + t.variation * self.pattern(q)
        pos = t.coulomb_pos * vary + t.viscous_pos * qd
        neg = -t.coulomb_neg * vary + t.viscous_neg * qd
        return self.cold_factor() * np.where(qd > 0, pos, np.where(qd < 0, neg, 0.0))

    def breakaway(self) -> tuple[np.ndarray, np.ndarray]:
        """Static friction limits (F_s+, F_s-) at the current temperature, magnitudes."""
        c = self.cold_factor()
        return c * self.truth.static_pos, c * self.truth.static_neg

    def sample_hold(self, joints: np.ndarray) -> np.ndarray:
        """Residual static friction for servo joints that just halted (Table 4.6), one per index."""
        t = self.truth
        x = t.hold_mean[joints] + t.hold_std[joints] * self.rng.standard_normal(len(joints))
        return np.clip(x, -t.static_neg[joints], t.static_pos[joints])

    def warm(self, moving: np.ndarray, h: float) -> None:
        """Advance the temperature state by h seconds (moving joints warm up, idle ones cool)."""
        if h != self._h:
            d = self.dist
            self._up = 1.0 - np.exp(-h / d.warmup_time) if d.warmup_time > 0 else 1.0
            self._down = 1.0 - np.exp(-h / d.cooldown_time) if d.cooldown_time > 0 else 1.0
            self._h = h
        up, down = self._up, self._down
        self.warmth = np.where(moving, self.warmth + up * (1.0 - self.warmth), self.warmth * (1.0 - down))
