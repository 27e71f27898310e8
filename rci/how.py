"""The `how` record: robot state as the robot reports it once per control cycle (thesis A.4).

Every A.4 field is kept with its thesis name and meaning. Added for a modern user (not in
A.4): ``cycle`` (the frame's sequence number), ``time_ns`` (the robot's own clock),
``rate_hz`` (the rate at which the robot executes the chg that answers this how: the
period until the next how; docs/protocol.md), ``robot_overruns`` (chg frames the
robot saw late or missing) and ``received`` (host monotonic arrival time, never on the wire).
``how`` must be treated as read-only by user code; the control task refills it in place
each cycle, so a reference taken once stays current.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import codes

NJ = 6      # joints on the PUMA 260 (the wire carries the actual count)
TPB = 3     # bytes returned by the teach pendant
ADC = 16    # analog-to-digital converter channels; the first NJ are the motor currents
ADC_MIN, ADC_MAX = -2048, 2047  # 12-bit two's complement


@dataclass
class How:
    """Robot state (A.4 ``struct how``) plus a cycle counter and timestamps.

    Units are the robot's raw units, as in the thesis: ``pos`` in encoder counts,
    ``adcr`` in 12-bit ADC counts. ``rci.conversions`` maps them to radians and N*m.
    """

    wc: int = 0                 # reserved for internal system use (A.4); we carry the link's word count
    status: int = 0             # robot error status word, 0 = no error (codes.ST_*)
    state: int = 0              # state flags: codes.CALIB_OK, TP_OK, ZINDEX_OK, POWER_ON, ZINDEX_ACTIVE
    exio: int = 0               # external I/O register (switch settings on the controller)
    pos: np.ndarray = field(default_factory=lambda: np.zeros(NJ, dtype=np.int64))  # encoder counts per joint
    inport1: int = 0            # parallel input port 1 (16 bits)
    outport1: int = 0           # value active on parallel output port 1 (16 bits)
    pendant: np.ndarray = field(default_factory=lambda: np.zeros(TPB, dtype=np.uint8))  # teach pendant bytes
    adcr: np.ndarray = field(default_factory=lambda: np.zeros(ADC, dtype=np.int64))  # ADC readings, 12-bit signed
    # --- ours ---
    cycle: int = -1             # sequence number of the HOW frame this came from (-1: none yet)
    time_ns: int = 0            # robot clock at the start of the cycle, ns (monotonic, robot's epoch)
    rate_hz: int = 36           # the rate the robot executes the chg answering this how at, Hz: the next
                                # how comes 1/rate_hz s later (a chg.rate command shows in the next how)
    robot_overruns: int = 0     # chg frames the robot received late or never (real-time mode)
    received: float = 0.0       # host time.monotonic() when the frame was decoded (s)

    @property
    def nj(self) -> int:
        """Number of joints."""
        return int(self.pos.shape[0])

    @property
    def calibrated(self) -> bool:
        """True if the robot reports CALIB_OK."""
        return bool(self.state & codes.CALIB_OK)

    @property
    def power(self) -> bool:
        """True if the arm power is on."""
        return bool(self.state & codes.POWER_ON)

    @property
    def motor_adc(self) -> np.ndarray:
        """The ADC channels reserved for the motor currents (first ``nj`` of ``adcr``)."""
        return self.adcr[: self.nj]

    def copy_from(self, other: "How") -> None:
        """Overwrite every field in place from ``other`` (keeps array identities when shapes match)."""
        for name in ("wc", "status", "state", "exio", "inport1", "outport1", "cycle",
                     "time_ns", "rate_hz", "robot_overruns", "received"):
            setattr(self, name, getattr(other, name))
        for name in ("pos", "pendant", "adcr"):
            mine, theirs = getattr(self, name), getattr(other, name)
            if mine.shape == theirs.shape:
                mine[:] = theirs
            else:
                setattr(self, name, theirs.copy())

    def copy(self) -> "How":
        """An independent snapshot."""
        h = How(pos=self.pos.copy(), pendant=self.pendant.copy(), adcr=self.adcr.copy())
        h.copy_from(self)
        return h
