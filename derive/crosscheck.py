"""Cross-check of the generated kinematics against Pinocchio on the URDFs.

`python -m derive.crosscheck --samples N` writes reports/crosscheck.md: the largest
error per quantity and robot, with the sample counts. The same functions back
tests/test_crosscheck.py. The two sides are independent: the generated code comes from
the DH table through SymPy, Pinocchio reads the URDF (a robot description written by
hand).
"""
from __future__ import annotations

import argparse
import dataclasses
import importlib
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType

import numpy as np
import pinocchio as pin

from rcci.models.kinematics import Singular

ROOT = Path(__file__).resolve().parent.parent
#: the package `make derive` writes the generated modules into (derive/__main__.py OUT_DIR);
#: the cross-check runs that output, loaded by name: the derivation never imports the runtime
GENERATED_PACKAGE = "rccl.kinematics"
def _robots() -> tuple[str, ...]:
    from rcci.models import available_robots

    return tuple(available_robots())


MODULES: dict[str, ModuleType] = {robot: importlib.import_module(f"{GENERATED_PACKAGE}.{robot}")
                                  for robot in _robots()}
#: below these the closed form loses digits (errors ~ eps / value): such samples are
#: checked through fk(ik(T)) = T only, not through q = ik(fk(q))
WELL_CONDITIONED = 1e-3


