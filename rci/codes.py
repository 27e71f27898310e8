"""RCI termination codes and robot state/status words (the thesis's <robot/errors.h> and <robot/cmdk.h>).

A termination code is a 32-bit word laid out as thesis A.5.1 says: the high 16 bits hold
status flags describing the error condition, the low 16 bits a specific error number.
The thesis names the errors but prints no numeric values; the numbers below are ours.
User-generated codes (A.5.2) are any number at or above ``R_USER_BASE``.
"""
from __future__ import annotations

from dataclasses import dataclass
import sys

# --- status flags (high 16 bits of a termination code) --------------------------------
F_SEVERE = 1 << 16      # severe: arm power is switched off by the implicit release
F_RANGE = 1 << 17       # a range check on how or chg failed (A.5.1 first group)
F_COMM = 1 << 18        # the robot link failed (checksum, timeout, dead link, framing)
F_ROBOT = 1 << 19       # the robot controller itself reported the error (how.status)
F_USER = 1 << 20        # the user's control functions caused it (exception, NaN, overrun)
F_JOINT_SHIFT = 24      # bits 24..27: 1 + index of the offending joint, 0 if none
F_JOINT_MASK = 0xF << F_JOINT_SHIFT

# --- error numbers (low 16 bits) -------------------------------------------------------
# A.5.1 range checks (each can be disabled through chg.checking, see CHECK_* bits)
R_MAXVEL = 1    # maximum velocity exceeded (observed, from how.pos)
R_MAXCUR = 2    # maximum current exceeded (observed, from how.adcr)
R_MAXPOS = 3    # maximum position exceeded (observed, how.pos out of range)
R_REQVEL = 4    # requested velocity too great (chg POS step too large)
R_REQCUR = 5    # requested current too great (chg CUR value)
R_REQPOS = 6    # requested position out of bounds (chg POS value)
# A.5.1 general errors
R_TOOMANY = 10  # too many commands sent to robot at once
R_CHKSUM = 11   # bad checksum on data received from the robot controller
R_BADCMD = 12   # bad command specification in chg
R_BTEST = 13    # test failure of the host-robot communication link (bad framing, dead link)
# A.3 errors that can also end a control
R_TIMEOUT = 20  # control task timed out, no response from robot
# Our additions (a modern host needs to name these)
R_OVERRUN = 30  # a control cycle took longer than the sample period
R_USERFUNC = 31  # a user control function raised an exception
R_NANCMD = 32   # a user control function left NaN/inf or a non-integer in chg
R_SEQGAP = 33   # a how frame was lost (sequence number gap)
R_ROBOT = 34    # the robot reported a non-zero how.status
R_INTERRUPT = 35  # Ctrl-C (SIGINT) at the planning level
R_CHGLATE = 36  # the robot got no chg in time for several cycles in a row although the control
                # functions were quick: commands lost or delayed between the host and the robot
R_USER_BASE = 0x1000  # A.5.2: codes >= this are the programmer's own

# --- chg.checking bits (A.5.1: the six range checks may be disabled) -------------------
CHECK_MAXVEL = 1 << 0
CHECK_MAXCUR = 1 << 1
CHECK_MAXPOS = 1 << 2
CHECK_REQVEL = 1 << 3
CHECK_REQCUR = 1 << 4
CHECK_REQPOS = 1 << 5
CHECK_ALL = 0x3F

# --- how.state flags (A.4) -------------------------------------------------------------
CALIB_OK = 1 << 0   # the robot is calibrated
TP_OK = 1 << 1      # the teach pendant is communicating properly
ZINDEX_OK = 1 << 2  # the calibration (zindex) procedure was successful
POWER_ON = 1 << 3   # arm power is on (ours: a modern user wants to see it)
ZINDEX_ACTIVE = 1 << 4  # ours: at least one joint is in calibration (zindex) mode

# --- how.status values (robot error status word; 0 = no error) -----------------------
ST_OK = 0
ST_NOT_CALIBRATED = 1   # motion refused: calibrate first (zindex / STOPCAL)
ST_JOINT_LIMIT = 2      # a joint hit its mechanical stop
ST_WATCHDOG = 3         # robot stopped the arm: no chg arrived in time
ST_BAD_COMMAND = 4      # the robot rejected a command in chg
ST_POWER_FAULT = 5      # arm power failed
ST_EXTERNAL_STOP = 6    # emergency stop pressed
ST_ENCODER_RANGE = 7    # an encoder counter left the 32-bit range of the link (saturated)
ST_BUSY = 8             # ERROR only: the robot is owned by another controller (HELLO refused)
ST_BAD_FRAME = 9        # the robot received a corrupt frame from its controller and ended the control

