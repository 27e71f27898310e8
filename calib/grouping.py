"""Columns of the dynamics fit that no motion separates from others, folded into them: the
base-parameter grouping of the rigid body (derive.dynamics_base) carried on to the friction and
rotor columns that calib fits beside it.

The generated base regressor is minimal for the rigid body with its rotors, but calib adds the
friction of eq. 4.27 per direction, and a joint's per-direction Coulomb pair adds up to a
constant force on that joint whenever it moves. A joint that carries a constant load has that
constant in its rigid-body columns too: the Microbo's vertical slide (joint 2) carries the weight
of everything above it, (M2 + M3R)(qdd2 + g) in its equation, which is its rotor column IA2
(qdd2) plus g times its Coulomb pair. No motion separates that part, so in joint 2's equation it
moves into joint 2's own drive columns, as the derivation folds IA1 into ZZ1R::

    IA2R = IA2 + M2 + M3R,   FC2+R = FC2+ + g (M2 + M3R),   FC2-R = FC2- - g (M2 + M3R)

M2, which appears in no other equation, is left with no column and goes; M3R keeps its name and
value and is identified from the radial slide's and the base's equations (joints 3 and 1), where
its column is the same as before. The rule, per joint j and rigid-body column c: when c's part in
joint j's equation is exactly (to 1e-9, on random moving states) a combination of joint j's
rotor and friction columns, that part moves into them (signs and factors found, not assumed).
The grouped values are what the arm's currents determine; splitting them again needs a value
from elsewhere (rccl.feedforward takes an eliminated parameter from the data file, and says so).

The equations the fit leaves out (rcci.calib.unmeasured: the Microbo's slides, for the
thesis's reason) take no part: their columns are masked, and a parameter left in no equation
the fit uses is eliminated as not identified (the Microbo: M2, its slides' rotor and friction
terms). So on the shipped arms nothing is folded today; the rule is there for an arm whose
vertical slide's torque is measured (a SCARA's quill, or the Microbo with its slides fitted:
tests/test_calib_grouping.py).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import numpy as np

from rcci.calib.exceptions import CalibError

NULL_RTOL = 1e-9        # singular value / largest (unit columns) under which columns are dependent
EXACT_RTOL = 1e-9       # a folded column must be its combination to this share of its norm
SAMPLES = 400           # random moving states the dependence is found on


@dataclass(frozen=True)
class Grouping:
    """How the fit's full column set (``full``) folds into the one it identifies (``names``):
    grouped values = ``K`` @ full values; ``keep`` the indices of ``full`` that stay columns."""

    full: tuple[str, ...]
    keep: tuple[int, ...]
    names: tuple[str, ...]
    K: np.ndarray                 # (len(names), len(full))
    eliminated: tuple[str, ...]
    mask: np.ndarray              # (n joints, len(full)): 0 where a column's part in that joint's equation moved

    def columns(self, Y: np.ndarray) -> np.ndarray:
        """The fit's regressor (..., n, len(names)) from the full one (..., n, len(full))."""
        return (Y * self.mask)[..., list(self.keep)]

    def parts(self) -> dict[str, dict[str, float]]:
        """Each grouped column's make-up: name -> {full name: coefficient} (only columns that took
        others in)."""
        out = {}
        for i, name in enumerate(self.names):
            nz = np.flatnonzero(self.K[i])
            if len(nz) > 1:       # its own column first, then what it took in
                own = self.keep[i]
                out[name] = {self.full[k]: float(self.K[i, k]) for k in sorted(nz, key=lambda k: (k != own, k))}
        return out

    def as_section(self) -> dict:
        """The keys of a parameter file's ``[dynamics]`` that say how its values are grouped
        (none when nothing is): ``not_identified`` (parameters in no equation the fit uses),
        ``grouped`` (names), ``grouped_of`` (the full names each is made of, its own first),
        ``grouped_coefficients``, ``grouped_formulas`` (in words)."""
        parts = self.parts()
        out: dict = {}
        lone = [e for e in self.eliminated if not any(e in p for p in parts.values())]
        if lone:          # in no equation the fit uses (rcci.calib.unmeasured)
            out["not_identified"] = lone
        if parts:
            out.update({"grouped": list(parts), "grouped_of": [list(p) for p in parts.values()],
                        "grouped_coefficients": [list(p.values()) for p in parts.values()],
                        "grouped_formulas": self.formulas()})
        return out

    def formulas(self) -> list[str]:
        """The grouped columns in words, e.g. ``FC2+R = FC2+ + 9.80665 M2``."""
        lines = []
        for name, part in self.parts().items():
            terms = []
            for k, (full_name, c) in enumerate(part.items()):
                mag = "" if abs(abs(c) - 1.0) < 1e-12 else f"{abs(c):.6g} "
                sign = "-" if c < 0 else "+"
                terms.append(f"{'- ' if c < 0 else ''}{mag}{full_name}" if k == 0 else f"{sign} {mag}{full_name}")
            lines.append(f"{name} = {' '.join(terms)}")
        return lines