@dataclass
class PinArm:
    """A Pinocchio model of one URDF with the DH-frame ids."""

    name: str
    model: pin.Model
    data: pin.Data
    frame: dict[int, int]  # DH frame k -> Pinocchio frame id of "link<k>"

    @classmethod
    def load(cls, name: str) -> "PinArm":
        model = pin.buildModelFromUrdf(str(ROOT / "models" / "urdf" / f"{name}.urdf"))
        frames = {k: model.getFrameId(f"link{k}") for k in range(1, model.nq + 1)}
        return cls(name, model, model.createData(), frames)

    @property
    def n(self) -> int:
        """The number of joints (6; 7 for a redundant arm): the last DH frame."""
        return self.model.nq

    def pose(self, q: np.ndarray, k: int | None = None) -> np.ndarray:
        pin.framesForwardKinematics(self.model, self.data, q)
        return self.data.oMf[self.frame[k or self.n]].homogeneous.copy()

    def jacobians(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(4J, 6J): Paul's frame-6 Jacobian is the LOCAL frame Jacobian of link6; the
        link-4 one has both 3-row blocks rotated into frame 4."""
        pin.computeJointJacobians(self.model, self.data, q)
        pin.updateFramePlacements(self.model, self.data)
        j6 = pin.getFrameJacobian(self.model, self.data, self.frame[self.n], pin.LOCAL)
        r46 = self.data.oMf[self.frame[4]].rotation.T @ self.data.oMf[self.frame[self.n]].rotation
        rot = np.zeros((6, 6))
        rot[:3, :3] = rot[3:, 3:] = r46
        return rot @ j6, j6.copy()

    def gravity(self, q: np.ndarray) -> np.ndarray:
        return pin.computeGeneralizedGravity(self.model, self.data, q).copy()

    def set_links(self, masses: np.ndarray, coms: np.ndarray, rng: np.random.Generator) -> None:
        """Replace every link's inertial: mass, centre of mass in DH frame k (random
        positive-definite rotational inertia, which gravity must not depend on)."""
        for k in range(1, self.n + 1):
            f = self.model.frames[self.frame[k]]
            a = rng.normal(size=(3, 3))
            inertia = a @ a.T * 1e-3 + np.eye(3) * 1e-4
            self.model.inertias[f.parentJoint] = pin.Inertia(
                float(masses[k - 1]), f.placement.act(np.asarray(coms[k - 1], dtype=float)), inertia)
        self.data = self.model.createData()

    def add_point_mass(self, mass: float, point_in_link6: np.ndarray) -> None:
        f = self.model.frames[self.frame[self.n]]
        extra = pin.Inertia(mass, f.placement.act(np.asarray(point_in_link6, dtype=float)), np.zeros((3, 3)))
        self.model.inertias[f.parentJoint] = self.model.inertias[f.parentJoint] + extra
        self.data = self.model.createData()


def _wrap(x: np.ndarray) -> np.ndarray:
    return (x + np.pi) % (2 * np.pi) - np.pi


def joint_error(mod: ModuleType, a: np.ndarray, b: np.ndarray) -> float:
    """Largest joint difference, revolute joints modulo 2 pi."""
    d = np.asarray(a, dtype=float) - np.asarray(b, dtype=float)
    rev = np.array([k == "revolute" for k in mod.JOINT_KINDS])
    d[..., rev] = _wrap(d[..., rev])
    return float(np.abs(d).max())


def edge_values(mod: ModuleType) -> list[list[float]]:
    """Per joint: 0, +-pi/2, pi (revolute) inside the range, and both limits."""
    out = []
    for kind, lo, hi in zip(mod.JOINT_KINDS, mod.LOWER, mod.UPPER):
        vals = [lo, hi]
        if kind == "revolute":
            vals += [v for v in (0.0, np.pi / 2, -np.pi / 2, np.pi, -np.pi) if lo <= v <= hi]
        else:
            vals.append(0.5 * (lo + hi))
        out.append(sorted(set(float(v) for v in vals)))
    return out


def samples(mod: ModuleType, n: int, seed: int = 0) -> np.ndarray:
    """n uniform configurations over the joint ranges, then edge configurations:
    each joint at each of its edge values (others random), and all joints at edge
    values together."""
    rng = np.random.default_rng(seed)
    lo, hi = np.asarray(mod.LOWER), np.asarray(mod.UPPER)
    rand = rng.uniform(lo, hi, size=(n, len(lo)))
    edges = edge_values(mod)
    rows = []
    for j, vals in enumerate(edges):
        for v in vals:
            q = rng.uniform(lo, hi)
            q[j] = v
            rows.append(q)
    for _ in range(max(8, n // 20)):
        rows.append(np.array([rng.choice(vals) for vals in edges]))
    return np.vstack([rand, np.array(rows)])


def conditioning(mod: ModuleType, q: np.ndarray) -> float:
    """Smallest of the normalised singularity distances at q: |S5| and, for the PUMA class,
    |cos(theta3 - phi)| (elbow) and |h|/(a2 + L) (shoulder), with L = sqrt(a3^2 + d4^2) the
    forearm and phi = atan2(a3, d4); for the Stanford class |S2| (the boom along the joint-1
    axis) and the boom's length q3 + d4; for the Microbo class the radial extension d3."""
    q = np.atleast_2d(q)
    if redundant(mod):  # no closed form to lose digits in: the Jacobian's conditioning
        s = np.linalg.svd(mod.jacobian6(q), compute_uv=False)
        return s[:, -1] / s[:, 0]
    vals = [np.abs(np.sin(q[:, 4]))]
    signs = tuple(f.name for f in dataclasses.fields(mod.Config))
    if signs == ("arm", "boom", "wrist"):  # the Stanford class
        vals += [np.abs(np.sin(q[:, 1])), np.abs(q[:, 2] + getattr(mod, "D4", 0.0))]
    elif len(mod.Config.all()) == 8:  # arm, elbow, wrist: the PUMA class
        a2, a3, d4 = mod.A2, getattr(mod, "A3", 0.0), mod.D4
        forearm = np.hypot(a3, d4)
        h = a2 * np.cos(q[:, 1]) + a3 * np.cos(q[:, 1] + q[:, 2]) - d4 * np.sin(q[:, 1] + q[:, 2])
        bend = (d4 * np.cos(q[:, 2]) + a3 * np.sin(q[:, 2])) / forearm
        vals += [np.abs(bend), np.abs(h) / (a2 + forearm)]
    else:
        vals.append(np.abs(q[:, 2]))
    return np.min(np.vstack(vals), axis=0)


def redundant(mod: ModuleType) -> bool:
    """A 7-joint arm: 6 x 7 Jacobians, least-squares inverse computations."""
    return len(mod.JOINT_KINDS) == 7


def has_ik(mod: ModuleType) -> bool:
    """The generated module has its inverse kinematics: its configuration record has sign
    fields (a redundant arm's record is field-less until derive/inverse_redundant.py exists)."""
    return len(dataclasses.fields(mod.Config)) > 0


@dataclass
class CrossCheckResult:
    """Largest error per quantity, with how many cases it covers."""

    robot: str
    errors: dict[str, float] = field(default_factory=dict)
    counts: dict[str, int] = field(default_factory=dict)
    notes: dict[str, str] = field(default_factory=dict)

    def record(self, key: str, err: float, count: int, note: str = "") -> None:
        self.errors[key] = max(self.errors.get(key, 0.0), float(err))
        self.counts[key] = self.counts.get(key, 0) + int(count)
        if note:
            self.notes[key] = note


