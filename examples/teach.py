"""A teach program driven from the keyboard: jog joints, record poses, save them.

Keys (one character each; on a terminal they act at once, otherwise they are read from
standard input or ``--keys``, so the program is scriptable):

    1..6   select a joint              + / -   jog it by the jog step (default 2 deg)
    s / f  slower / faster jog step    r       record the current pose
    p      print the current pose      q       quit (release, write the poses)

The control function servos every joint towards its target (POS), moving no faster than
``--speed`` (default 0.2 rad/s), so a jog is a smooth motion. Recorded poses are joint
angles in radians, written as JSON to ``--out``.

    python examples/teach.py socket://127.0.0.1:7600 --out poses.json
    python examples/teach.py --simula=-p --keys "2++++r3--r q" --out poses.json
"""
from __future__ import annotations

import argparse
import json
import os
import sys
from contextlib import ExitStack, contextmanager
from typing import Iterator

import numpy as np

from rci.conversions import Conversions
from rcci.models import load_robot
from rci.session import Session


class Servo:
    """The control function: moves the joints towards ``goal`` (rad) at most ``speed`` rad/s."""

    def __init__(self, session: Session, robot: str, speed: float) -> None:
        self.s = session
        self.conv = Conversions.for_robot(robot)
        self.model = load_robot(robot)
        self.speed = speed
        self.goal: np.ndarray | None = None
        self.command: np.ndarray | None = None    # last commanded angles (rad)

    def __call__(self) -> None:
        q = self.conv.counts_to_angles(self.s.how.pos)
        if self.goal is None:
            self.goal, self.command = q.copy(), q.copy()
        step = self.speed / self.s.rate_hz
        self.command = self.command + np.clip(self.goal - self.command, -step, step)
        self.conv.command_positions(self.s.chg, self.command)

    def angles(self) -> np.ndarray:
        return self.conv.counts_to_angles(self.s.how.pos)

    def arrived(self, tol: float = 3e-4) -> bool:
        """True once the command reached the goal and the joints are within ``tol`` rad of it
        (about two encoder counts on the PUMA's arm joints)."""
        return (self.goal is not None and bool(np.all(self.command == self.goal))
                and bool(np.all(np.abs(self.angles() - self.goal) < tol)))


def keys_from(stream) -> Iterator[str]:
    """Single keys from a terminal (put it in cbreak mode first: ``cbreak``) or a pipe/file."""
    if stream.isatty():
        fd = stream.fileno()
        while True:
            ch = os.read(fd, 1).decode(errors="ignore")
            if not ch:
                return
            yield ch
    else:
        for line in stream:
            for ch in line:
                if not ch.isspace():
                    yield ch


@contextmanager
def cbreak(stream):
    """Keys act at once on a terminal (no <CR>, no echo); restored on exit. No-op on a pipe."""
    if not stream.isatty():
        yield
        return
    import termios
    import tty
    fd = stream.fileno()
    saved = termios.tcgetattr(fd)
    tty.setcbreak(fd, termios.TCSANOW)      # TCSANOW: keys typed early are kept, not flushed
    try:
        yield
    finally:
        termios.tcsetattr(fd, termios.TCSADRAIN, saved)


def say(message: str) -> None:
    print(message, flush=True)


def teach(session: Session, keys: Iterator[str], *, step_deg: float = 2.0, speed: float = 0.2,
          echo=say) -> list[list[float]]:
    """Run the teach loop on an open session; returns the recorded poses (rad)."""
    servo = Servo(session, session.robot, speed)
    session.chg.power_on.com = 1
    session.control(servo)
    session.wait(until=lambda: session.how.power and servo.goal is not None, seconds=5.0)
    joint = 0
    step = np.radians(step_deg)
    poses: list[list[float]] = []
    lower, upper = servo.model.lower, servo.model.upper
    echo("ready: 1-6 joint, +/- jog, s/f step, r record, p print, q quit")
    for key in keys:
        if key in "123456"[: servo.conv.n]:
            joint = int(key) - 1
            echo(f"joint {joint + 1}")
        elif key in "+-":
            goal = servo.goal.copy()
            goal[joint] = np.clip(goal[joint] + (step if key == "+" else -step), lower[joint], upper[joint])
            servo.goal = goal
            session.wait(until=servo.arrived, seconds=10.0)
        elif key in "sf":
            step = step / 2 if key == "s" else step * 2
            echo(f"jog step {np.degrees(step):.3f} deg")
        elif key == "r":
            poses.append([float(x) for x in servo.angles()])
            echo(f"recorded pose {len(poses)}: " + np.array2string(np.degrees(servo.angles()), precision=2))
        elif key == "p":
            echo("pose (deg): " + np.array2string(np.degrees(servo.angles()), precision=2))
        elif key == "q":
            break
    session.release()
    return poses


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("url", nargs="?", default="socket://127.0.0.1:7600")
    ap.add_argument("--robot", default="puma260")
    ap.add_argument("--rate", type=int, default=36)
    ap.add_argument("--keys", help="keys to use instead of the keyboard")
    ap.add_argument("--step", type=float, default=2.0, help="jog step, deg")
    ap.add_argument("--speed", type=float, default=0.2, help="jog speed, rad/s")
    ap.add_argument("--out", default="poses.json", help="where to write the recorded poses (JSON, rad)")
    ap.add_argument("--simula", metavar="ARGS", help="start a lockstep simula with these options and use it")
    args = ap.parse_args(argv)
    keys = iter(args.keys) if args.keys is not None else keys_from(sys.stdin)
    with ExitStack() as stack:
        if args.keys is None:
            stack.enter_context(cbreak(sys.stdin))
        url = args.url
        if args.simula is not None:
            from rci.simula.process import SimulaProcess
            url = stack.enter_context(SimulaProcess(*args.simula.split(), robot=args.robot, lockstep=True)).url
        s = stack.enter_context(Session(url, args.robot, rate_hz=args.rate))
        poses = teach(s, (k for k in keys if not k.isspace()), step_deg=args.step, speed=args.speed)
    with open(args.out, "w") as f:
        json.dump({"robot": args.robot, "unit": "rad", "poses": poses}, f, indent=1)
    print(f"{len(poses)} poses written to {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
