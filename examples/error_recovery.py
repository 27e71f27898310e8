"""Error recovery (thesis A.5.5): an error handler decides, the main program recovers.

The thesis's C example saves a context with ``setjmp``; the ``user_hangup`` handler
examines ``RCIterminate``, picks a recovery action and ``longjmp``s back, where a
``switch`` runs the action and calls ``RCIcontrol()`` again. In Python the handler
(``session.on_error``) raises an exception carrying the action, and the ``try`` around the
main program is the ``setjmp`` point. The control has already been released (and the arm
stopped) when the handler runs, as A.5.3 says.

The program moves joint 1 by ``--angle`` degrees at ``--speed`` times the joint's speed
limit. Asked to go too fast, the first control ends with R_REQVEL; the handler answers
"slower", the main program halves the speed and starts control again from where the arm
is, until the move is done. Any other error ends the program with the usual TERMINATE
line and exit status 1.

    python examples/error_recovery.py socket://127.0.0.1:7600
    python examples/error_recovery.py --simula=-p --speed 1.6
"""
from __future__ import annotations

import argparse
import sys
from contextlib import ExitStack

import numpy as np

from rci import codes
from rci.checks import CommandLimits
from rci.chg import POS
from rci.conversions import Conversions
from rci.session import Session


class Recover(Exception):
    """Thrown by the error handler to the main program (the longjmp of A.5.5)."""

    def __init__(self, action: str, termination: codes.Termination) -> None:
        super().__init__(action)
        self.action = action
        self.termination = termination


def error_handler(t: codes.Termination) -> None:
    """user_hangup: examine the termination code and decide what to do."""
    codes.print_terminate_code(t.code, f"error handler: {t.detail}", file=sys.stdout)
    if t.number == codes.R_REQVEL:
        raise Recover("slower", t)
    if t.number in (codes.R_REQPOS, codes.R_MAXPOS):
        raise Recover("give up", t)
    raise Recover("abort", t)


class Mover:
    """The control function: drive joint ``joint`` towards ``goal[0]`` (rad) at ``speed`` rad/s.

    ``goal`` is a one-element list shared by every attempt; when empty, the first cycle
    sets it to the joint's angle then plus ``delta`` rad.
    """

    def __init__(self, session: Session, conv: Conversions, joint: int, goal: list[float],
                 delta: float, speed: float) -> None:
        self.s, self.conv, self.joint, self.speed = session, conv, joint, speed
        self.goal_box, self.delta = goal, delta
        self.command: np.ndarray | None = None

    @property
    def goal(self) -> float:
        return self.goal_box[0]

    def __call__(self) -> None:
        if self.command is None:
            self.command = self.conv.counts_to_angles(self.s.how.pos)
            if not self.goal_box:
                self.goal_box.append(float(self.command[self.joint] + self.delta))
        step = self.speed / self.s.rate_hz
        self.command[self.joint] += float(np.clip(self.goal - self.command[self.joint], -step, step))
        counts = self.conv.angles_to_counts_int(self.command)
        self.s.chg.motion[self.joint].issue(POS, int(counts[self.joint]))

    def done(self) -> bool:
        if not self.goal_box:
            return False
        q = self.conv.counts_to_angles(self.s.how.pos)[self.joint]
        return abs(q - self.goal) < 3e-4


def move_with_recovery(session: Session, angle_deg: float, speed_factor: float, joint: int = 0,
                       max_attempts: int = 6) -> list[str]:
    """Move one joint, recovering from errors as the handler decides; returns the log of actions."""
    conv = Conversions.for_robot(session.robot)
    vmax = CommandLimits.for_robot(session.robot).max_velocity[joint]
    goal: list[float] = []
    speed = speed_factor * vmax
    actions: list[str] = []
    session.on_error = error_handler
    for _ in range(max_attempts):
        # a chg refused by the checks is discarded whole, so power_on goes with every attempt
        session.chg.power_on.com = 1
        mover = Mover(session, conv, joint, goal, float(np.radians(angle_deg)), speed)
        try:                                             # setjmp()
            session.control(mover)
            if not session.wait(until=mover.done, seconds=60.0):
                raise TimeoutError("move not finished")
            session.release()
            actions.append(f"done at {speed / vmax:.2f} x the speed limit")
            return actions
        except Recover as r:                             # longjmp() landed here: switch (jump_code)
            actions.append(f"{r.termination.name}: {r.action}")
            if r.action == "slower":
                speed /= 2
                continue
            if r.action == "give up":
                return actions
            raise SystemExit(1)
    actions.append("too many attempts")
    return actions


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("url", nargs="?", default="socket://127.0.0.1:7600")
    ap.add_argument("--robot", default="puma260")
    ap.add_argument("--rate", type=int, default=36)
    ap.add_argument("--angle", type=float, default=20.0, help="move joint 1 by this many degrees")
    ap.add_argument("--speed", type=float, default=1.6, help="first try at this multiple of the speed limit")
    ap.add_argument("--simula", metavar="ARGS", help="start a lockstep simula with these options and use it")
    args = ap.parse_args(argv)
    with ExitStack() as stack:
        url = args.url
        if args.simula is not None:
            from rci.simula.process import SimulaProcess
            url = stack.enter_context(SimulaProcess(*args.simula.split(), robot=args.robot, lockstep=True)).url
        s = stack.enter_context(Session(url, args.robot, rate_hz=args.rate))
        for line in move_with_recovery(s, args.angle, args.speed):
            print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