def check_forward(mod, arm: PinArm, qs: np.ndarray, res: CrossCheckResult) -> None:
    batch = mod.fk(qs)
    err = 0.0
    for q, t in zip(qs, batch):
        err = max(err, np.abs(t - arm.pose(q)).max())
        err = max(err, np.abs(mod.fk(q) - t).max())  # scalar == batched
    res.record("T6, all 16 entries (m, 1)", err, len(qs))


def check_jacobians(mod, arm: PinArm, qs: np.ndarray, res: CrossCheckResult) -> None:
    e4 = e6 = 0.0
    j4b, j6b = mod.jacobian4(qs), mod.jacobian6(qs)
    for i, q in enumerate(qs):
        j4, j6 = arm.jacobians(q)
        e4 = max(e4, np.abs(j4 - mod.jacobian4(q)).max(), np.abs(j4 - j4b[i]).max())
        e6 = max(e6, np.abs(j6 - mod.jacobian6(q)).max(), np.abs(j6 - j6b[i]).max())
    res.record("6J vs getFrameJacobian(link6, LOCAL)", e6, len(qs))
    res.record("4J vs 6J rotated into frame 4", e4, len(qs))


def check_jacobian_computations(mod, arm: PinArm, qs: np.ndarray, res: CrossCheckResult, seed: int = 1) -> None:
    """The four computations, frames 4 and 6, against J formed by Pinocchio.

    Forward ones are compared absolutely (inputs of unit size); inverse ones relative to
    the size of the answer, over configurations with cond(J) < 1e6.
    """
    rng = np.random.default_rng(seed)
    fwd = {4: 0.0, 6: 0.0}
    inv = {4: 0.0, 6: 0.0}
    n_inv = 0
    nj = arm.n
    for q in qs:
        j4, j6 = arm.jacobians(q)
        ok = conditioning(mod, q)[0] > WELL_CONDITIONED and np.linalg.cond(j6) < 1e6
        n_inv += ok
        for frame, j in ((4, j4), (6, j6)):
            dq, f = rng.normal(size=nj), rng.normal(size=6)
            e = max(np.abs(mod.cartesian_from_joint(q, dq, frame) - j @ dq).max(),
                    np.abs(mod.torque_from_force(q, f, frame) - j.T @ f).max())
            fwd[frame] = max(fwd[frame], e)
            if ok:
                dc, tau = rng.normal(size=6), rng.normal(size=nj)
                # 6 joints: the inverse; 7: the minimum-norm and least-squares solutions
                want_dq = np.linalg.lstsq(j, dc, rcond=None)[0]
                want_f = np.linalg.lstsq(j.T, tau, rcond=None)[0]
                e = max(np.abs(mod.joint_from_cartesian(q, dc, frame) - want_dq).max() / max(1.0, np.abs(want_dq).max()),
                        np.abs(mod.force_from_torque(q, tau, frame) - want_f).max() / max(1.0, np.abs(want_f).max()))
                inv[frame] = max(inv[frame], e)
    for frame in (4, 6):
        res.record(f"J dq and J^T f, frame {frame}", fwd[frame], len(qs))
        res.record(f"J^-1 dc and J^-T tau, frame {frame} (relative)", inv[frame], n_inv,
                   "configurations with every singularity distance > 1e-3 and cond(J) < 1e6")


