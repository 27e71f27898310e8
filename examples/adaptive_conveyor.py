"""Conveyor tracking (thesis Table 2.1's first RCCL program; 5.4.4): follow an object on a moving belt.

    .venv/bin/python examples/adaptive_conveyor.py          # starts its own simula with a conveyor

simula carries an object along +y at 1 cm/s from (0.25, -0.22, 0.12) m and publishes the
belt's travel the way a conveyor encoder would, as ADC counts (0.1 mm each, 12-bit,
wrapping) on channel 12 of ``how.adcr``. The program's transform ``CONV`` is functional:
each sample its function reads the encoder from the latest ``how``, unwraps it, and puts
CONV where the object is. The grasp position CONV OBJ (the object frame, tool pointing
down 3 cm above it) therefore moves with the belt. The robot moves to it in Cartesian
mode, tracks it for 6 s (a "stop" at a moving position), then leaves for a point above.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import rccl.adaptive                                  # noqa: E402
from rccl import EQ, T6, TL, Trsf, makeposition       # noqa: E402
from rccl.transform import rot, trsl                  # noqa: E402
from rci.simula.environment import CONVEYOR_CHANNEL, CONVEYOR_COUNTS_PER_M  # noqa: E402

START = np.array([0.25, -0.22, 0.12])
VELOCITY = np.array([0.0, 0.01, 0.0])
ABOVE = 0.03
TRACK_S = 6.0
ENV = ("conveyor:x={},y={},z={},vx={},vy={},vz={}".format(*START, *VELOCITY),)


class BeltEncoder:
    """The controller's view of the belt: unwraps the 12-bit encoder into metres of travel."""

    def __init__(self, arm) -> None:
        self.arm = arm
        self.last = None
        self.turns = 0

    def travel(self) -> float:
        c = int(self.arm.rci.how.adcr[CONVEYOR_CHANNEL])
        if self.last is not None:
            if c - self.last < -2048:
                self.turns += 1
            elif c - self.last > 2048:
                self.turns -= 1
        self.last = c
        return (c + 4096 * self.turns) / CONVEYOR_COUNTS_PER_M


def main(url: str):
    """Run the program; returns (arm, encoder, the tracking request)."""
    with rccl.adaptive.open(url, robot="puma260", record=True, timeout=2.0) as arm:
        enc = BeltEncoder(arm)
        direction = VELOCITY / np.linalg.norm(VELOCITY)
        conv = Trsf("CONV", trsl(*START), kind="variable")

        def follow_belt(t: Trsf) -> None:
            t.p = START + direction * enc.travel()

        obj = Trsf("OBJ", trsl(0.0, 0.0, ABOVE) @ rot("y", math.pi))
        grasp = makeposition("GRASP", T6, EQ, conv, obj, TL, T6)
        leave = makeposition("LEAVE", T6, EQ, Trsf("L", trsl(0.22, -0.05, 0.20) @ rot("y", math.pi)), TL, T6)
        conv.bind(follow_belt)
        arm.setmod("cartesian")
        arm.setvel(0.05, math.radians(30.0))
        arm.move(grasp)
        track = arm.stop(TRACK_S)
        r_leave = arm.move(leave)
        arm.waitfor(r_leave)
    return arm, enc, track


def tracking_error(arm, track) -> tuple[np.ndarray, np.ndarray]:
    """(times, |measured T6 position - object position + 3 cm up|) while tracking, from the how records.

    The object position comes from the belt encoder in the same how as the joint angles.
    """
    import pinocchio as pin
    from rcci.models import load_robot

    pm = pin.buildModelFromUrdf(str(load_robot("puma260").urdf_path))
    pd = pm.createData()
    fid = pm.getFrameId("link6")
    t_end = track.finished_t
    ts, err = [], []
    last, turns = None, 0
    for (t, _, _, q, _), adc in zip(arm.adaptive_trace, arm.adc_trace):
        c = int(adc[CONVEYOR_CHANNEL])
        if last is not None:
            turns += (c - last < -2048) - (c - last > 2048)
        last = c
        c += 4096 * turns
        if t_end - TRACK_S + 1.0 < t < t_end - 0.5:
            pin.framesForwardKinematics(pm, pd, q)
            target = START + VELOCITY / np.linalg.norm(VELOCITY) * c / CONVEYOR_COUNTS_PER_M + [0, 0, ABOVE]
            ts.append(t)
            err.append(np.linalg.norm(pd.oMf[fid].translation - target))
    return np.array(ts), np.array(err)


def _cli(argv: list[str]) -> int:
    from adaptive_sim import example_args, run_main

    args = example_args(__doc__, argv, plot=False)

    arm, enc, track = run_main(main, args.url, *ENV)
    ts, err = tracking_error(arm, track)
    print(f"tracked the belt for {TRACK_S} s; belt travel at the end {enc.travel():.4f} m; "
          f"tracking error over {len(ts)} samples: mean {1000 * err.mean():.2f} mm, max {1000 * err.max():.2f} mm")
    return 0


if __name__ == "__main__":
    sys.exit(_cli(sys.argv[1:]))
