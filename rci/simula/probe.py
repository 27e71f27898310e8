"""Measure a simula process from a bare controller: HOW period jitter (real time) or cycles per second (lockstep).

    python -m rci.simula.probe --rate 1000 --seconds 3            # real time
    python -m rci.simula.probe --rate 36 --seconds 3 --lockstep   # simulated seconds per wall second

The controller side is deliberately minimal (raw rci.protocol frames, an empty CHG per
HOW, SCHED_FIFO 80 where allowed) so the figures describe simula and the machine, not the
RCI control task; ``make bench`` measures the full stack.
"""
from __future__ import annotations

import argparse
import os
import time

import numpy as np

from .. import protocol
from ..chg import Chg
from ..link import open_link
from ..realtime import pin_to_cpus
from .process import SimulaProcess


def probe(rate: int, seconds: float, lockstep: bool, args: list[str], cpu: int | None = None,
          robot: str = "puma260") -> dict:
    """Run one control of ``seconds`` (simulated) at ``rate`` Hz on a simula of ``robot``;
    return the statistics.

    ``cpu``: pin simula and this controller to that CPU (see ``rci.realtime.pin_to_cpus``).
    """
    with SimulaProcess("-p", "--power-on", *args, robot=robot, lockstep=lockstep) as sim:
        if cpu is not None:
            pin_to_cpus({cpu}, sim.proc.pid)
            pin_to_cpus({cpu})
        link = open_link(sim.url)
        link.send(protocol.HELLO, 0, protocol.Hello(robot, rate, "probe").encode())
        if link.recv(10.0) is None:
            raise RuntimeError("simula did not answer HELLO")
        link.send(protocol.START, 1, protocol.Start(rate).encode())
        empty = protocol.encode_chg(Chg())
        arrivals = []
        how = None
        t0 = time.monotonic()
        for _ in range(int(round(rate * seconds))):
            f = link.recv(5.0)
            if f is None or f.type != protocol.HOW:
                raise RuntimeError(f"expected HOW, got {f.name if f else 'nothing'}")
            arrivals.append(time.monotonic())
            how = protocol.decode_how(f.payload, f.seq)
            link.send(protocol.CHG, f.seq, empty)
        wall = time.monotonic() - t0
        end = Chg()
        end.end.com = 1
        f = link.recv(5.0)
        if f is not None:
            link.send(protocol.CHG, f.seq, protocol.encode_chg(end))
        link.close()
    period = np.diff(arrivals) * 1e6
    return {"rate_hz": rate, "cycles": len(arrivals), "wall_s": wall, "simulated_s": len(arrivals) / rate,
            "p50_us": float(np.percentile(period, 50)), "p99_us": float(np.percentile(period, 99)),
            "max_us": float(period.max()), "robot_overruns": int(how.robot_overruns), "status": int(how.status)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m rci.simula.probe", description=__doc__.splitlines()[0])
    ap.add_argument("--rate", type=int, default=1000)
    ap.add_argument("--seconds", type=float, default=3.0)
    ap.add_argument("--lockstep", action="store_true")
    ap.add_argument("--robot", default="puma260", help="simula's arm (models/ROBOT.toml), default puma260")
    ap.add_argument("--no-fifo", action="store_true", help="leave this controller at normal priority")
    ap.add_argument("--cpu", type=int, default=-1, help="pin simula and this controller to one CPU (-1: no)")
    a, rest = ap.parse_known_args(argv)
    if not a.no_fifo and hasattr(os, "sched_setscheduler"):
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(80))
        except OSError:
            pass
    r = probe(a.rate, a.seconds, a.lockstep, rest, None if a.cpu < 0 else a.cpu, a.robot)
    if a.lockstep:
        print(f"lockstep {r['rate_hz']} Hz: {r['cycles']} cycles in {r['wall_s']:.2f} s wall = "
              f"{r['simulated_s'] / r['wall_s']:.1f} simulated s per wall s ({r['cycles'] / r['wall_s']:.0f} cycles/s)")
    else:
        print(f"real time {r['rate_hz']} Hz: {r['cycles']} HOWs, period p50 {r['p50_us']:.0f} us, "
              f"p99 {r['p99_us']:.0f} us, max {r['max_us']:.0f} us; robot overruns {r['robot_overruns']}, "
              f"status {r['status']}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