def check_gravity(mod, arm: PinArm, qs: np.ndarray, res: CrossCheckResult, seed: int = 2) -> None:
    from rcci.models import load_robot

    model = load_robot(mod.ROBOT)
    masses = np.array([link.mass for link in model.links])
    coms = np.array([link.com for link in model.links])
    e_table = e_links = e_coeff = e_reg = 0.0
    c_links = np.array(list(mod.coefficients_from_links(masses, coms).values()))
    for q in qs:
        g = arm.gravity(q)
        if model.gravity_coeffs:  # a new arm's file may leave them out until they are known
            e_table = max(e_table, np.abs(mod.gravity(q, model) - g).max())
        e_links = max(e_links, np.abs(mod.gravity_links(q, masses, coms) - g).max())
        e_coeff = max(e_coeff, np.abs(mod.gravity(q, c_links) - g).max())
        e_reg = max(e_reg, np.abs(mod.gravity_regressor(q) @ c_links - mod.gravity(q, c_links)).max())
    if model.gravity_coeffs:
        origin = next(iter(model.gravity_coeffs.values())).source.tag
        res.record("gravity 4.24, model-file coefficients vs URDF (N m, N)", e_table, len(qs),
                   f"the model file's coefficients ({origin}); the URDF's inertials carry 11 digits, which bounds this error")
    res.record("gravity 4.24, coefficients of the URDF inertials (N m, N)", e_coeff, len(qs))
    res.record("gravity 4.20, URDF link masses and centres of mass (N m, N)", e_links, len(qs))
    res.record("gravity regressor Y(q) c = gravity(q, c)", e_reg, len(qs))
    # 4.20 with arbitrary centres of mass (no 4.21 assumption) and random masses
    rng = np.random.default_rng(seed)
    rand = PinArm.load(mod.ROBOT)
    m_r = rng.uniform(0.1, 3.0, rand.n)
    c_r = rng.uniform(-0.2, 0.2, (rand.n, 3))
    rand.set_links(m_r, c_r, rng)
    e_rand = max(np.abs(mod.gravity_links(q, m_r, c_r) - rand.gravity(q)).max() for q in qs)
    res.record("gravity 4.20, random masses and centres of mass (N m, N)", e_rand, len(qs))
    # 4.26: a tool of mass m_t at d_t on z6
    tool = PinArm.load(mod.ROBOT)
    m_t, d_t = 0.8, 0.12
    tool.add_point_mass(m_t, np.array([0.0, 0.0, d_t]))
    loaded = mod.tool_load(dict(zip(mod.GRAVITY_COEFFS, c_links)), m_t, d_t)
    e_tool = max(np.abs(mod.gravity(q, loaded) - tool.gravity(q)).max() for q in qs)
    res.record("gravity with tool load 4.26 (0.8 kg at 0.12 m on z6) (N m, N)", e_tool, len(qs))


def check_inverse(mod, qs: np.ndarray, res: CrossCheckResult) -> None:
    """fk(ik(T, c)) = T for every configuration c that reaches T; ik(fk(q), config_of(q))
    = q (mod 2 pi); ik_all contains q and only distinct solutions."""
    e_fk = e_q = 0.0
    n_fk = n_q = n_all = 0
    cond = conditioning(mod, qs)
    for q, well in zip(qs, cond > WELL_CONDITIONED):
        t = mod.fk(q)
        try:
            sols = mod.ik_all(t, q_ref=None if well else q)
        except Singular:
            sols = mod.ik_all(t, q_ref=q)
        for cfg, qs_ in sols:
            e_fk = max(e_fk, np.abs(mod.fk(qs_) - t).max())
            n_fk += 1
        if well:
            q2 = mod.ik(t, mod.config_of(q))
            e_q = max(e_q, joint_error(mod, q2, q))
            n_q += 1
            if not any(joint_error(mod, s, q) < 1e-10 for _, s in sols):
                raise AssertionError(f"{mod.ROBOT}: ik_all misses q = {q}")
            for i in range(len(sols)):
                for j in range(i):
                    if joint_error(mod, sols[i][1], sols[j][1]) < 1e-6:
                        raise AssertionError(f"{mod.ROBOT}: ik_all repeats a solution at q = {q}")
            n_all += 1
    res.record("fk(ik(T, c)) - T, every reachable configuration", e_fk, n_fk)
    res.record("ik(fk(q), config_of(q)) - q, mod 2 pi (rad, m)", e_q, n_q,
               "samples with every singularity distance > 1e-3")
    res.record("ik_all contains q, solutions distinct (poses)", 0.0, n_all)
    # batched ik agrees with the scalar one
    well = qs[cond > WELL_CONDITIONED]
    if len(well):
        cfg = mod.config_of(well[0])
        same = [q for q in well if mod.config_of(q) == cfg]
        tb = mod.fk(np.array(same))
        qb = mod.ik(tb, cfg)
        e_b = max(np.abs(qb[i] - mod.ik(tb[i], cfg)).max() for i in range(len(same)))
        res.record("batched ik = scalar ik", e_b, len(same))