STATUS_TEXT = {
    ST_OK: "no error",
    ST_NOT_CALIBRATED: "robot not calibrated, motion refused",
    ST_JOINT_LIMIT: "joint hit its mechanical stop",
    ST_WATCHDOG: "robot watchdog: no chg in time, arm stopped",
    ST_BAD_COMMAND: "robot rejected a command",
    ST_POWER_FAULT: "arm power fault",
    ST_EXTERNAL_STOP: "emergency stop",
    ST_ENCODER_RANGE: "encoder counter out of the link's 32-bit range",
    ST_BUSY: "robot owned by another controller",
    ST_BAD_FRAME: "robot received a corrupt frame from the controller",
}

REASONS = {
    R_MAXVEL: "maximum velocity exceeded",
    R_MAXCUR: "maximum current exceeded",
    R_MAXPOS: "maximum position exceeded",
    R_REQVEL: "requested velocity too great",
    R_REQCUR: "requested current too great",
    R_REQPOS: "requested position out of bounds",
    R_TOOMANY: "too many commands sent to robot at once",
    R_CHKSUM: "bad checksum on data received from robot controller",
    R_BADCMD: "bad command specification in chg",
    R_BTEST: "robot communication link failure",
    R_TIMEOUT: "control task timed out, no response from robot",
    R_OVERRUN: "control cycle overran the sample period",
    R_USERFUNC: "user control function raised an exception",
    R_NANCMD: "user control function produced NaN or non-integer command",
    R_SEQGAP: "how packet lost (sequence gap)",
    R_ROBOT: "robot controller reported an error",
    R_INTERRUPT: "interrupted from the keyboard",
    R_CHGLATE: "commands reached the robot late or never (link)",
}

NAMES = {v: k for k, v in globals().items() if k.startswith("R_") and isinstance(v, int) and k != "R_USER_BASE"}


def for_status(status: int) -> int:
    """The termination code for a non-zero robot status word (how.status or an ERROR frame).

    The robot's own link-fault reports keep the link codes, so the fault is blamed on the
    link and not on the robot: its watchdog (no chg in time) is R_CHGLATE, a corrupt frame
    it received is R_CHKSUM; every other status is R_ROBOT. All are severe.
    """
    if status == ST_WATCHDOG:
        return make_code(R_CHGLATE, F_COMM | F_SEVERE)
    if status == ST_BAD_FRAME:
        return make_code(R_CHKSUM, F_COMM | F_SEVERE)
    return make_code(R_ROBOT, F_ROBOT | F_SEVERE)


def make_code(number: int, flags: int = 0, joint: int | None = None) -> int:
    """Pack an error number, status flags and optional joint index (0-based) into a termination code."""
    code = (flags & 0xFFFF0000) | (number & 0xFFFF)
    if joint is not None:
        code = (code & ~F_JOINT_MASK) | ((joint + 1) << F_JOINT_SHIFT)
    return code


def error_number(code: int) -> int:
    """The specific error number (low 16 bits) of a termination code."""
    return code & 0xFFFF


def joint_of(code: int) -> int | None:
    """The 0-based joint index stored in a termination code, or None."""
    j = (code & F_JOINT_MASK) >> F_JOINT_SHIFT
    return j - 1 if j else None


def is_severe(code: int) -> bool:
    """True if the code asks for arm power off on release."""
    return bool(code & F_SEVERE)


def reason(code: int) -> str | None:
    """Information string for a termination code (None if the number is not known)."""
    number = error_number(code)
    if number in REASONS:
        text = REASONS[number]
    elif number >= R_USER_BASE:
        text = f"user-generated error {number:#x}"
    else:
        return None
    j = joint_of(code)
    return text if j is None else f"{text} (joint {j + 1})"


def print_terminate_code(code: int, message: str | None = None, file=None) -> int:
    """Print ``TERMINATE/ <message> / <reason>`` (thesis A.5.4); returns 0, or -1 if the code is unknown.

    With ``message`` None no message is printed; with an unknown code no reason is printed.
    """
    out = sys.stderr if file is None else file
    why = reason(code)
    parts = ["TERMINATE/"]
    if message is not None:
        parts.append(f" {message} /")
    if why is not None:
        parts.append(f" {why}")
    print("".join(parts), file=out, flush=True)
    return 0 if why is not None else -1


@dataclass(frozen=True)
class Termination:
    """Why a control ended: the A.5.1 code plus a human-readable detail (what, where)."""

    code: int
    detail: str = ""
    cycle: int = -1

    @property
    def number(self) -> int:
        return error_number(self.code)

    @property
    def name(self) -> str:
        return NAMES.get(self.number, f"R_{self.number:#x}")

    @property
    def severe(self) -> bool:
        return is_severe(self.code)

    def __str__(self) -> str:
        why = reason(self.code) or f"code {self.code:#010x}"
        where = f" at cycle {self.cycle}" if self.cycle >= 0 else ""
        extra = f": {self.detail}" if self.detail else ""
        return f"{self.name}{where}: {why}{extra}"
