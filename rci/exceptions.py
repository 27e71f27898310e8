"""Exceptions raised by the RCI layer (one module for the whole package)."""
from __future__ import annotations

# a malformed robot model: defined by the robot description (models, its own root), named
# here too for programs that import it from rci
from rcci.models.exceptions import ModelError  # noqa: F401


class RCIError(Exception):
    """Base class of every error the RCI layer raises."""


# --- A.3 session errors -----------------------------------------------------------------
class SessionError(RCIError):
    """A session primitive was called in the wrong state (A.3 errors)."""


class AlreadyOpen(SessionError):
    """R_OPENP: the RCI control task is already open."""


class NotOpen(SessionError):
    """R_NOOPEN: the RCI control task is not open."""


class ControlInProgress(SessionError):
    """R_CONTROLP: a control is already in progress."""


class NoControl(SessionError):
    """R_NOCONTROL: no control is in progress."""


class BadFunction(SessionError):
    """R_NOFUNCTION: a control function is not callable."""


class DeviceError(RCIError):
    """R_BAD_OPEN / R_BAD_IOCTL / R_BAD_START: the robot link cannot be opened or used."""


class Timeout(RCIError):
    """R_TIMEOUT: no response from the robot within the allowed time."""


class RobotRefused(RCIError):
    """The robot answered a session request with an error frame (code and text)."""

    def __init__(self, code: int, text: str) -> None:
        self.code = code
        self.text = text
        super().__init__(f"robot refused: {text} (code {code})")


class RobotBusy(RobotRefused, DeviceError):
    """The robot is owned by another controller (an ERROR ``ST_BUSY`` answer to HELLO).

    ``text`` names the owner (pid, address, client name). The running control of the
    owner is not disturbed. A crashed owner can be taken over with ``takeover=True`` once
    the robot's watchdog has stopped its control (docs/protocol.md, "Ownership").
    """


# --- protocol (framing) errors ----------------------------------------------------------
class ProtocolError(RCIError):
    """A frame on the robot link is bad. ``code`` is the A.5.1 error number it maps to."""

    code: int = 13  # R_BTEST


class ChecksumError(ProtocolError):
    """A frame's CRC-16 does not match its contents (maps to R_CHKSUM)."""

    code = 11


class VersionError(ProtocolError):
    """A frame of a protocol version this side does not speak (``version``: the one received)."""

    def __init__(self, version: int, text: str) -> None:
        self.version = version
        super().__init__(text)


class FrameLengthError(ProtocolError):
    """A frame's length field is impossible, or a payload has the wrong size for its type."""


class UnknownFrameType(ProtocolError):
    """A well-formed frame carries a type this side does not know."""


class SequenceGap(ProtocolError):
    """A frame's sequence number is not the one expected (a frame was lost or repeated)."""

    code = 33  # R_SEQGAP

    def __init__(self, expected: int, got: int) -> None:
        self.expected = expected
        self.got = got
        super().__init__(f"sequence gap: expected {expected}, got {got}")


class LinkClosed(ProtocolError):
    """The other end closed the link (end of file on the byte stream)."""


# --- control-level termination ---------------------------------------------------------
class ControlTerminated(RCIError):
    """A control ended on an error; raised in the planning level (thesis: SIGHUP).

    ``termination`` is an ``rci.codes.Termination`` (code laid out as A.5.1 + detail).
    """

    def __init__(self, termination) -> None:
        self.termination = termination
        super().__init__(str(termination))

    @property
    def code(self) -> int:
        return self.termination.code


# --- recorder --------------------------------------------------------------------------
class LogFormatError(RCIError):
    """A recorder log file is malformed; the message names the file and the record/block."""

    def __init__(self, path: str, where: str, problem: str) -> None:
        self.path = str(path)
        self.where = where
        self.problem = problem
        super().__init__(f"{self.path}: {where}: {problem}")


class LogWriteError(RCIError):
    """The recorder could not write its log (a full disk, a quota, an I/O error).

    ``errno`` and ``strerror`` are the operating system's; ``written`` the records the file
    holds in whole blocks; ``lost`` those recorded but not written; ``where`` the byte or part
    of the file where writing stopped. The file stays readable to its last whole block.
    """

    def __init__(self, path: str, error: OSError, *, written: int, lost: int, where: str) -> None:
        self.path = str(path)
        self.errno = error.errno
        self.strerror = error.strerror or str(error)
        self.written = written
        self.lost = lost
        self.where = where
        super().__init__(path, where)

    def __str__(self) -> str:
        return (f"{self.path}: the recorder cannot write its log at {self.where}: {self.strerror}; "
                f"recording stopped: {self.written} records are in the file, {self.lost} recorded were not written")


class RecorderWarning(UserWarning):
    """The recorder stopped writing its log (``Recorder(on_write_error="warn")``, the default)."""
