"""Run-time checks of the control task (thesis A.5.1) and the joint limits they use.

Observed checks look at ``how`` (R_MAXPOS, R_MAXVEL, R_MAXCUR, plus a non-zero robot
status); request checks look at ``chg`` before it is sent (R_REQPOS, R_REQVEL, R_REQCUR,
R_TOOMANY, R_BADCMD, R_NANCMD). The six range checks can be switched off through
``chg.checking`` (bit map ``codes.CHECK_*``), as A.5.1 allows; the general ones cannot.
Positions are checked in joint space (radians), through the robot's encoder conversion,
so that the PUMA's coupled wrist is handled once, in ``rci.conversions``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from . import codes
from .chg import CUR, DAC_MAX, DAC_MIN, MOTION_NAMES, NONE, POS, STOP, STOPCAL, UNVALUED, VALUED, Chg, Cmd, Flag
from rcci.models import ModelError
from .how import How
from .rate import rate_from_code


class CheckFailed(Exception):
    """Internal: a check failed; carries the termination code and a detail string."""

    def __init__(self, code: int, detail: str) -> None:
        self.code = code
        self.detail = detail
        super().__init__(detail)


@dataclass
class CommandLimits:
    """Joint limits for the checks, in SI units, plus the robot's counts -> radians map.

    ``lower``/``upper`` joint angles (rad), ``max_velocity`` (rad/s), ``max_adc`` and
    ``max_dac`` absolute motor-current limits in ADC and DAC units. ``counts_to_rad``
    maps a full vector of encoder counts to joint angles.
    """

    lower: np.ndarray
    upper: np.ndarray
    max_velocity: np.ndarray
    max_adc: np.ndarray
    max_dac: np.ndarray
    counts_to_rad: Callable[[np.ndarray], np.ndarray]
    velocity_margin: float = 1.2   # observed speed may exceed max_velocity by this factor (encoder quantisation, noise)

    @classmethod
    def linear(cls, lower, upper, max_velocity, counts_per_rad, offset_counts=0.0,
               max_adc=2047, max_dac=2047) -> "CommandLimits":
        """CommandLimits for a robot with uncoupled joints: q = (counts - offset) / counts_per_rad."""
        cpr = np.asarray(counts_per_rad, dtype=float)
        off = np.asarray(offset_counts, dtype=float)
        n = len(np.atleast_1d(lower))
        return cls(np.asarray(lower, float), np.asarray(upper, float), np.asarray(max_velocity, float),
                   np.broadcast_to(np.asarray(max_adc, float), (n,)).copy(),
                   np.broadcast_to(np.asarray(max_dac, float), (n,)).copy(),
                   lambda c: (np.asarray(c, float) - off) / cpr)

    @classmethod
    def for_robot(cls, name: str) -> "CommandLimits":
        """CommandLimits from the robot model (``models``) and its conversions (``rci.conversions``).

        Current limits: the model's ``max_current`` (A) in ADC counts (``currents_to_adc``)
        and in DAC counts (kappa times the ADC value, eq. 4.34), capped at the 12-bit range.
        """
        from .conversions import Conversions
        from rcci.models import load_robot
        model = load_robot(name)
        conv = Conversions.from_model(model)
        adc = np.abs(np.asarray(conv.currents_to_adc(np.asarray(model.max_current, float)), float))
        dac = adc * np.asarray(conv.kappa, float)
        return cls(np.asarray(model.lower, float), np.asarray(model.upper, float),
                   np.asarray(model.max_velocity, float), np.minimum(adc, 2047.0), np.minimum(dac, 2047.0),
                   conv.counts_to_angles)


class Checker:
    """Applies the A.5.1 checks once per cycle; raises ``CheckFailed`` on the first failure."""

    def __init__(self, nj: int, nadc: int, limits: CommandLimits | None, *, max_commands: int = 16,
                 checking: int = codes.CHECK_ALL) -> None:
        self.nj, self.nadc = nj, nadc
        self.limits = limits
        # estimate: the thesis gives no figure for R_TOOMANY; 16 lets a cycle carry a
        # motion and a setparam for every joint of a 6-joint arm plus four others.
        self.max_commands = max_commands
        self.checking = checking
        self._q_prev: np.ndarray | None = None
        self._skip_velocity = True
        # last POS target per joint (counts) while the joint stays in position mode: a
        # servo lags its command by up to a cycle, so a requested velocity is measured from
        # the previous request, not from the (lagging) measured position
        self._last_pos: dict[int, int] = {}

    def reset(self) -> None:
        """Forget the previous position (new control, or encoder counts were reset)."""
        self._q_prev = None
        self._skip_velocity = True
        self._last_pos = {}

    # --- observed ---------------------------------------------------------------------
    def check_how(self, how: How, period: float) -> np.ndarray | None:
        """Check a fresh ``how``; returns the joint angles (rad) when limits are known."""
        if how.status:
            raise CheckFailed(codes.for_status(how.status),
                        f"how.status = {how.status}: {codes.STATUS_TEXT.get(how.status, 'unknown status')}")
        lim = self.limits
        chk = self.checking
        if chk & codes.CHECK_MAXCUR and lim is not None:
            over = np.abs(how.adcr[: self.nj]) > lim.max_adc
            if over.any():
                j = int(np.argmax(over))
                raise CheckFailed(codes.make_code(codes.R_MAXCUR, codes.F_RANGE | codes.F_SEVERE, j),
                            f"joint {j + 1}: |adcr| = {abs(int(how.adcr[j]))} > {lim.max_adc[j]:.0f}")
        if lim is None:
            return None
        q = np.asarray(lim.counts_to_rad(how.pos), dtype=float)
        calibrated = how.calibrated
        if chk & codes.CHECK_MAXPOS and calibrated:
            bad = (q < lim.lower) | (q > lim.upper)
            if bad.any():
                j = int(np.argmax(bad))
                raise CheckFailed(codes.make_code(codes.R_MAXPOS, codes.F_RANGE | codes.F_SEVERE, j),
                            f"joint {j + 1} at {q[j]:.4f} rad, range [{lim.lower[j]:.4f}, {lim.upper[j]:.4f}]")
        if chk & codes.CHECK_MAXVEL and self._q_prev is not None and not self._skip_velocity:
            v = np.abs(q - self._q_prev) / period
            bad = v > lim.max_velocity * lim.velocity_margin
            if bad.any():
                j = int(np.argmax(bad))
                raise CheckFailed(codes.make_code(codes.R_MAXVEL, codes.F_RANGE | codes.F_SEVERE, j),
                            f"joint {j + 1} moving at {v[j]:.3f} rad/s, limit {lim.max_velocity[j]:.3f} rad/s")
        self._q_prev = q
        self._skip_velocity = False
        return q

    # --- requested --------------------------------------------------------------------
    def check_chg(self, chg: Chg, how: How, q_now: np.ndarray | None, period: float) -> int:
        """Validate the pending commands of ``chg``; returns the new checking mask to use.

        Raises CheckFailed for NaN values, bad command codes, too many commands, and the REQ
        range checks. Nothing is modified.
        """
        check_structure(chg)
        n = 0
        self._pending_clear: set[int] = set()
        motion_target: dict[int, int] = {}
        stopcal = False
        for i, c in enumerate(chg.motion):
            if not _com(c, f"motion[{i}]", i):
                continue
            n += 1
            if c.com not in MOTION_NAMES or c.com == NONE:
                raise CheckFailed(codes.make_code(codes.R_BADCMD, codes.F_USER, i), f"chg.motion[{i}].com = {c.com!r} is not POS/CUR/STOP/STOPCAL")
            if c.com != POS:
                self._pending_clear.add(i)
            if c.com in (STOP,):
                continue
            v = _value(c, f"motion[{i}]")
            if c.com == CUR:
                if not (DAC_MIN <= v <= DAC_MAX):
                    raise CheckFailed(codes.make_code(codes.R_BADCMD, codes.F_USER, i), f"chg.motion[{i}] CUR {v} outside the 12-bit DAC range")
                if self.checking & codes.CHECK_REQCUR and self.limits is not None and abs(v) > self.limits.max_dac[i]:
                    raise CheckFailed(codes.make_code(codes.R_REQCUR, codes.F_RANGE, i),
                                f"joint {i + 1}: CUR {v} exceeds {self.limits.max_dac[i]:.0f}")
            elif c.com == POS:
                motion_target[i] = v
            elif c.com == STOPCAL:
                stopcal = True
        for i, c in enumerate(chg.setparam):
            if _com(c, f"setparam[{i}]", i):
                n += 1
                _value(c, f"setparam[{i}]")
        new_checking = self.checking
        for name in VALUED:
            c: Cmd = getattr(chg, name)
            if not _com(c, name):
                continue
            n += 1
            v = _value(c, name)
            if name == "hand" and v not in (1, 2):
                raise CheckFailed(codes.make_code(codes.R_BADCMD, codes.F_USER), f"chg.hand.value = {v} is neither OPEN (1) nor CLOSE (2)")
            if name == "rate":
                try:
                    rate_from_code(v)
                except ValueError as e:
                    raise CheckFailed(codes.make_code(codes.R_BADCMD, codes.F_USER), str(e)) from None
            if name == "checking":
                if not (0 <= v <= codes.CHECK_ALL):
                    raise CheckFailed(codes.make_code(codes.R_BADCMD, codes.F_USER), f"chg.checking.value = {v:#x} has bits outside {codes.CHECK_ALL:#x}")
                new_checking = v
            if name == "zindex" and not (0 <= v < (1 << self.nj)):
                raise CheckFailed(codes.make_code(codes.R_BADCMD, codes.F_USER), f"chg.zindex.value = {v:#x} names joints beyond {self.nj}")
            if name == "adco" and not (0 <= v < self.nadc):
                raise CheckFailed(codes.make_code(codes.R_BADCMD, codes.F_USER), f"chg.adco.value = {v} is not an ADC channel (0..{self.nadc - 1})")
            if name in ("outport1", "pendant") and not (0 <= v <= 0xFFFF):
                raise CheckFailed(codes.make_code(codes.R_BADCMD, codes.F_USER), f"chg.{name}.value = {v} does not fit in 16 bits")
        for name in UNVALUED:
            if _com(getattr(chg, name), name):
                n += 1
        if n > self.max_commands:
            raise CheckFailed(codes.make_code(codes.R_TOOMANY), f"{n} commands in one cycle, at most {self.max_commands}")
        if motion_target and self.limits is not None:
            self._check_targets(motion_target, how, q_now, period, new_checking)
        for i in self._pending_clear:
            self._last_pos.pop(i, None)
        self._last_pos.update(motion_target)
        if stopcal or chg.stop.com:
            self.reset()   # encoder counts jump on STOPCAL: no velocity check next cycle
        return new_checking

    def _check_targets(self, target: dict[int, int], how: How, q_now: np.ndarray | None,
                       period: float, checking: int) -> None:
        lim = self.limits
        assert lim is not None
        base = np.array(how.pos, dtype=float)
        for i, v in self._last_pos.items():
            base[i] = v
        counts = base.copy()
        for i, v in target.items():
            counts[i] = v
        q_t = np.asarray(lim.counts_to_rad(counts), dtype=float)
        if checking & codes.CHECK_REQPOS and how.calibrated:
            bad = (q_t < lim.lower) | (q_t > lim.upper)
            if bad.any():
                j = int(np.argmax(bad))
                raise CheckFailed(codes.make_code(codes.R_REQPOS, codes.F_RANGE, j),
                            f"joint {j + 1}: requested {q_t[j]:.4f} rad, range [{lim.lower[j]:.4f}, {lim.upper[j]:.4f}]")
        if checking & codes.CHECK_REQVEL:
            q0 = np.asarray(lim.counts_to_rad(base), dtype=float)
            v = np.abs(q_t - q0) / period
            bad = v > lim.max_velocity
            if bad.any():
                j = int(np.argmax(bad))
                raise CheckFailed(codes.make_code(codes.R_REQVEL, codes.F_RANGE, j),
                            f"joint {j + 1}: requested step needs {v[j]:.3f} rad/s, limit {lim.max_velocity[j]:.3f} rad/s")


def check_structure(chg: Chg) -> None:
    """CheckFailed(R_BADCMD) naming the entry if user code replaced part of ``chg`` with something else."""
    for name in ("motion", "setparam"):
        seq = getattr(chg, name)
        if not isinstance(seq, list) or len(seq) != chg.nj:
            raise CheckFailed(codes.make_code(codes.R_BADCMD, codes.F_USER),
                        f"chg.{name} was replaced by {type(seq).__name__} {seq!r:.40}: it must stay a list of "
                        f"{chg.nj} commands (set chg.{name}[i].com and .value instead)")
        for i, c in enumerate(seq):
            if not isinstance(c, Cmd):
                raise CheckFailed(codes.make_code(codes.R_BADCMD, codes.F_USER, i),
                            f"chg.{name}[{i}] = {c!r:.40} is not a command: use chg.{name}[{i}].issue(com, value)")
    for name in VALUED:
        if not isinstance(getattr(chg, name), Cmd):
            raise CheckFailed(codes.make_code(codes.R_BADCMD, codes.F_USER),
                        f"chg.{name} = {getattr(chg, name)!r:.40} is not a command: use chg.{name}.issue(value)")
    for name in UNVALUED:
        if not isinstance(getattr(chg, name), (Flag, Cmd)):
            raise CheckFailed(codes.make_code(codes.R_BADCMD, codes.F_USER),
                        f"chg.{name} = {getattr(chg, name)!r:.40} is not a command: set chg.{name}.com = 1")


def _com(c: Cmd | Flag, where: str, joint: int | None = None) -> int:
    """The command code of an entry (0: none); CheckFailed(R_BADCMD) unless an integer 0..255."""
    com = c.com
    if isinstance(com, (bool, np.bool_)):
        return int(com)
    if not isinstance(com, (int, np.integer)):
        raise CheckFailed(codes.make_code(codes.R_BADCMD, codes.F_USER, joint),
                    f"chg.{where}.com = {com!r:.40} is not an integer command code")
    if not 0 <= com <= 255:
        raise CheckFailed(codes.make_code(codes.R_BADCMD, codes.F_USER, joint),
                    f"chg.{where}.com = {int(com)} is not a command code (0..255)")
    return int(com)


def _value(c: Cmd, where: str) -> int:
    """The integer value of a command: CheckFailed(R_NANCMD) for NaN or infinity, CheckFailed(R_BADCMD) for
    anything that is not a real number (text such as ``"12"`` included) or does not fit in 32 bits."""
    v = c.value
    if isinstance(v, (int, np.integer)) and not isinstance(v, bool):
        out = int(v)
    else:
        if isinstance(v, (str, bytes, bytearray, bool, np.bool_)) or v is None:
            raise CheckFailed(codes.make_code(codes.R_BADCMD, codes.F_USER),
                        f"chg.{where}.value = {v!r:.40} is a {type(v).__name__}, not a number")
        try:
            f = float(v)
        except (TypeError, ValueError):
            raise CheckFailed(codes.make_code(codes.R_BADCMD, codes.F_USER),
                        f"chg.{where}.value = {v!r:.40} is not a number") from None
        if not math.isfinite(f):
            raise CheckFailed(codes.make_code(codes.R_NANCMD, codes.F_USER), f"chg.{where}.value = {v!r}")
        out = int(round(f))
    if not -2**31 <= out < 2**31:
        raise CheckFailed(codes.make_code(codes.R_BADCMD, codes.F_USER),
                    f"chg.{where}.value = {out} does not fit in the link's 32-bit value field")
    return out