def check_inverse_redundant(mod, qs: np.ndarray, res: CrossCheckResult) -> None:
    """A redundant arm (q7 free, derive.inverse_redundant): fk of every solution of
    ik_all(fk(q), q7 = q's joint 7) reproduces T, and q is among them (mod 2 pi); samples at
    a singular branch (Singular raised) are counted apart."""
    e_fk = e_q = 0.0
    n_fk = n_q = 0
    for q in qs:
        t = mod.fk(q)
        try:
            sols = mod.ik_all(t, q[6])
        except Singular:
            continue
        for _, s in sols:
            e_fk = max(e_fk, float(np.abs(mod.fk(s) - t).max()))
            n_fk += 1
        e_q = max(e_q, min((joint_error(mod, s, q) for _, s in sols), default=np.inf))
        n_q += 1
    res.record("fk(ik_all(T, q7)) - T, every solution (q7 free)", e_fk, n_fk)
    res.record("ik_all(fk(q), q7) contains q, mod 2 pi (rad; q7 free)", e_q, n_q,
               f"{len(qs) - n_q} samples singular")


def _rel(a, b) -> float:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return float(np.abs(a - b).max() / max(1.0, np.abs(b).max()))


def check_dynamics(mod, arm: PinArm, qs: np.ndarray, res: CrossCheckResult, seed: int = 3) -> None:
    """The whole dynamics (4.6, derive.dynamics) against Pinocchio's rnea, crba,
    computeCoriolisMatrix, computeGeneralizedGravity and computeJointTorqueRegressor; errors
    relative to max(1, largest entry of Pinocchio's answer)."""
    from rcci.models import load_robot

    rng = np.random.default_rng(seed)
    model = load_robot(mod.ROBOT)
    masses = np.array([li.mass for li in model.links])
    coms = np.array([li.com for li in model.links])
    inertia = np.array([[i[0, 0], i[1, 1], i[2, 2], i[0, 1], i[0, 2], i[1, 2]]
                        for i in (np.asarray(li.inertia) for li in model.links)])
    nj = arm.n
    beta = mod.base_parameters(masses, coms, inertia, np.zeros(nj))
    # a second model: random physical inertials (DH frame k) and rotor inertias
    other = arm.model.copy()
    m_r, c_r = rng.uniform(0.5, 5.0, nj), rng.uniform(-0.2, 0.2, (nj, 3))
    i_r = []
    for k in range(nj):
        a = rng.normal(size=(3, 3))
        ic = a @ a.T * 1e-2 + np.eye(3) * 1e-3
        i_r.append([ic[0, 0], ic[1, 1], ic[2, 2], ic[0, 1], ic[0, 2], ic[1, 2]])
        f = other.frames[arm.frame[k + 1]]
        other.inertias[f.parentJoint] = f.placement.act(pin.Inertia(float(m_r[k]), c_r[k], ic))
    rotor = rng.uniform(0.0, 0.1, nj)
    other.armature = rotor
    od = other.createData()
    beta_r = mod.base_parameters(m_r, c_r, np.array(i_r), rotor)
    pi = np.concatenate([other.inertias[j].toDynamicParameters() for j in range(1, other.njoints)])
    m, d = arm.model, arm.data
    e = dict.fromkeys(("id", "D", "c", "C", "tg", "tg4", "yb", "yr", "pinreg", "skew"), 0.0)
    eig = np.inf
    h = 1e-6
    for q in qs:
        qd, qdd = rng.uniform(-2, 2, nj), rng.uniform(-5, 5, nj)
        tau = pin.rnea(m, d, q, qd, qdd).copy()
        grav = pin.computeGeneralizedGravity(m, d, q).copy()
        e["id"] = max(e["id"], _rel(mod.inverse_dynamics(q, qd, qdd), tau))
        dm = mod.inertia_matrix(q)
        e["D"] = max(e["D"], _rel(dm, np.triu(pin.crba(m, d, q)) + np.triu(d.M, 1).T))
        e["c"] = max(e["c"], _rel(mod.coriolis(q, qd), pin.rnea(m, d, q, qd, np.zeros(nj)) - grav))
        cm = mod.coriolis_matrix(q, qd)
        e["C"] = max(e["C"], _rel(cm, pin.computeCoriolisMatrix(m, d, q, qd)))
        tg = mod.inverse_dynamics(q, np.zeros(nj), np.zeros(nj))
        e["tg"] = max(e["tg"], _rel(tg, grav))
        e["tg4"] = max(e["tg4"], _rel(tg, mod.gravity_links(q, masses, coms)))
        y = mod.base_regressor(q, qd, qdd)
        e["yb"] = max(e["yb"], _rel(y @ beta, tau))
        tau_r = pin.rnea(other, od, q, qd, qdd)
        e["yr"] = max(e["yr"], _rel(y @ beta_r, tau_r))
        e["pinreg"] = max(e["pinreg"], _rel(pin.computeJointTorqueRegressor(other, od, q, qd, qdd) @ pi + rotor * qdd,
                                            y @ beta_r))
        eig = min(eig, float(np.linalg.eigvalsh(dm).min()))
        ddot = (mod.inertia_matrix(q + h * qd) - mod.inertia_matrix(q - h * qd)) / (2 * h)
        n_ = ddot - 2 * cm
        e["skew"] = max(e["skew"], float(np.abs(n_ + n_.T).max() / max(1.0, np.abs(ddot).max())))
    n = len(qs)
    res.record("inverse_dynamics vs rnea (relative)", e["id"], n,
               "qd uniform in +-2, qdd in +-5 (rad/s, rad/s^2; m/s, m/s^2 on prismatic joints)")
    res.record("inertia_matrix D vs crba (relative)", e["D"], n)
    res.record("coriolis c vs rnea(q, qd, 0) - gravity (relative)", e["c"], n)
    res.record("coriolis_matrix C vs computeCoriolisMatrix (relative)", e["C"], n)
    res.record("t_g = inverse_dynamics(q, 0, 0) vs computeGeneralizedGravity (relative)", e["tg"], n)
    res.record("t_g vs the gravity kernel 4.20 (relative)", e["tg4"], n)
    res.record("base_regressor x base_parameters(data file) vs rnea (relative)", e["yb"], n)
    res.record("base_regressor x base_parameters, random inertials and rotors, vs rnea (relative)", e["yr"], n,
               "one random model per arm: masses 0.5-5 kg, centres of mass within 0.2 m, random SPD inertias, "
               "rotor inertias 0-0.1 (Pinocchio's armature)")
    res.record("computeJointTorqueRegressor x parameters + rotor vs base_regressor x base_parameters (relative)",
               e["pinreg"], n)
    res.record("smallest eigenvalue of D over the samples (kg m^2; > 0: positive definite)", eig, n)
    res.record("D' - 2C skew: |N + N^T| / |D'|, D' by central differences (h = 1e-6)", e["skew"], n)


