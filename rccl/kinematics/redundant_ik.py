"""Runtime of a redundant 7-joint arm's closed-form inverse kinematics (q7 the free parameter).

The arm's generated module (``rccl/kinematics/<robot>.py``, ``python -m derive``: the kernels of
derive.inverse_redundant beside fk, Jacobians and dynamics) holds the straight-line kernels;
this module gives the contract's entries for a redundant arm (the compiled fast entries of
``ik``/``ik_all``, _c/kin_redundant.h, do the same checks in C and call these for the rest):

* ``ik(T, config, q_ref=None, q7=...)``: q (7,) for the flange pose T (4, 4), the value of
  joint 7 (rad) and a :class:`RedundantConfig`; a batch of poses (N, 4, 4) with q7 a float
  or (N,) gives (N, 7);
* ``ik_all(T, q7, q_ref=None)``: every distinct solution within the joint ranges, a list of
  (RedundantConfig, q) (a list of such lists for a batch);
* ``config_of(q)``.

Every returned solution lies in the joint ranges (the 2 pi branch of each joint is the
one inside its range, or the nearest to q_ref among those) and reproduces T: fk of it is
checked against T within ``REPRODUCE_TOL``. Unreachable poses (or a q7 outside joint 7's
range, or solutions only outside the ranges) raise ``exceptions.Unreachable``, singular
ones ``exceptions.Singular``, each naming the pose, q7 and the reason.
"""
from __future__ import annotations

from dataclasses import dataclass
import numpy as np

from rccl.kinematics import exceptions
from rccl.kinematics.runtime import RIGID_TOL, SAME_SOLUTION_TOL, Robot, SignedConfig

#: largest |fk(q) - T| element (m for the position, 1 for the rotation) a returned solution may have
REPRODUCE_TOL = 1e-9
#: slack (rad) on the joint ranges for rounding at a range's end
RANGE_TOL = 1e-12
_SINGULAR = "Singular"


def _wrap(x: np.ndarray) -> np.ndarray:
    """Angles (rad) into [-pi, pi)."""
    return (x + np.pi) % (2 * np.pi) - np.pi


def _fmt_pose(t: np.ndarray) -> str:
    return np.array2string(np.asarray(t), precision=6, suppress_small=True, separator=", ").replace("\n", "")


@dataclass(frozen=True)
class RedundantConfig(SignedConfig):
    """Configuration of the redundant class (derive.inverse_redundant): shoulder +1 / -1 the
    sign of sin q2; elbow +1 / -1 which of the two elbow angles q4 giving the shoulder-wrist
    distance; wrist +1 / -1 which of the two q6 putting the shoulder point at the height q4
    needs along the joint-5 axis."""

    LABELS = (("shoulder+", "shoulder-"), ("elbow+", "elbow-"), ("wrist+", "wrist-"))
    shoulder: int = 1
    elbow: int = 1
    wrist: int = 1


#: every configuration, in the order of the ik_all kernel's rows
_CONFIGS = RedundantConfig.all()


