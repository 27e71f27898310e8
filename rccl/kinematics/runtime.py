"""Hand-written runtime shared by the generated kinematics modules.

The generated modules (``puma260.py``, ``microbo.py``) hold straight-line kernels; this
module checks their inputs, dispatches one configuration or a batch, turns negative
guards into ``exceptions.Unreachable`` / ``exceptions.Singular`` naming the pose and the reason,
and implements the parts of the contract that are logic rather than algebra: the
configuration records, the wrist-singular fallback and 2 pi branch choice of ``ik``,
``ik_all`` and ``config_of``. ``public_api`` builds the contract's public functions of one
robot, which the generated module binds to its names: the compiled fast entries
(``rccl.kinematics.backend``) in front of the Python code here.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass, fields
from typing import Any, Callable, ClassVar, Mapping, NamedTuple, Sequence

import numpy as np

from rcci.models.kinematics import PUBLIC  # the contract's public functions, in binding order
from rccl.kinematics import exceptions
from rccl.kinematics.redundant import NoConfig  # noqa: F401  (a redundant arm's Config, before its solver)

#: two solutions closer than this (rad or m, per joint) are the same solution: at a
#: boundary (stretched elbow, arm on the d3 cylinder) the two branches meet through a
#: square root of a rounding-level radicand, so they differ by ~sqrt(eps) ~ 1e-8
SAME_SOLUTION_TOL = 1e-6
#: a pose whose rotation part deviates from orthonormal by more than this is rejected
RIGID_TOL = 1e-6


class SignedConfig:
    """What the configuration records share: fields that are each +1 or -1, in the order of
    the ``ik`` kernel's config input; ``LABELS`` names each field's +1 and -1 for printing."""

    LABELS: ClassVar[tuple[tuple[str, str], ...]] = ()

    def __post_init__(self) -> None:
        for f in fields(self):
            if getattr(self, f.name) not in (1, -1):
                raise exceptions.InvalidInput(f"{type(self).__name__}.{f.name} must be +1 or -1, "
                                              f"got {getattr(self, f.name)!r}")

    @property
    def signs(self) -> tuple[int, ...]:
        return tuple(getattr(self, f.name) for f in fields(self))

    @classmethod
    def all(cls) -> tuple[Any, ...]:
        """Every configuration, in ``itertools.product((1, -1), repeat=n)`` order."""
        return tuple(cls(*s) for s in itertools.product((1, -1), repeat=len(fields(cls))))

    def __str__(self) -> str:
        return "/".join(label[s < 0] for label, s in zip(self.LABELS, self.signs))


@dataclass(frozen=True)
class ArmConfig(SignedConfig):
    """PUMA configuration: arm +1 right / -1 left, elbow +1 up / -1 down,
    wrist +1 noflip (sin theta5 >= 0) / -1 flip (thesis Figure 3.4)."""

    LABELS = (("right", "left"), ("up", "down"), ("noflip", "flip"))
    arm: int = 1
    elbow: int = 1
    wrist: int = 1


@dataclass(frozen=True)
class WristConfig(SignedConfig):
    """Microbo configuration: wrist +1 noflip (sin theta5 >= 0) / -1 flip (thesis 3.51)."""

    LABELS = (("noflip", "flip"),)
    wrist: int = 1


@dataclass(frozen=True)
class BoomConfig(SignedConfig):
    """Stanford-class configuration: arm +1 right / -1 left (the shoulder offset d2 on the
    right / left of the wrist centre's reach seen from above, as the PUMA's arm), boom +1 out
    (extended through the wrist centre, q3 + d4 > 0) / -1 reversed (back through the
    shoulder, q3 + d4 < 0: a solution only where joint 3's range allows it), wrist +1 noflip
    (sin theta5 >= 0) / -1 flip."""

    LABELS = (("right", "left"), ("out", "reversed"), ("noflip", "flip"))
    arm: int = 1
    boom: int = 1
    wrist: int = 1


@dataclass(frozen=True)
class GuardInfo:
    name: str
    error: str
    message: str


@dataclass(frozen=True)
class KernelFn:
    """One generated kernel: scalar and batched code plus its signature."""

    name: str
    one: Callable[..., tuple]
    many: Callable[..., tuple]
    inputs: tuple[tuple[str, tuple[int, ...]], ...]
    outputs: tuple[tuple[str, tuple[int, ...]], ...]
    guards: tuple[GuardInfo, ...] = ()


def frame_kernel(base: str, frame: int) -> str:
    if frame not in (4, 6):
        raise exceptions.InvalidInput(f"{base}: frame must be 4 or 6, got {frame!r}")
    return f"{base}{frame}"


def _wrap(x: np.ndarray) -> np.ndarray:
    """Angle difference brought into [-pi, pi)."""
    return (x + np.pi) % (2 * np.pi) - np.pi


def _fmt_pose(t: np.ndarray) -> str:
    return np.array2string(np.asarray(t), precision=6, suppress_small=True, separator=", ").replace("\n", "")


class Robot:
    """The contract's functions for one robot, over its generated kernels."""

    def __init__(self, name: str, kernels: Mapping[str, KernelFn], kinds: Sequence[str],
                 lower: np.ndarray, upper: np.ndarray, config_type: type, coeff_names: Sequence[str]):
        self.name = name
        self.kernels = dict(kernels)
        self.revolute = np.array([k == "revolute" for k in kinds])
        self.lower = np.asarray(lower, dtype=float)
        self.upper = np.asarray(upper, dtype=float)
        self.config_type = config_type
        self.coeff_names = tuple(coeff_names)
        #: the compiled kernel solving every configuration of a pose at once, or None
        self.ik_all_kernel = self._find_ik_all()

    def _find_ik_all(self) -> Callable | None:
        from rccl.kinematics import backend  # the loader of the compiled kernels
        ik = self.kernels.get("ik")
        if ik is None:
            return None
        n_cfg, n_guard = len(self.config_type.all()), len(ik.guards)
        return backend.kernel(self.name, "ik_all", ((4, 4),), ((n_cfg, 6), (n_cfg, n_guard)))

    # -- dispatch ----------------------------------------------------------------------

    def _arrays(self, k: KernelFn, args: Sequence[Any]) -> tuple[list[np.ndarray], bool]:
        if len(args) != len(k.inputs):
            raise exceptions.InvalidInput(f"{self.name}.{k.name}: expected {len(k.inputs)} arguments, got {len(args)}")
        arrays, flags = [], []
        for (name, shape), a in zip(k.inputs, args):
            try:
                x = np.asarray(a, dtype=float)
            except (TypeError, ValueError) as exc:
                raise exceptions.InvalidInput(f"{self.name}.{k.name}: argument {name!r} is not numeric: {exc}") from None
            if x.shape == shape:
                flags.append(False)
            elif x.ndim == len(shape) + 1 and x.shape[1:] == shape:
                flags.append(True)
            else:
                raise exceptions.InvalidInput(f"{self.name}.{k.name}: argument {name!r} has shape {x.shape}, "
                                          f"expected {shape} or (N,) + {shape}")
            bad = ~np.isfinite(x)
            if bad.any():
                where = np.argwhere(bad)[0]
                raise exceptions.InvalidInput(f"{self.name}.{k.name}: argument {name!r} is not finite "
                                          f"(NaN or inf at index {tuple(int(i) for i in where)})")
            arrays.append(x)
        batch = any(flags)
        if batch:
            sizes = {a.shape[0] for a, f in zip(arrays, flags) if f}
            if len(sizes) != 1:
                raise exceptions.InvalidInput(f"{self.name}.{k.name}: batch sizes differ: {sorted(sizes)}")
            n = sizes.pop()
            # a single argument next to batched ones is shared by every row
            arrays = [a if f else np.broadcast_to(a, (n,) + a.shape) for a, f in zip(arrays, flags)]
        return arrays, batch

    def raw(self, name: str, *args: Any) -> tuple[tuple, tuple, bool]:
        """(outputs, guard values, batched) without raising on guards."""
        k = self.kernels[name]
        arrays, batch = self._arrays(k, args)
        if batch:
            with np.errstate(all="ignore"):
                res = k.many(*arrays)
        else:
            try:
                res = k.one(*arrays)
            except (ZeroDivisionError, ValueError, OverflowError):
                # at an exactly singular input plain floats raise where numpy gives
                # inf/nan; rerun as a batch of one and let the guards name the problem
                with np.errstate(all="ignore"):
                    res = tuple(np.asarray(r)[0] for r in k.many(*(a[None] for a in arrays)))
        n_out = len(k.outputs)
        return res[:n_out], res[n_out:], batch

    def call(self, name: str, *args: Any, context: Callable[[int | None], str] | None = None,
             out: np.ndarray | None = None) -> tuple:
        """Run a kernel; a negative guard raises its error naming the input. With ``out``
        (numpy's convention) the first output is written into that array, which is returned."""
        outs, guards, batch = self.raw(name, *args)
        self._check(name, guards, batch, args, context)
        self._finite(name, outs, batch, args, context)
        if out is not None:
            outs = (self._into(name, out, outs[0]),) + tuple(outs[1:])
        return outs

    def _into(self, name: str, out: Any, value: Any) -> np.ndarray:
        value = np.asarray(value)
        if not isinstance(out, np.ndarray) or out.dtype != np.float64 or out.shape != value.shape \
                or not out.flags.writeable:
            got = (f"a {'read-only ' if not out.flags.writeable else ''}{out.dtype} array of shape {out.shape}"
                   if isinstance(out, np.ndarray) else f"{type(out).__name__}")
            raise exceptions.InvalidInput(f"{self.name}.{name}: out must be a writable float64 numpy array of "
                                      f"shape {value.shape}, got {got}")
        out[...] = value
        return out

    def _finite(self, name, outs, batch, args, context) -> None:
        """Last line of defence: never hand back a silent NaN or inf."""
        for o in outs:
            o = np.asarray(o)
            if not np.isfinite(o).all():
                i = int(np.argmax(~np.isfinite(o).reshape(o.shape[0], -1).all(axis=1))) if batch else None
                where = context(i) if context else self._describe(args, i)
                raise exceptions.KinematicsError(f"{self.name}.{name}: non-finite result; {where}")

    def _check(self, name, guards, batch, args, context, skip=()) -> None:
        k = self.kernels[name]
        for info, value in zip(k.guards, guards):
            if info.name in skip:
                continue
            v = np.asarray(value)
            bad = ~(v >= 0)
            if bad.any():
                i = int(np.argmax(bad)) if batch else None
                where = context(i) if context else self._describe(args, i)
                raise getattr(exceptions, info.error)(
                    f"{self.name}.{name}: {info.message} ({info.name} = {float(v.flat[i or 0]):.3g}); {where}")

    @staticmethod
    def _describe(args, i) -> str:
        first = np.asarray(args[0], dtype=float)
        row = first if i is None else first[i]
        label = "at " if i is None else f"at batch row {i}: "
        return label + np.array2string(row, precision=6, separator=", ").replace("\n", "")

    # -- contract ----------------------------------------------------------------------

    def fk(self, q):
        return self.call("fk", q)[0]

    def _pose(self, T) -> np.ndarray:
        t = np.asarray(T, dtype=float)
        if t.shape[-2:] != (4, 4) or t.ndim not in (2, 3):
            raise exceptions.InvalidInput(f"{self.name}.ik: pose has shape {t.shape}, expected (4, 4) or (N, 4, 4)")
        if not np.isfinite(t).all():
            raise exceptions.InvalidInput(f"{self.name}.ik: pose is not finite: {_fmt_pose(t)}")
        r = t[..., :3, :3]
        dev = np.abs(np.swapaxes(r, -1, -2) @ r - np.eye(3)).max(axis=(-1, -2))
        bottom = np.abs(t[..., 3, :] - np.array([0.0, 0.0, 0.0, 1.0])).max(axis=-1)
        bad = (dev > RIGID_TOL) | (bottom > 0) | (np.linalg.det(r) < 0)
        if np.any(bad):
            i = int(np.argmax(np.atleast_1d(bad)))
            row = t if t.ndim == 2 else t[i]
            raise exceptions.InvalidInput(f"{self.name}.ik: not a rigid homogeneous transform "
                                      f"(rotation off orthonormal by {float(np.atleast_1d(dev)[i]):.2g}): {_fmt_pose(row)}")
        return t

    def coerce_config(self, config) -> Any:
        if isinstance(config, self.config_type):
            return config
        try:
            return self.config_type(*[int(s) for s in np.atleast_1d(config)])
        except (TypeError, ValueError) as exc:
            raise exceptions.InvalidInput(f"{self.name}.ik: bad configuration {config!r}: {exc}") from None

    def ik(self, T, config, q_ref=None):
        t = self._pose(T)
        cfg = self.coerce_config(config)
        batch = t.ndim == 3
        signs = np.array(cfg.signs, dtype=float).reshape(self.kernels["ik"].inputs[1][1])
        if batch:
            signs = np.broadcast_to(signs, (t.shape[0],) + signs.shape)
        ref = None
        if q_ref is not None:
            ref = np.asarray(q_ref, dtype=float)
            if ref.shape != t.shape[:-2] + (6,) or not np.isfinite(ref).all():
                raise exceptions.InvalidInput(f"{self.name}.ik: q_ref must be finite with shape {t.shape[:-2] + (6,)}, got {ref.shape}")

        def context(i):
            pose = t if i is None else t[i]
            row = "" if i is None else f"batch row {i}: "
            return f"{row}pose T = {_fmt_pose(pose)}, configuration {cfg}"

        (q,), guards, _ = self.raw("ik", t, signs)
        q = np.array(q)
        names = [g.name for g in self.kernels["ik"].guards]
        self._check("ik", guards, batch, (t,), context, skip={"guard_wrist"})
        wrist_bad = ~(np.asarray(guards[names.index("guard_wrist")]) >= 0)
        if np.any(wrist_bad):
            if ref is None:
                self._check("ik", guards, batch, (t,), context)
            # keep theta4 of q_ref and solve theta5, theta6 for it
            rows = np.nonzero(np.atleast_1d(wrist_bad))[0]
            # (theta5, theta6 from the singular solve may be nan; ik_wrist ignores them)
            if batch:
                q[rows, 3] = ref[rows, 3]
                q[rows, 4:6] = 0.0
                (q56,) = self.call("ik_wrist", t[rows], q[rows])
                q[rows, 4:6] = q56
            else:
                q[3] = ref[3]
                q[4:6] = 0.0
                (q56,) = self.call("ik_wrist", t, q)
                q[4:6] = q56
        if ref is not None:
            rev = self.revolute
            q[..., rev] = ref[..., rev] + _wrap(q[..., rev] - ref[..., rev])
        self._finite("ik", (q,), batch, (t,), context)
        self._check_prismatic(q, batch, context)
        return q

    def _check_prismatic(self, q, batch, context) -> None:
        pri = ~self.revolute
        if not pri.any():
            return
        qp = q[..., pri]
        lo, hi = self.lower[pri], self.upper[pri]
        bad = (qp < lo - 1e-12) | (qp > hi + 1e-12)
        if bad.any():
            if batch:
                i = int(np.argmax(bad.any(axis=-1)))
                row = qp[i]
            else:
                i, row = None, qp
            j = int(np.argmax(bad[i] if batch else bad))
            joint = int(np.nonzero(pri)[0][j]) + 1
            raise exceptions.Unreachable(
                f"{self.name}.ik: prismatic joint {joint} would need {row[j]:.6g} m, outside its range "
                f"[{lo[j]:.6g}, {hi[j]:.6g}] m; {context(i)}")

    def ik_all(self, T, q_ref=None):
        """Every distinct solution of one pose (a list of (config, q)) or of a batch of poses
        (N, 4, 4) (a list of such lists; q_ref then (N, 6)).

        The compiled ``ik_all`` kernel solves every configuration at once; a configuration
        whose guards all pass is taken from it directly, any other goes through ``ik`` so
        errors and the wrist-singular fallback are exactly those of ``ik`` (an unreachable
        configuration is left out, a singular one raises).
        """
        t = self._pose(T)
        batch = t.ndim == 3
        ref = None
        if q_ref is not None:
            ref = np.asarray(q_ref, dtype=float)
            if ref.shape != t.shape[:-2] + (6,) or not np.isfinite(ref).all():
                raise exceptions.InvalidInput(f"{self.name}.ik_all: q_ref must be finite with shape "
                                          f"{t.shape[:-2] + (6,)}, got {ref.shape}")
        configs = self.config_type.all()
        n = t.shape[0] if batch else 1
        t3 = t if batch else t[None]
        ref2 = None if ref is None else (ref if batch else ref[None])
        if self.ik_all_kernel is None:
            q_all = np.full((n, len(configs), 6), np.nan)
            ok = np.zeros((n, len(configs)), dtype=bool)
        else:
            with np.errstate(all="ignore"):
                q_all, g_all = self.ik_all_kernel(t3)[:2]
            # a configuration is taken from the kernel when every guard passes and its joints
            # are finite and in range; the others go through ik (messages, wrist fallback)
            ok = (g_all >= 0).all(axis=-1) & np.isfinite(q_all).all(axis=-1)
            if ref2 is not None:
                rev = self.revolute
                q_all[..., rev] = ref2[:, None, rev] + _wrap(q_all[..., rev] - ref2[:, None, rev])
            pri = ~self.revolute
            if pri.any():
                qp = q_all[..., pri]
                ok &= np.all((qp >= self.lower[pri] - 1e-12) & (qp <= self.upper[pri] + 1e-12), axis=-1)
        found = ok.copy()
        for i, j in zip(*np.nonzero(~ok)):
            try:
                q_all[i, j] = self.ik(t3[i], configs[j], None if ref2 is None else ref2[i])
                found[i, j] = True
            except exceptions.Unreachable:
                continue
        # keep the first of every group of equal solutions (2 pi apart on revolute joints)
        d = q_all[:, :, None, :] - q_all[:, None, :, :]
        d[..., self.revolute] = _wrap(d[..., self.revolute])
        with np.errstate(invalid="ignore"):
            same = np.all(np.abs(d) < SAME_SOLUTION_TOL, axis=-1)
        if n <= 16:  # few poses: plain Python is cheaper than numpy on 8 x 8 booleans
            out = []
            for i, (f_i, s_i) in enumerate(zip(found.tolist(), same.tolist())):
                kept: list[int] = []
                for j in range(len(configs)):
                    if f_i[j] and not any(s_i[j][k] for k in kept):
                        kept.append(j)
                out.append([(configs[j], q_all[i, j].copy()) for j in kept])
            return out if batch else out[0]
        keep = found.copy()
        for j in range(1, len(configs)):  # drop j when it equals a kept earlier solution
            keep[:, j] &= ~np.any(same[:, j, :j] & keep[:, :j], axis=-1)
        return [[(configs[j], q_all[i, j].copy()) for j in np.nonzero(keep[i])[0]] for i in range(n)]

    def _same(self, a: np.ndarray, b: np.ndarray) -> bool:
        d = a - b
        d[self.revolute] = _wrap(d[self.revolute])
        return bool(np.all(np.abs(d) < SAME_SOLUTION_TOL))

    def config_of(self, q):
        (ind,) = self.call("config_indicators", q)
        batch = np.asarray(q).ndim == 2
        signs = np.where(np.asarray(ind) >= 0, 1, -1)
        signs = signs.reshape(-1, len(self.config_type.__dataclass_fields__))
        if not batch:
            signs = signs[0]
        if signs.ndim == 1:
            return self.config_type(*(int(s) for s in signs))
        return [self.config_type(*(int(s) for s in row)) for row in signs]

    def coeff_vector(self, coeffs) -> np.ndarray:
        """Gravity coefficients as a vector in GRAVITY_COEFFS order."""
        if hasattr(coeffs, "gravity_coeffs"):  # a RobotModel
            coeffs = coeffs.gravity_coeffs
        if isinstance(coeffs, Mapping):
            missing = [n for n in self.coeff_names if n not in coeffs]
            if missing:
                raise exceptions.InvalidInput(f"{self.name}.gravity: coefficients {missing} missing "
                                          f"(need {list(self.coeff_names)})")
            vals = [getattr(coeffs[n], "value", coeffs[n]) for n in self.coeff_names]
            return np.array(vals, dtype=float)
        c = np.asarray(coeffs, dtype=float)
        if c.shape[-1:] != (len(self.coeff_names),):
            raise exceptions.InvalidInput(f"{self.name}.gravity: expected {len(self.coeff_names)} coefficients "
                                      f"{list(self.coeff_names)}, got shape {c.shape}")
        return c

    def tool_load(self, coeffs, mass, com) -> dict[str, float]:
        c = self.coeff_vector(coeffs)
        com = np.atleast_1d(np.asarray(com, dtype=float))
        if com.shape == (3,):
            if abs(com[0]) > 1e-12 or abs(com[1]) > 1e-12:
                raise exceptions.InvalidInput(f"{self.name}.tool_load: the grouped gravity model (4.26) "
                                          f"takes the load on the z6 axis; com = {com} is off it")
            dist = com[2]
        elif com.shape == (1,):
            dist = com[0]
        else:
            raise exceptions.InvalidInput(f"{self.name}.tool_load: com must be d_t or (0, 0, d_t), got {com}")
        (out,) = self.call("tool_load", c, [float(mass), float(dist)])
        return dict(zip(self.coeff_names, (float(x) for x in out)))


# -- the public functions ------------------------------------------------------------------

PublicAPI = NamedTuple("PublicAPI", [(n, Callable) for n in PUBLIC])
PublicAPI.__doc__ = "The contract's public functions of one robot, by name, in the order of PUBLIC."


def public_api(robot: Robot) -> PublicAPI:
    """The contract's public functions of one robot (``PUBLIC``), over its kernels.

    Each is the compiled fast entry (``rccl.kinematics.backend``) when the C kernels are
    built: one configuration or a batch of float64 numpy arrays (a pose, a Config, gravity
    coefficients as an array or a mapping of floats) runs in C with every check there; any
    other call, and every error, goes to the Python function defined here, so conversions
    and messages are the runtime's. Batched calls take ``out=`` (numpy's convention: an
    array of exactly the result's shape, float64, writable; the result is written there
    and returned).
    """
    from rccl.kinematics import backend  # the loader of the compiled kernels

    name, kernels = robot.name, robot.kernels

    def fk(q, out=None):
        """T6 (4, 4), link 6 in the base frame (thesis 3.16-3.18); q (6,) or (N, 6) -> (N, 4, 4)."""
        return robot.call("fk", q, out=out)[0]

    def ik(T, config, q_ref=None):
        """Joint variables for pose T in configuration `config` (thesis 3.19-3.53).

        q_ref (optional current joints) keeps theta4 at a wrist singularity and picks the
        2 pi branch of each revolute joint nearest to it. Raises exceptions.Unreachable or
        exceptions.Singular with the pose and the reason.
        """
        return robot.ik(T, config, q_ref)

    def ik_all(T, q_ref=None):
        """Every distinct solution for one pose T, as a list of (Config, q)."""
        return robot.ik_all(T, q_ref)

    def config_of(q):
        """The Config of q (a list of Configs for a batch)."""
        return robot.config_of(q)

    def jacobian4(q, out=None):
        """4J (6, 6): link 6's motion observed in frame 4 (thesis 3.54-3.61)."""
        return robot.call("jacobian4", q, out=out)[0]

    def jacobian6(q, out=None):
        """6J (6, 6): link 6's motion observed in frame 6 (Pinocchio LOCAL frame Jacobian)."""
        return robot.call("jacobian6", q, out=out)[0]

    def framed(base: str) -> dict[int, Callable]:
        """The frame-4 and frame-6 kernels of one Jacobian computation, as fast entries."""
        def entry(frame: int) -> Callable:
            kname = f"{base}{frame}"

            def run(q, x, out=None):
                return robot.call(kname, q, x, out=out)[0]
            run.__name__ = kname
            return backend.public(name, kname, run, kernels)
        return {4: entry(4), 6: entry(6)}

    def pick(table: dict[int, Callable], base: str, frame) -> Callable:
        fn = table.get(frame) if frame in (4, 6) else None
        if fn is None:
            frame_kernel(base, frame)  # raises InvalidInput naming the bad frame
        return fn

    c_from_j, t_from_f = framed("cartesian_from_joint"), framed("torque_from_force")
    if "joint_from_cartesian4" not in kernels:  # a redundant arm: least squares (rccl.kinematics.redundant)
        from rccl.kinematics import redundant
        j_from_c, f_from_t = redundant.least_squares(robot)
    else:
        j_from_c, f_from_t = framed("joint_from_cartesian"), framed("force_from_torque")

    def cartesian_from_joint(q, dq, frame=6, out=None):
        """dc = J dq observed in frame 4 or 6 (thesis 3.71, 3.75, 3.79)."""
        fn = pick(c_from_j, "cartesian_from_joint", frame)
        return fn(q, dq) if out is None else fn(q, dq, out=out)

    def torque_from_force(q, f, frame=6, out=None):
        """tau = J^T f with f observed in frame 4 or 6 (thesis 3.72, 3.76, 3.79)."""
        fn = pick(t_from_f, "torque_from_force", frame)
        return fn(q, f) if out is None else fn(q, f, out=out)

    def joint_from_cartesian(q, dc, frame=6, out=None):
        """dq = J^-1 dc with dc observed in frame 4 or 6 (thesis 3.73, 3.77, 3.79); raises Singular."""
        fn = pick(j_from_c, "joint_from_cartesian", frame)
        return fn(q, dc) if out is None else fn(q, dc, out=out)

    def force_from_torque(q, tau, frame=6, out=None):
        """f = J^-T tau observed in frame 4 or 6 (thesis 3.74, 3.78, 3.79); raises Singular."""
        fn = pick(f_from_t, "force_from_torque", frame)
        return fn(q, tau) if out is None else fn(q, tau, out=out)

    def gravity(q, coeffs, out=None):
        """Joint torques holding the arm against gravity (thesis 4.24).

        coeffs: an array in GRAVITY_COEFFS order, a mapping name -> value (floats, or records
        with a ``.value`` such as ``RobotModel.gravity_coeffs``), or a record with
        ``gravity_coeffs``; the compiled entry reads all of these directly.
        """
        return robot.call("gravity", q, robot.coeff_vector(coeffs), out=out)[0]

    def gravity_regressor(q, out=None):
        """(6, k) matrix Y with gravity(q, c) = Y c, columns in GRAVITY_COEFFS order."""
        return robot.call("gravity_regressor", q, out=out)[0]

    def gravity_links(q, masses, coms):
        """Thesis 4.20 from link masses (6,) kg and centres of mass (6, 3) m in frames 1..6."""
        return robot.call("gravity_links", q, masses, coms)[0]

    def coefficients_from_links(masses, coms):
        """Gravity coefficients (dict, GRAVITY_COEFFS) of link masses (6,) kg and centres of
        mass (6, 3) m in frames 1..6; components 4.24 neglects (4.21) are ignored."""
        (c,) = robot.call("coefficients_from_links", masses, coms)
        return dict(zip(robot.coeff_names, (float(x) for x in c))) if c.ndim == 1 else c

    def tool_load(coeffs, mass, com):
        """Coefficients with a tool of `mass` kg at `com` on the z6 axis (thesis 4.26)."""
        return robot.tool_load(coeffs, mass, com)

    if "ik" not in kernels:  # a redundant arm before its solver is derived (derive.redundant)
        from rccl.kinematics.redundant import missing_solver
        ik, ik_all, config_of = missing_solver(name).values()
    if hasattr(robot, "public_entries"):  # a redundant arm: ik(T, config, q_ref, q7), ik_all(T, q7, q_ref)
        fast = robot.public_entries()  # rccl.kinematics.redundant_ik
    else:
        fast = backend.public_ik(name, {"ik": ik, "ik_all": ik_all, "config_of": config_of}, kernels,
                                 robot.config_type, robot.revolute, robot.lower, robot.upper,
                                 RIGID_TOL, SAME_SOLUTION_TOL)
    return PublicAPI(
        fk=backend.public(name, "fk", fk, kernels),
        ik=fast["ik"], ik_all=fast["ik_all"], config_of=fast["config_of"],
        jacobian4=backend.public(name, "jacobian4", jacobian4, kernels),
        jacobian6=backend.public(name, "jacobian6", jacobian6, kernels),
        cartesian_from_joint=cartesian_from_joint, torque_from_force=torque_from_force,
        joint_from_cartesian=joint_from_cartesian, force_from_torque=force_from_torque,
        gravity=backend.public(name, "gravity", gravity, kernels, keys=robot.coeff_names),
        gravity_regressor=backend.public(name, "gravity_regressor", gravity_regressor, kernels),
        gravity_links=gravity_links, coefficients_from_links=coefficients_from_links, tool_load=tool_load)
