"""The zero-gravity program of thesis section 2.2.2: current mode with gravity compensation.

Every cycle the control function reads the encoder counts, converts them to joint angles,
computes the gravity loading torques (eq. 4.24, generated closed-form code) and sets each
joint's motor current to hold exactly that load (``tortodac``). The arm then floats: it
does not fall, and it moves when pushed.

    python examples/zero_gravity.py socket://127.0.0.1:7600      # type <CR> to exit
    python examples/zero_gravity.py --simula "-c --warm" --cycles 180   # own lockstep simula
    python examples/zero_gravity.py --params fitted.toml ...   # calib's fitted sigma and gravity

As in the thesis, the first control function is a dummy and the second does the work.
"""
from __future__ import annotations

import argparse
import sys
from contextlib import ExitStack

import numpy as np

from rccl.kinematics import puma260 as kinematics
from rci.chg import CUR
from rci.conversions import Conversions
from rcci.models import load_robot
from rci.session import Session


class Weightless:
    """The control function ``weightless()`` of 2.2.2, bound to one session."""

    def __init__(self, session: Session, robot: str = "puma260", fitted=None) -> None:
        """``fitted``: a ``rcci.calib.params.Fitted`` (torque sensitivities, gravity
        coefficients) to use instead of the robot data file's values."""
        self.s = session
        if fitted is None:
            self.conv = Conversions.for_robot(robot)
            self.coeffs = load_robot(robot).gravity_coeffs
        else:
            self.conv = Conversions.from_model(load_robot(robot), sigma=fitted.sigma)
            self.coeffs = dict(fitted.gravity_coeffs)
        self.torques = np.zeros(self.conv.n)        # last gravity torques (N*m), for the planning level

    def __call__(self) -> None:
        angles = self.conv.counts_to_angles(self.s.how.pos)          # enctoang()
        gload = np.asarray(kinematics.gravity(angles, self.coeffs))   # compute_gravity_loadings()
        current_setting = self.conv.tortodac(gload)                   # tortodac()
        for i, value in enumerate(current_setting):
            self.s.chg.motion[i].issue(CUR, int(value))
        self.torques = gload


def run(session: Session, cycles: int | None = None, fitted=None) -> np.ndarray:
    """Float the arm until <CR> (or for ``cycles`` control cycles); returns the angle drift (rad)."""
    weightless = Weightless(session, session.robot, fitted)
    session.control(None, weightless)         # dummy() is None
    session.chg.power_on.com = 1              # turn on the arm power
    session.wait(until=lambda: session.how.power, seconds=5.0)
    start = weightless.conv.counts_to_angles(session.how.pos)
    if cycles is None:
        input("Type <CR> to exit:\n")
    else:
        first = session.how.cycle
        session.wait(until=lambda: session.how.cycle - first >= cycles, seconds=max(30.0, 3 * cycles / session.rate_hz))
    drift = weightless.conv.counts_to_angles(session.how.pos) - start
    session.release()
    return drift


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("url", nargs="?", default="socket://127.0.0.1:7600", help="robot link (pyserial URL or device)")
    ap.add_argument("--robot", default="puma260")
    ap.add_argument("--rate", type=int, default=36, help="sample rate, Hz (thesis default 36)")
    ap.add_argument("--cycles", type=int, help="release after this many cycles instead of waiting for <CR>")
    ap.add_argument("--simula", metavar="ARGS", help="start a lockstep simula with these options and use it")
    ap.add_argument("--params", metavar="FILE", help="parameter file of fitted values (`calib fit`)")
    ap.add_argument("--timeout", type=float, metavar="S",
                    help="end the control after S s without a HOW (default: the session's; give more on a "
                         "loaded machine)")
    args = ap.parse_args(argv)
    from rcci.calib.exceptions import CalibError
    from rcci.calib.params import load_fitted
    try:
        fitted = load_fitted(args.params, args.robot) if args.params else None
    except (CalibError, OSError) as exc:
        print(f"zero_gravity: --params {args.params}: {exc}", file=sys.stderr)
        return 2
    with ExitStack() as stack:
        url = args.url
        if args.simula is not None:
            from rci.simula.process import SimulaProcess
            url = stack.enter_context(SimulaProcess(*args.simula.split(), robot=args.robot, lockstep=True)).url
        extra = {} if args.timeout is None else {"timeout": args.timeout}
        session = stack.enter_context(Session(url, args.robot, rate_hz=args.rate, **extra))
        drift = run(session, args.cycles, fitted)
        print("joint drift while weightless (deg):", np.array2string(np.degrees(drift), precision=3))
    return 0


if __name__ == "__main__":
    sys.exit(main())
