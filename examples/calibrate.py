"""A calibration program: brings an uncalibrated arm to calibrated with zindex and STOPCAL (A.4).

The encoder counters of an uncalibrated arm read an arbitrary count. The program

1. switches arm power on and puts every joint in calibration mode (``chg.zindex``);
2. creeps every joint (POS a few counts further each cycle) until it stops on the index
   mark of its motor encoder and freezes there (its count no longer changes);
3. reads the joint potentiometers (ADC channels nj..2nj-1) for a coarse absolute angle,
   turns it into the motor count the mark must have (a mark sits at every multiple of the
   counts per motor revolution), and sends STOPCAL with that count.

The robot then reports CALIB_OK. The pot scaling (4000 counts over the joint range) is the
one docs/simula.md documents for the simulated arm; a real arm's monitor documents its own.

    python examples/calibrate.py socket://127.0.0.1:7600
    python examples/calibrate.py --simula "--seed 3"       # own (uncalibrated) lockstep simula
"""
from __future__ import annotations

import argparse
import sys
from contextlib import ExitStack

import numpy as np

from rci import codes
from rci.chg import POS, STOPCAL
from rci.conversions import Conversions
from rcci.models import load_robot
from rci.session import Session

CREEP_COUNTS = 20          # counts per cycle while searching for the index mark
STILL_CYCLES = 3           # cycles without a count change = frozen on the mark
POT_SPAN = 4000.0          # potentiometer ADC counts over the joint range (simula's scaling)


class Calibrator:
    """The control function: zindex, creep to the marks, STOPCAL with the true counts."""

    def __init__(self, session: Session, robot: str = "puma260") -> None:
        self.s = session
        self.model = load_robot(robot)
        self.conv = Conversions.from_model(self.model)
        self.nj = self.conv.n
        self.direction = np.sign(np.diag(self.conv.R))     # creep towards increasing joint angle
        self.per_rev = np.asarray(self.model.conversion.encoder_counts_per_motor_rev.values, float)
        self.phase = "start"
        self.target: np.ndarray | None = None
        self.last: np.ndarray | None = None
        self.still = np.zeros(self.nj, dtype=int)
        self.marks: np.ndarray | None = None

    def coarse_angles(self) -> np.ndarray:
        """Joint angles (rad) from the potentiometers, about 0.1 deg resolution."""
        pots = np.asarray(self.s.how.adcr[self.nj:2 * self.nj], float)
        return self.model.lower + (pots + POT_SPAN / 2) / POT_SPAN * (self.model.upper - self.model.lower)

    def __call__(self) -> None:
        how, chg = self.s.how, self.s.chg
        if self.phase == "start":
            chg.power_on.issue()
            chg.zindex.issue(1, (1 << self.nj) - 1)
            self.phase = "zindex"
        elif self.phase == "zindex":
            if how.state & codes.ZINDEX_ACTIVE and how.power:
                self.target = how.pos.astype(float)
                self.last = how.pos.copy()
                self.phase = "creep"
        elif self.phase == "creep":
            self.still = np.where(how.pos == self.last, self.still + 1, 0)
            self.last = how.pos.copy()
            moving = self.still < STILL_CYCLES
            if not moving.any():
                e = self.conv.angles_to_counts(self.coarse_angles())
                self.marks = np.rint(e / self.per_rev) * self.per_rev
                for j in range(self.nj):
                    chg.motion[j].issue(STOPCAL, int(self.marks[j]))
                self.phase = "stopcal"
                return
            self.target = np.where(moving, self.target + CREEP_COUNTS * self.direction, self.target)
            for j in np.flatnonzero(moving):
                chg.motion[j].issue(POS, int(self.target[j]))
        elif self.phase == "stopcal":
            if how.calibrated:
                self.phase = "done"


def calibrate(session: Session, timeout: float = 120.0) -> Calibrator:
    """Run the calibration control until the robot reports CALIB_OK; returns the calibrator."""
    cal = Calibrator(session, session.robot)
    session.control(cal)
    if not session.wait(until=lambda: cal.phase == "done", seconds=timeout):
        session.release()
        raise TimeoutError(f"calibration not finished after {timeout} s (phase {cal.phase})")
    session.release()
    return cal


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("url", nargs="?", default="socket://127.0.0.1:7600")
    ap.add_argument("--robot", default="puma260")
    ap.add_argument("--rate", type=int, default=36)
    ap.add_argument("--simula", metavar="ARGS", help="start a lockstep simula with these options and use it")
    args = ap.parse_args(argv)
    with ExitStack() as stack:
        url = args.url
        if args.simula is not None:
            from rci.simula.process import SimulaProcess
            url = stack.enter_context(SimulaProcess(*args.simula.split(), robot=args.robot, lockstep=True)).url
        s = stack.enter_context(Session(url, args.robot, rate_hz=args.rate))
        if s.how.state & codes.CALIB_OK:
            print("already calibrated")
            return 0
        cal = calibrate(s)
        angles = cal.conv.counts_to_angles(s.how.pos)
        print("calibrated; joint angles (deg):", np.array2string(np.degrees(angles), precision=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