def run(n: int, seed: int = 0) -> list[CrossCheckResult]:
    results = []
    for name, mod in MODULES.items():
        arm = PinArm.load(name)
        qs = samples(mod, n, seed)
        res = CrossCheckResult(name)
        check_forward(mod, arm, qs, res)
        check_jacobians(mod, arm, qs, res)
        check_jacobian_computations(mod, arm, qs, res)
        check_gravity(mod, arm, qs, res)
        if has_ik(mod):
            (check_inverse_redundant if redundant(mod) else check_inverse)(mod, qs, res)
        check_dynamics(mod, arm, qs, res)
        results.append(res)
    return results


def report(results: list[CrossCheckResult], n: int, seed: int, seconds: float) -> str:
    lines = [
        "# Cross-check: generated kinematics and dynamics vs Pinocchio",
        "",
        f"Written by `python -m derive.crosscheck --samples {n} --seed {seed}` "
        f"(`make demo` runs it with 2000 samples).",
        "",
        "Each robot: the random configurations uniform over the joint ranges of",
        "`models/<robot>.toml`, plus edge configurations (each joint at 0, +-pi/2, pi where",
        "inside its range, and at both limits; all joints at edge values together).",
        "Left side: `rccl/kinematics/<robot>.py`, generated by `make derive` from the DH",
        "table. Right side: Pinocchio on `models/urdf/<robot>.urdf`. Errors are the largest",
        "absolute difference of any entry (SI units) unless marked relative.",
        "",
    ]
    for res in results:
        lines += [f"## {res.robot}", "", "| quantity | largest error | cases |", "|---|---|---|"]
        for key, err in res.errors.items():
            lines.append(f"| {key} | {err:.2e} | {res.counts[key]} |")
        notes = [f"- {k}: {v}" for k, v in res.notes.items()]
        if notes:
            lines += ["", "Notes:", *notes]
        lines.append("")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m derive.crosscheck", description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=2000, help="random configurations per robot")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=ROOT / "reports" / "crosscheck.md")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    results = run(args.samples, args.seed)
    text = report(results, args.samples, args.seed, time.perf_counter() - t0)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text)
    print(text)
    print(f"derive.crosscheck: {time.perf_counter() - t0:.1f} s; wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
