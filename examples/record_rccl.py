"""Record an RCCL program's every control cycle, then plot the log and export it (docs/recording.md).

    .venv/bin/python examples/record_rccl.py                          # starts its own simula (real time)
    .venv/bin/python examples/record_rccl.py socket://127.0.0.1:7600  # a running `simula -p --power-on`
    .venv/bin/python examples/record_rccl.py --log run.rcilog --png run.png --mcap run.mcap

The PUMA 260 goes from park to the corner of a 5 cm square in a horizontal plane near park (a joint
move), round the square in straight lines (Cartesian moves) and back to park. RCCL's
trajectory generator is an RCI control function, so the recorder is attached to the arm's RCI
session (``arm.rci.record``): it logs every cycle's HOW (encoder counts, currents, time) and
CHG (the POS commands RCCL sent). ``rci.plot`` draws the log, ``rci.export`` writes the MCAP
file that Foxglove opens.
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

import rccl
from rccl import EQ, T6, TL, Trsf, makeposition
from rci.recorder import Recorder, read_log

SIDE = 0.05                                   # m, the square's side
CORNER = np.array([0.17, -0.16, 0.17])        # m, base frame: in front of the shoulder, near park
TOOL_DOWN = np.diag([-1.0, 1.0, -1.0])        # T6's z axis pointing down (a turn of pi about y)


def pose(name: str, p: np.ndarray):
    """An RCCL position whose T6 is at ``p`` (m) with the tool pointing down."""
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = TOOL_DOWN, p
    return makeposition(name, T6, EQ, Trsf(name.upper(), T), TL, T6)


def run(url: str, log_path: Path, rate_hz: int = 36, **rci_options) -> Recorder:
    """Move round the square on the arm at ``url``, recording every cycle into ``log_path``;
    ``rci_options`` go to the RCI session (e.g. ``timeout``, s)."""
    corners = [CORNER + SIDE * np.array(d) for d in ((0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 0))]
    with rccl.open(url, robot="puma260", rate_hz=rate_hz, **rci_options) as arm:
        rec = Recorder(log_path, robot=arm.robot, rate_hz=rate_hz, meta={"program": "examples/record_rccl.py"})
        arm.rci.record(rec)                   # from now on every control cycle is logged
        rec.start_writer()                    # the planning level writes the log while the arm moves
        try:
            arm.setvel(0.08, math.radians(60))                 # m/s, rad/s
            arm.setmod("joint")
            arm.move(pose("c0", corners[0]))
            arm.setmod("cartesian")                            # straight lines round the square
            for k, c in enumerate(corners[1:], start=1):
                arm.move(pose(f"c{k}", c))
            arm.setmod("joint")
            arm.move(arm.park)
            arm.waitfor(arm.park.end)
        finally:
            arm.rci.record(None)
            rec.close()                       # flush, end marker
    return rec


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("url", nargs="?", help="robot link of a powered PUMA 260 (default: start a simula in real time)")
    ap.add_argument("--log", type=Path, default=Path("demo-out/record-rccl.rcilog"), help="the log to write")
    ap.add_argument("--png", type=Path, help="also draw the log (python -m rci.plot)")
    ap.add_argument("--mcap", type=Path, help="also export it for Foxglove (python -m rci.export)")
    ap.add_argument("--lockstep", action="store_true",
                    help="start simula in lockstep (one period per command: a busy machine slows the run down "
                         "instead of making cycles late; the timing panel then shows the machine, not the robot)")
    args = ap.parse_args(argv)
    args.log.parent.mkdir(parents=True, exist_ok=True)
    if args.url:
        rec = run(args.url, args.log)
    else:
        from rci.simula.process import SimulaProcess
        with SimulaProcess("-p", "--power-on", lockstep=args.lockstep) as sim:   # real time, as a robot
            rec = run(sim.url, args.log, timeout=2.0 if args.lockstep else None)
    log = read_log(args.log)
    print(f"recorded {len(log)} cycles into {args.log} (written {rec.written}, dropped {rec.dropped}, "
          f"lost {rec.lost})")
    if args.png:
        from rci.plot import plot_log
        print("wrote", plot_log(log, args.png, title="examples/record_rccl.py: a 5 cm square on the PUMA 260 "
                                                     "(simula, 36 Hz)"))
    if args.mcap:
        from rci.export import to_mcap
        print(f"wrote {args.mcap}: {to_mcap(log, args.mcap)} messages")
    return 0


if __name__ == "__main__":
    sys.exit(main())