def random_states(n: int, lower: np.ndarray, upper: np.ndarray, samples: int = SAMPLES, seed: int = 0):
    """``samples`` random moving states: q inside the ranges, every |qd| in [0.2, 1] (both
    signs: the friction columns need the joint moving), qdd normal."""
    rng = np.random.default_rng(seed)
    q = rng.uniform(lower, upper, (samples, n))
    qd = rng.choice((-1.0, 1.0), q.shape) * rng.uniform(0.2, 1.0, q.shape)
    return q, qd, rng.normal(size=q.shape)


def drive_columns(full: tuple[str, ...], joint: int) -> list[int]:
    """Indices in ``full`` of joint ``joint``'s (0-based) own drive terms: its rotor inertia
    ``IA<j>`` and friction ``FC<j>+-``, ``FV<j>+-``: columns of its equation only."""
    j = joint + 1
    own = {f"IA{j}", f"FC{j}+", f"FC{j}-", f"FV{j}+", f"FV{j}-"}
    return [k for k, name in enumerate(full) if name in own]


@cache
def grouping(robot: str) -> Grouping:
    """The fit's grouping for ``robot`` (module docstring), in two steps: (1) in each joint's
    equation, the part of a rigid-body column that is exactly a combination of that joint's own
    drive columns (:func:`drive_columns`) moves into them, and a column left in no equation the
    fit uses is eliminated; (2) while the remaining columns are exactly dependent (a null vector
    on random moving states), the rigid-body column that weighs most in it is folded into the
    others of the null vector (the Microbo without its slides' equations: MZ3R into M3R and
    ZZ1R, which joint 1's equation alone cannot tell apart). A dependence among friction and rotor
    columns alone is left for rcci.calib.identification.identifiable to refuse."""
    import rccl.kinematics as kinematics
    from rcci.calib.regressor import fitted_joints, full_column_names, full_regressor_columns
    from rcci.models import load_robot

    m = load_robot(robot)
    full = full_column_names(robot)
    n, P = len(m.lower), len(full)
    q, qd, qdd = random_states(n, np.asarray(m.lower, float), np.asarray(m.upper, float))
    Y = full_regressor_columns(robot, q, qd, qdd)                 # (N, n, P)
    K = np.eye(P)
    mask = np.ones((n, P))
    used = fitted_joints(robot)
    mask[[j for j in range(n) if j not in used]] = 0.0      # equations the fit leaves out
    for j in used:
        _fold_into_drive(Y, full, n, j, K, mask)
    A = (Y * mask[None]).reshape(-1, P)
    left = np.linalg.norm(A, axis=0)
    keep = [k for k in range(P) if left[k] > 0 or not np.any(Y[:, :, k])]
    _fold_dependent(A, full, set(kinematics.load(robot).BASE_PARAMETERS), K, keep, robot)
    eliminated = tuple(full[k] for k in range(P) if k not in keep)
    names = tuple(full[k] + ("R" if np.count_nonzero(K[k]) > 1 else "") for k in keep)
    return Grouping(full, tuple(keep), names, K[keep], eliminated, mask)


def _fold_into_drive(Y: np.ndarray, full: tuple[str, ...], n: int, j: int, K: np.ndarray, mask: np.ndarray) -> None:
    """Step (1) of :func:`grouping` for joint ``j``'s equation (updates ``K`` and ``mask``)."""
    drive = drive_columns(full, j)
    every_drive = {c for i in range(n) for c in drive_columns(full, i)}
    D = Y[:, j, drive]
    for c in range(len(full)):
        part = Y[:, j, c]
        if c in every_drive or not np.any(part):
            continue
        a, *_ = np.linalg.lstsq(D, part, rcond=None)
        if np.linalg.norm(D @ a - part) > EXACT_RTOL * np.linalg.norm(part):
            continue
        for k, coef in zip(drive, np.round(a, 10)):   # x_k' = x_k + coef x_c: rows carrying c pass it on
            if coef != 0.0:
                K[k] += coef * K[c]
        mask[j, c] = 0.0


def _fold_dependent(A: np.ndarray, full: tuple[str, ...], rigid: set[str], K: np.ndarray, keep: list[int],
                    robot: str) -> None:
    """Step (2) of :func:`grouping` on the stacked regressor ``A`` (updates ``K`` and ``keep``)."""
    while True:
        sub = A[:, keep]
        nrm = np.linalg.norm(sub, axis=0)
        if np.any(nrm == 0):
            return
        s, Vt = np.linalg.svd(sub / nrm, full_matrices=False)[1:]
        if s[-1] > NULL_RTOL * s[0]:
            return
        v = np.abs(Vt[-1])
        candidates = [i for i in np.argsort(-v) if v[i] > 1e-6 and full[keep[i]] in rigid]
        if not candidates:
            return
        e = keep[candidates[0]]
        support = [keep[i] for i in np.flatnonzero(v > 1e-6) if keep[i] != e]
        a, *_ = np.linalg.lstsq(A[:, support], A[:, e], rcond=None)
        gap = np.linalg.norm(A[:, support] @ a - A[:, e])
        if gap > EXACT_RTOL * np.linalg.norm(A[:, e]):
            raise CalibError(f"robot {robot}: the fit's column {full[e]} depends on "
                             f"{', '.join(full[k] for k in support)} only approximately ({gap:.1e}): "
                             "no exact grouping")
        for k, coef in zip(support, np.round(a, 10)):
            if coef != 0.0:
                K[k] += coef * K[e]
        keep.remove(e)
