"""A recorder log in SI units: joint positions, velocities and torques, measured and commanded, and the pose T6.

A ``.rcilog`` holds what crossed the link: encoder counts (``how_pos``), ADC counts of the
motor currents (``how_adcr``), and the commands as sent (``chg_motion_com`` / ``_value``: POS
in encoder counts, CUR in DAC units). ``log_in_si(log)`` turns them into the quantities a
program thinks in, with the conversions of thesis 4.4.3 (``rci.conversions``, the log's own
robot) and the forward kinematics of the robot's DH table (thesis 3.16-3.18, ``models``: the
same table the generated ``rccl.kinematics.<robot>.fk`` is derived from; T6 is link 6 in the
base frame, metres):

* measured: joint values ``q`` (rad; m on a prismatic joint) from the encoders, their rates
  ``qd`` (rad/s, m/s: central differences over the record times), the motor currents
  (A, eq. C.1) and the joint torques they make (N m, N: eq. 4.36), every link's pose;
* commanded: ``q_cmd`` where the joint was sent a POS command in that cycle, ``tau_cmd``
  where it was sent CUR (eq. 4.35 inverted), NaN elsewhere. A wrist joint whose motors are
  coupled (G, R not diagonal) has a commanded value only when every motor it depends on was
  commanded the same way. Commands are not carried forward: NaN means "not sent this cycle".

The exports (``rci.export``), the replay (``rcci.view.replay``) and the plot (``rci.plot``) all
read a log through this module, so the three show the same numbers.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rcci.models import load_robot

from .chg import CUR, POS
from .conversions import Conversions
from .recorder import Log


@dataclass(frozen=True)
class LogSI:
    """One log in SI units, one row per record (arrays ``(N, n)`` unless said otherwise)."""

    robot: str
    joint_names: tuple[str, ...]
    prismatic: np.ndarray     # (n,) bool: the joint's values are m, m/s, N
    t: np.ndarray             # (N,) s from the first record: the robot's clock when it ticks, else the host's
    q: np.ndarray             # measured joint values, rad / m
    qd: np.ndarray            # measured joint rates, rad/s / m/s
    q_cmd: np.ndarray         # commanded (POS) joint values, NaN where not sent
    qd_cmd: np.ndarray        # rates of the commanded values, NaN around a gap
    current: np.ndarray | None    # motor currents, A (None: the log has fewer ADC channels than joints)
    tau: np.ndarray | None        # joint torques from the measured currents, N m / N (eq. 4.36)
    tau_cmd: np.ndarray           # joint torques commanded by CUR, N m / N, NaN where not sent
    links: np.ndarray         # (N, n, 4, 4) measured pose of links 1..n in the base frame; links[:, -1] is T6
    T6_cmd: np.ndarray        # (N, 4, 4) T6 at the commanded joint values, NaN where q_cmd is incomplete

    @property
    def T6(self) -> np.ndarray:
        """(N, 4, 4) measured T6: link 6 in the base frame, m."""
        return self.links[:, -1]

    def unit(self, quantity: str) -> list[str]:
        """The unit of each joint's value of ``quantity`` (``"q"``, ``"qd"``, ``"tau"``; suffix ``_cmd`` allowed)."""
        base = quantity.removesuffix("_cmd")
        table = {"q": ("rad", "m"), "qd": ("rad/s", "m/s"), "tau": ("N m", "N")}[base]
        return [table[1] if p else table[0] for p in self.prismatic]


def record_times(log: Log) -> np.ndarray:
    """Seconds from the first record: the robot's clock where it advances every record, else the host's ``t``."""
    r = log.records
    ns = np.asarray(r["robot_time_ns"], dtype=np.int64)
    if len(ns) > 1 and np.all(np.diff(ns) > 0):
        return (ns - ns[0]) * 1e-9
    t = np.asarray(r["t"], dtype=float)
    return t - t[0] if len(t) else t


def _coupled(matrix: np.ndarray, values: np.ndarray, sent: np.ndarray) -> np.ndarray:
    """``values @ matrix.T`` per row, NaN in a column that depends on a value not ``sent``."""
    needs = np.abs(matrix) > 0                                 # (n_out, n_in)
    complete = ~((~sent)[:, None, :] & needs[None]).any(axis=2)  # (N, n_out)
    out = np.where(sent, values, 0.0) @ matrix.T
    return np.where(complete, out, np.nan)


def _rates(x: np.ndarray, t: np.ndarray) -> np.ndarray:
    """d x / d t per column (central differences, one-sided at the ends); NaN where x is."""
    if len(t) < 2:
        return np.full_like(x, np.nan)
    return np.gradient(x, t, axis=0)