class RedundantRobot(Robot):
    """The generated kernels of one redundant arm with the checks of the module doc."""

    def __init__(self, name: str, kernels, kinds, lower, upper, config_type: type = RedundantConfig,
                 coeff_names=()):
        if tuple(kinds) != ("revolute",) * 7 or config_type is not RedundantConfig:
            raise exceptions.InvalidInput(f"{name}: the redundant inverse needs 7 revolute joints and "
                                          f"RedundantConfig, got {tuple(kinds)} and {config_type.__name__}")
        super().__init__(name, kernels, kinds, lower, upper, config_type, coeff_names)

    def _find_ik_all(self):
        from rccl.kinematics import backend

        n_cfg, n_guard = len(RedundantConfig.all()), len(self.kernels["ik"].guards)
        return backend.kernel(self.name, "ik_all", ((4, 4), ()), ((n_cfg, 7), (n_cfg, n_guard)))

    def public_entries(self) -> dict:
        """ik, ik_all and config_of as the contract's public functions: ik and ik_all the
        compiled fast entries (rccl/kinematics/_c/kin_redundant.h: the same checks in C, this
        class's methods behind them for every other call and every error) when the module's
        C kernels are built, else these methods."""
        from rccl.kinematics import backend

        singular = tuple(g.error == _SINGULAR for g in self.kernels["ik"].guards)
        return backend.public_redundant_ik(
            self.name, {"ik": self.ik, "ik_all": self.ik_all, "config_of": self.config_of}, self.kernels,
            self.config_type, self.lower, self.upper, singular,
            (RIGID_TOL, SAME_SOLUTION_TOL, RANGE_TOL, REPRODUCE_TOL))

    def _every_config(self, t3: np.ndarray, v1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(q (N, 8, 7), guards (N, 8, n_guard)) of every configuration: the compiled ik_all
        kernel, or the ik kernel once per configuration (the Python kernels)."""
        if self.ik_all_kernel is not None:
            q_all, g_all = self.ik_all_kernel(t3, v1)[:2]
            return np.array(q_all), np.asarray(g_all)
        qs, gs = [], []
        for cfg in _CONFIGS:
            signs = np.broadcast_to(np.array(cfg.signs, dtype=float), (t3.shape[0], 3))
            (q,), guards, _ = self.raw("ik", t3, v1, signs)
            qs.append(np.asarray(q))
            gs.append(np.stack([np.asarray(g) for g in guards], axis=-1))
        return np.stack(qs, axis=1), np.stack(gs, axis=1)

    def _free(self, q7, t: np.ndarray, where: str) -> np.ndarray:
        try:
            v = np.asarray(q7, dtype=float)
        except (TypeError, ValueError):
            raise exceptions.InvalidInput(f"{self.name}.{where}: q7 (joint 7, rad) must be a number, "
                                          f"got {q7!r}") from None
        want = t.shape[:-2]
        if v.shape not in ((), want) or not np.isfinite(v).all():
            raise exceptions.InvalidInput(f"{self.name}.{where}: q7 (joint 7, rad) must be finite, a float "
                                          f"or shape {want}, got {q7!r}")
        lo, hi = self.lower[6], self.upper[6]
        bad = (v < lo - RANGE_TOL) | (v > hi + RANGE_TOL)
        if np.any(bad):
            x = float(np.atleast_1d(v)[int(np.argmax(np.atleast_1d(bad)))])
            raise exceptions.Unreachable(f"{self.name}.{where}: q7 = {x:.6g} rad is outside joint 7's range "
                                         f"[{lo:.6g}, {hi:.6g}] rad")
        return np.broadcast_to(v, want).copy() if want else v

    def _ref(self, q_ref, t: np.ndarray, where: str) -> np.ndarray | None:
        if q_ref is None:
            return None
        ref = np.asarray(q_ref, dtype=float)
        if ref.shape != t.shape[:-2] + (7,) or not np.isfinite(ref).all():
            raise exceptions.InvalidInput(f"{self.name}.{where}: q_ref must be finite with shape "
                                          f"{t.shape[:-2] + (7,)}, got {ref.shape}")
        return ref

    def _in_range(self, q: np.ndarray, ref: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """(q moved to its 2 pi branch in range, or nearest ref among those; in range per row)."""
        lo, hi = self.lower, self.upper
        if ref is not None:
            q = ref + _wrap(q - ref)
        q = np.where(q < lo - RANGE_TOL, q + 2 * np.pi, q)
        q = np.where(q > hi + RANGE_TOL, q - 2 * np.pi, q)
        ok = np.all((q >= lo - RANGE_TOL) & (q <= hi + RANGE_TOL), axis=-1)
        return q, ok

    def _misses(self, q: np.ndarray, t: np.ndarray) -> np.ndarray:
        """The largest element of |fk(q) - t| (rotation and position rows), per solution; NaN where q is not finite."""
        with np.errstate(all="ignore"):
            tq = self.kernels["fk"].many(q if q.ndim == 2 else q[None])[0]  # q finite: from a checked solve
        tq = tq if q.ndim == 2 else tq[0]
        return np.abs(np.asarray(tq)[..., :3, :] - t[..., :3, :]).reshape(q.shape[:-1] + (12,)).max(axis=-1)

    def _reproduces(self, q: np.ndarray, t: np.ndarray, context) -> None:
        """Raise KinematicsError unless fk(q) equals t within REPRODUCE_TOL (q (..., 7), t (..., 4, 4))."""
        err = self._misses(q, t)
        if np.any(~(err <= REPRODUCE_TOL)):
            i = int(np.argmax(np.atleast_1d(~(err <= REPRODUCE_TOL))))
            raise exceptions.KinematicsError(f"{self.name}: a solution misses the pose by "
                                             f"{float(np.atleast_1d(err)[i]):.3g}; {context(None if q.ndim == 1 else i)}")

    def ik(self, T, config, q_ref=None, q7=None):
        """q (7,) for the flange pose T, joint 7 = q7 (rad) and ``config``; see the module doc."""
        if q7 is None:
            raise exceptions.InvalidInput(f"{self.name}.ik: a redundant arm needs the free value: "
                                          "ik(T, config, q7=...) with q7 the angle of joint 7 (rad)")
        t = self._pose(T)
        v = self._free(q7, t, "ik")
        ref = self._ref(q_ref, t, "ik")
        cfg = self.coerce_config(config)
        batch = t.ndim == 3
        signs = np.array(cfg.signs, dtype=float)
        if batch:
            signs = np.broadcast_to(signs, (t.shape[0], 3))

        def context(i):
            pose, x = (t, v) if i is None else (t[i], v[i])
            row = "" if i is None else f"batch row {i}: "
            return f"{row}pose T = {_fmt_pose(pose)}, q7 = {float(x):.6g}, configuration {cfg}"

        (q,), guards, _ = self.raw("ik", t, v, signs)
        self._check("ik", guards, batch, (t,), context)
        q, ok = self._in_range(np.array(q), ref)
        if not np.all(ok):
            i = None if not batch else int(np.argmax(~ok))
            row = q if i is None else q[i]
            j = int(np.argmax((row < self.lower - RANGE_TOL) | (row > self.upper + RANGE_TOL)))
            raise exceptions.Unreachable(
                f"{self.name}.ik: joint {j + 1} would need {row[j]:.6g} rad, outside its range "
                f"[{self.lower[j]:.6g}, {self.upper[j]:.6g}] rad; {context(i)}")
        self._finite("ik", (q,), batch, (t,), context)
        self._reproduces(q, t, context)
        return q

    def ik_all(self, T, q7, q_ref=None):
        """Every distinct solution in the joint ranges for pose T and joint 7 = q7 (rad)."""
        t = self._pose(T)
        v = self._free(q7, t, "ik_all")
        ref = self._ref(q_ref, t, "ik_all")
        batch = t.ndim == 3
        t3, v1 = (t, v) if batch else (t[None], v[None])
        ref2 = None if ref is None else (ref if batch else ref[None])
        configs = _CONFIGS
        with np.errstate(all="ignore"):
            q_all, g_all = self._every_config(t3, v1)
            ok = (g_all >= 0).all(axis=-1) & np.isfinite(q_all).all(axis=-1)
            if not ok.all():
                reach = [i for i, g in enumerate(self.kernels["ik"].guards) if g.error != _SINGULAR]
                for i, j in zip(*np.nonzero(~ok & (g_all[..., reach] >= 0).all(axis=-1))):
                    self.ik(t3[i], configs[j], q7=v1[i])  # reachable but singular: raises Singular
        q_all, in_range = self._in_range(q_all, None if ref2 is None else ref2[:, None, :])
        ok &= in_range
        if ok.any():
            # a branch that does not reproduce T within REPRODUCE_TOL (round-off where two branches
            # meet, near a singular configuration) is left out: every solution returned reproduces T
            ok[ok] = self._misses(q_all[ok], np.broadcast_to(t3[:, None], q_all.shape[:2] + (4, 4))[ok]) <= REPRODUCE_TOL
        # equal solutions (2 pi apart on a joint) kept once: pairwise over the configurations
        same = (np.abs(_wrap(q_all[:, :, None, :] - q_all[:, None, :, :])) < SAME_SOLUTION_TOL).all(axis=-1)
        out = []
        for ok_i, same_i, q_i in zip(ok.tolist(), same.tolist(), q_all):
            kept: list[int] = []
            for j in range(len(configs)):
                if ok_i[j] and not any(same_i[j][k] for k in kept):
                    kept.append(j)
            out.append([(configs[j], q_i[j].copy()) for j in kept])
        return out if batch else out[0]
