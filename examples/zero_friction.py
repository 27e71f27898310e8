"""The "zero friction" program of thesis section 4.6: a net joint torque of zero on every joint.

Every cycle the control function reads the encoder counts, estimates the joint velocities
from the change since the last cycle, and sets each motor current to the value of eq. 4.38
for a net torque t_a = 0: the gravity loading (4.24) plus the kinetic friction of the
direction of motion (4.27, Tables 4.2 and 4.3), so that nothing but the user's hand acts on
the arm. In the thesis the manipulator then "bounced around unless held in one place": a
push keeps a joint going, where the zero-gravity program (examples/zero_gravity.py, which
leaves friction alone) lets friction stop it. At rest no friction is modelled, so static
friction still makes the joints stick, as the thesis found ("except when the joints were
stationary").

    python examples/zero_friction.py socket://127.0.0.1:7600      # type <CR> to exit
    python examples/zero_friction.py --simula "-c --warm --test-channel" --cycles 72 --push 1:1.5
"""
from __future__ import annotations

import argparse
import sys
from contextlib import ExitStack

import numpy as np

import rccl.kinematics
from rccl.adaptive.force import JointModel, gravity_vector
from rci.chg import CUR
from rci.conversions import DAC_MAX, DAC_MIN
from rci.session import Session


class ZeroFriction:
    """The control function of 4.6's program, bound to one session: zero net torque (4.38)."""

    def __init__(self, session: Session, robot: str = "puma260") -> None:
        self.s = session
        self.model = JointModel.for_robot(robot)
        self.conv = self.model.conv
        self.kin = rccl.kinematics.load(robot)     # generated (make derive)
        self.coeffs = gravity_vector(self.kin, self.model.gravity_coeffs)
        self.last: np.ndarray | None = None            # joint angles of the last cycle (rad)
        self.speeds = np.zeros(self.conv.n)             # rad/s, for the planning level
        self.friction = np.zeros(self.conv.n)           # N*m compensated in the last cycle

    def __call__(self) -> None:
        angles = self.conv.counts_to_angles(self.s.how.pos)
        if self.last is not None:
            self.speeds = (angles - self.last) * self.s.rate_hz
        self.last = angles
        gload = np.asarray(self.kin.gravity(angles, self.coeffs))             # t_g (4.24)
        self.friction = self.model.friction(self.speeds)                       # f (4.27), 0 at rest
        dac = self.conv.dac_for_net_torques(np.zeros(self.conv.n), gload,      # 4.38 with t_a = 0
                                            self.conv.friction_to_dac(self.friction))
        for i, value in enumerate(np.clip(np.rint(dac), DAC_MIN, DAC_MAX).astype(int)):
            self.s.chg.motion[i].issue(CUR, int(value))


def run(session: Session, cycles: int | None = None, push: tuple[int, float] | None = None,
        push_cycles: int = 9, command=None) -> np.ndarray:
    """Zero net torque until <CR> (or for ``cycles`` cycles); returns the joints' travel (rad).

    ``push = (joint, N*m)``: with ``command`` (a simula control-channel call, ``--test-channel``)
    a hand pushes that joint (1-based) for ``push_cycles`` cycles at the start, then lets go."""
    zero = ZeroFriction(session, session.robot)
    session.control(None, zero)
    session.chg.power_on.com = 1
    session.wait(until=lambda: session.how.power, seconds=5.0)
    start = zero.conv.counts_to_angles(session.how.pos)
    first = session.how.cycle
    if push is not None and command is not None:
        command(f"torque {push[0]} {push[1]}")
        session.wait(until=lambda: session.how.cycle - first >= push_cycles, seconds=30.0)
        command("torque clear")
    if cycles is None:
        input("Type <CR> to exit:\n")
    else:
        session.wait(until=lambda: session.how.cycle - first >= cycles, seconds=max(30.0, 3 * cycles / session.rate_hz))
    travel = zero.conv.counts_to_angles(session.how.pos) - start
    session.release()
    return travel


def _push(text: str) -> tuple[int, float]:
    joint, _, value = text.partition(":")
    try:
        return int(joint), float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: give JOINT:N*m, e.g. 1:1.5") from None


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("url", nargs="?", default="socket://127.0.0.1:7600", help="robot link (pyserial URL or device)")
    ap.add_argument("--robot", default="puma260")
    ap.add_argument("--rate", type=int, default=36, help="sample rate, Hz (thesis default 36)")
    ap.add_argument("--cycles", type=int, help="release after this many cycles instead of waiting for <CR>")
    ap.add_argument("--simula", metavar="ARGS", help="start a lockstep simula with these options and use it")
    ap.add_argument("--push", type=_push, metavar="JOINT:NM",
                    help="with --simula ... --test-channel: a hand pushes JOINT with NM N*m for 0.25 s, then lets go")
    ap.add_argument("--timeout", type=float, metavar="S",
                    help="end the control after S s without a HOW (default: the session's, 2 periods; give more "
                         "on a loaded machine)")
    args = ap.parse_args(argv)
    with ExitStack() as stack:
        url, command = args.url, None
        if args.simula is not None:
            from rci.simula.process import SimulaProcess
            sim = stack.enter_context(SimulaProcess(*args.simula.split(), robot=args.robot, lockstep=True))
            url, command = sim.url, sim.command
        if args.push is not None and command is None:
            ap.error("--push needs --simula with --test-channel (a simulated hand)")
        extra = {} if args.timeout is None else {"timeout": args.timeout}
        session = stack.enter_context(Session(url, args.robot, rate_hz=args.rate, **extra))
        travel = run(session, args.cycles, args.push, command=command)
        print("joint travel with zero net torque (deg):", np.array2string(np.degrees(travel), precision=3))
    return 0


if __name__ == "__main__":
    sys.exit(main())
