"""Runtime of a redundant 7-joint arm's closed-form inverse kinematics (q7 the free parameter).

The generated module (``rccl/kinematics/<robot>_ik.py``, derive.redundant_kernels) holds the
straight-line kernels; this module gives the contract's entries for a redundant arm:

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
from rccl.kinematics.runtime import SAME_SOLUTION_TOL, Robot, SignedConfig, _fmt_pose, _wrap

#: largest |fk(q) - T| element (m for the position, 1 for the rotation) a returned solution may have
REPRODUCE_TOL = 1e-9
#: slack (rad) on the joint ranges for rounding at a range's end
RANGE_TOL = 1e-12
_SINGULAR = "Singular"


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


class RedundantRobot(Robot):
    """The generated kernels of one redundant arm with the checks of the module doc."""

    def __init__(self, name: str, kernels, lower, upper):
        super().__init__(name, kernels, ("revolute",) * 7, lower, upper, RedundantConfig, ())

    def _find_ik_all(self):
        from rccl.kinematics import backend

        n_cfg, n_guard = len(RedundantConfig.all()), len(self.kernels["ik"].guards)
        return backend.kernel(self.name, "ik_all", ((4, 4), ()), ((n_cfg, 7), (n_cfg, n_guard)))

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

    def _reproduces(self, q: np.ndarray, t: np.ndarray, context) -> None:
        """Raise KinematicsError unless fk(q) equals t within REPRODUCE_TOL (q (..., 7), t (..., 4, 4))."""
        (tq,), _, _ = self.raw("fk", q)
        err = np.abs(np.asarray(tq)[..., :3, :] - t[..., :3, :]).reshape(q.shape[:-1] + (12,)).max(axis=-1)
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
        configs = RedundantConfig.all()
        k = self.kernels["ik"]
        with np.errstate(all="ignore"):
            if self.ik_all_kernel is not None:
                q_all, g_all = self.ik_all_kernel(t3, v1)[:2]
            else:
                (q_all, g_all), _, _ = self.raw("ik_all", t3, v1)
        q_all, g_all = np.array(q_all), np.asarray(g_all)
        ok = (g_all >= 0).all(axis=-1) & np.isfinite(q_all).all(axis=-1)
        singular = [i for i, g in enumerate(k.guards) if g.error == _SINGULAR]
        reach = [i for i, g in enumerate(k.guards) if g.error != _SINGULAR]
        reachable = (g_all[..., reach] >= 0).all(axis=-1)
        for i, j in zip(*np.nonzero(~ok & reachable)):  # a reachable branch failing a Singular guard
            self.ik(t3[i], configs[j], q7=v1[i])  # raises Singular with the message
        q_all, in_range = self._in_range(q_all, None if ref2 is None else ref2[:, None, :])
        ok &= in_range
        if ok.any():
            self._reproduces(q_all[ok], np.broadcast_to(t3[:, None], q_all.shape[:2] + (4, 4))[ok],
                             lambda i: "in ik_all")
        out = []
        for i in range(t3.shape[0]):
            kept: list[int] = []
            for j in np.nonzero(ok[i])[0]:
                d = _wrap(q_all[i, kept] - q_all[i, j])
                if not np.any(np.all(np.abs(d) < SAME_SOLUTION_TOL, axis=-1)):
                    kept.append(int(j))
            out.append([(configs[j], q_all[i, j].copy()) for j in kept])
        return out if batch else out[0]