def poses(model, q: np.ndarray) -> np.ndarray:
    """(N, n, 4, 4) links 1..n in the base frame at each row of ``q`` (DH table, thesis eq. 4.9); NaN rows stay NaN."""
    out = np.full((len(q), model.n_joints, 4, 4), np.nan)
    for i, row in enumerate(q):
        if np.all(np.isfinite(row)):
            out[i] = model.base_to_link(row)
    return out


def log_in_si(log: Log, conv: Conversions | None = None) -> LogSI:
    """The log ``log`` in SI units (module docstring); ``conv`` defaults to the log's robot's data file."""
    robot = str(log.meta["robot"])
    model = load_robot(robot)
    conv = conv or Conversions.from_model(model)
    n = conv.n
    r = log.records
    t = record_times(log)
    q = conv.counts_to_angles(np.asarray(r["how_pos"], float)) if len(r) else np.zeros((0, n))
    com = np.asarray(r["chg_motion_com"]).reshape(len(r), n)
    value = np.asarray(r["chg_motion_value"], float).reshape(len(r), n)
    # e = R q + e0, so q = R^-1 (e - e0): joint j needs every motor m with R^-1[j, m] != 0
    q_cmd = _coupled(conv.R_inv, value - conv.encoder_offset, com == POS)
    # t_j = G^T t_s, t_s = v_dac / k_dac: joint j needs every motor m with G[m, j] != 0
    tau_cmd = _coupled(conv.G.T, value / conv.k_dac, com == CUR)
    adc = np.asarray(r["how_adcr"], float).reshape(len(r), -1)
    current = tau = None
    if adc.shape[1] >= n:
        current = conv.adc_to_currents(adc[:, :n])
        tau = conv.adc_to_joint_torques(adc[:, :n])
    links = poses(model, q)
    T6_cmd = poses(model, q_cmd)[:, -1] if len(r) else np.zeros((0, 4, 4))
    return LogSI(robot=robot, joint_names=tuple(j.name for j in model.joints),
                 prismatic=np.array([j.kind == "prismatic" for j in model.joints]), t=t,
                 q=q, qd=_rates(q, t), q_cmd=q_cmd, qd_cmd=_rates(q_cmd, t), current=current, tau=tau,
                 tau_cmd=tau_cmd, links=links, T6_cmd=T6_cmd)


def quaternion(R: np.ndarray) -> np.ndarray:
    """Unit quaternions ``(x, y, z, w)`` of rotation matrices ``R`` (..., 3, 3), w >= 0; NaN in, NaN out."""
    R = np.asarray(R, dtype=float)
    m = R.reshape(-1, 3, 3)
    d = np.stack([m[:, 0, 0], m[:, 1, 1], m[:, 2, 2]], axis=1)
    # Shepperd's choice: compute the largest of 4w^2, 4x^2, 4y^2, 4z^2 from the diagonal and
    # the others from the off-diagonal sums/differences divided by it (never a small divisor;
    # 180-degree turns, common in T6, are where the plain formula fails)
    big = np.stack([1 + d.sum(1), 1 + d[:, 0] - d[:, 1] - d[:, 2], 1 - d[:, 0] + d[:, 1] - d[:, 2],
                    1 - d[:, 0] - d[:, 1] + d[:, 2]], axis=1)
    k = np.argmax(np.nan_to_num(big, nan=0.0), axis=1)
    s = 0.5 * np.sqrt(np.maximum(big[np.arange(len(m)), k], 0.0))       # the largest component
    f = np.where(s > 0, 0.25 / np.where(s > 0, s, 1.0), np.nan)
    a = m[:, 2, 1] - m[:, 1, 2]
    b = m[:, 0, 2] - m[:, 2, 0]
    c = m[:, 1, 0] - m[:, 0, 1]
    xy = m[:, 0, 1] + m[:, 1, 0]
    xz = m[:, 0, 2] + m[:, 2, 0]
    yz = m[:, 1, 2] + m[:, 2, 1]
    cases = [np.stack([a * f, b * f, c * f, s], 1),      # w largest
             np.stack([s, xy * f, xz * f, a * f], 1),     # x largest
             np.stack([xy * f, s, yz * f, b * f], 1),     # y largest
             np.stack([xz * f, yz * f, s, c * f], 1)]     # z largest
    out = np.choose(k[:, None], cases)
    out = np.where(out[:, 3:4] < 0, -out, out)
    out = out / np.linalg.norm(out, axis=1, keepdims=True)
    return out.reshape(R.shape[:-2] + (4,))
