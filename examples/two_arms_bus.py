"""Two arms in two processes on the Zenoh bus (thesis 2.4.3: one processor per robot).

The program of examples/two_arms.py, split the way the thesis's multi-processor RCI would
run it: the PUMA's control task in one process, the Microbo's in another, the planning
level in a third, and each robot reached over the bus (``zenoh/KEY`` links; the processes
may be on different hosts). The PUMA swings its waist and publishes its angles in the
workcell's shared data; the Microbo reads them and turns its own waist the mirror way,
reporting to the planning level on a channel every REPORT_EVERY samples; the planning
level prints the reports and, after ``--seconds``, tells both arms to stop (shared data
``stop``), then waits for their processes.

    python examples/two_arms_bus.py --simula                 # everything on this host, loopback
    python examples/two_arms_bus.py --bus tcp/10.0.0.1:7447 \\
        zenoh/lab/puma?connect=tcp/10.0.0.2:7447 zenoh/lab/microbo?connect=tcp/10.0.0.3:7447

The arm processes are this same file: ``two_arms_bus.py arm puma URL --bus ENDPOINT``.
"""
from __future__ import annotations

import argparse
import math
import subprocess
import sys
import time
from contextlib import ExitStack
from pathlib import Path

import numpy as np

from rci.bus import Bus
from rci.bus.link import free_endpoint
from rci.chg import POS
from rci.conversions import Conversions
from rci.session import Session

CELL = "two-arms"
AMPLITUDE = 0.25          # rad, the PUMA waist's swing
SWING_PERIOD = 4.0        # s
REPORT_EVERY = 18         # Microbo samples between reports
MAX_SPEED = 1.0           # rad/s, the Microbo waist's fastest catch-up
ROBOTS = {"puma": "puma260", "microbo": "microbo"}


def run_arm(name: str, url: str, bus_endpoints: tuple[str, ...], rate_hz: int = 36) -> int:
    """One arm's process: its Session and control task; shared data and the report channel on the bus."""
    robot = ROBOTS[name]
    conv = Conversions.for_robot(robot)
    with Bus(CELL, tasks=(name,), connect=bus_endpoints) as bus, \
            Session(url, robot, rate_hz=rate_hz, on_error="raise", signals=False, lock_memory=False,
                    # an ordinary (not real-time) process on a shared machine: a HOW may come a few
                    # periods late over the bus, so 0.25 s without one (not two periods) ends the
                    # control, and so do late cycles in a row for as long (9 at 36 Hz; the default 3
                    # ended it at a load of 4-5 on 2 cores); simula's watchdog stops the arm if this
                    # process itself stalls
                    realtime=False, timeout=0.25, late_limit=max(3, round(0.25 * rate_hz))) as s:
        reports = bus.channel("microbo", "planning", capacity=8)
        state = {"q0": None, "k": 0}

        def puma_control() -> None:
            q = conv.counts_to_angles(np.asarray(s.how.pos, dtype=float))
            if state["q0"] is None:
                state["q0"] = q.copy()
                s.chg.power_on.com = 1
            t = state["k"] / s.rate_hz
            state["k"] += 1
            bus.shared["puma_q"] = q                      # t1, for every process on the bus
            bus.shared["puma_q0"] = state["q0"]
            goal = state["q0"].copy()
            goal[0] += AMPLITUDE * math.sin(2.0 * math.pi * t / SWING_PERIOD)
            s.chg.motion[0].issue(POS, int(conv.angles_to_counts_int(goal)[0]))

        def microbo_control() -> None:
            q = conv.counts_to_angles(np.asarray(s.how.pos, dtype=float))
            if state["q0"] is None:
                state["q0"] = q.copy()
                s.chg.power_on.com = 1
            k = state["k"]
            state["k"] += 1
            seen, p0 = bus.shared.get("puma_q"), bus.shared.get("puma_q0")
            if seen is None or p0 is None:
                return
            # the mirror of the PUMA's swing, approached at most MAX_SPEED: the processes start
            # one after the other, so the PUMA may already be swinging when the Microbo begins
            target = float(state["q0"][0] - (seen[0] - p0[0]))
            last = state.get("cmd", float(q[0]))
            step = MAX_SPEED / s.rate_hz
            cmd = state["cmd"] = last + max(-step, min(step, target - last))
            goal = q.copy()
            goal[0] = cmd
            s.chg.motion[0].issue(POS, int(conv.angles_to_counts_int(goal)[0]))
            if k % REPORT_EVERY == 0:
                reports.send({"sample": k, "puma_waist": float(seen[0] - p0[0]),
                              "microbo_waist": float(q[0] - state["q0"][0]), "command": cmd - float(state["q0"][0])})

        s.control(puma_control if name == "puma" else microbo_control)
        print(f"{name}: controlling", flush=True)
        while not bus.shared.get("stop", False):
            s.wait(0.05)
        s.release()
    print(f"{name}: released after {state['k']} samples", flush=True)
    return 0


def plan(urls: dict[str, str], bus_listen: str, seconds: float, quiet: bool = False) -> list[dict]:
    """The planning process: start the arms' processes, collect the reports, stop them."""
    reports: list[dict] = []
    with Bus(CELL, tasks=("planning",), listen=(bus_listen,)) as bus, ExitStack() as stack:
        channel = bus.channel("microbo", "planning", capacity=8)
        procs = {}
        for name, url in urls.items():
            p = subprocess.Popen([sys.executable, str(Path(__file__).resolve()), "arm", name, url, "--bus", bus_listen],
                                 stdout=subprocess.PIPE, text=True)
            stack.callback(_stop, p)
            procs[name] = p
        for name, p in procs.items():
            line = p.stdout.readline().strip()
            if line != f"{name}: controlling":
                raise RuntimeError(f"the {name} process did not start its control (said {line!r}, "
                                   f"exit code {p.poll()})")
        t_end = time.monotonic() + seconds
        while time.monotonic() < t_end:
            msg = channel.receive(timeout=min(0.2, max(0.0, t_end - time.monotonic())) or 0.01)
            if msg is not None:
                reports.append(msg)
                if not quiet:
                    print(f"microbo: sample {msg['sample']:4d}  PUMA waist {math.degrees(msg['puma_waist']):+7.2f} deg"
                          f"  Microbo waist {math.degrees(msg['microbo_waist']):+7.2f} deg")
        bus.shared["stop"] = True
        for name, p in procs.items():
            out, _ = p.communicate(timeout=10)
            if p.returncode != 0:
                raise RuntimeError(f"the {name} process ended with code {p.returncode}")
            if not quiet:
                print(out.strip())
        while (msg := channel.receive()) is not None:
            reports.append(msg)
    return reports


def _stop(p: subprocess.Popen) -> None:
    if p.poll() is None:
        p.kill()
        p.wait(5)


def _cli(argv: list[str] | None = None) -> int:
    if argv is None:
        argv = sys.argv[1:]
    if argv[:1] == ["arm"]:
        ap = argparse.ArgumentParser(prog="two_arms_bus.py arm", description="one arm's process")
        ap.add_argument("name", choices=sorted(ROBOTS))
        ap.add_argument("url", help="the arm's link (zenoh/KEY?connect=..., socket://..., a device)")
        ap.add_argument("--bus", action="append", default=[], help="Zenoh endpoint of the workcell's bus")
        a = ap.parse_args(argv[1:])
        return run_arm(a.name, a.url, tuple(a.bus))
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("urls", nargs="*", help="PUMA link, Microbo link (zenoh/KEY?connect=... or socket://...)")
    ap.add_argument("--simula", action="store_true", help="start two real-time simulas on the Zenoh bus")
    ap.add_argument("--bus", help="Zenoh endpoint this (planning) process listens on for the workcell's bus "
                                  "(default: a free loopback port)")
    ap.add_argument("--seconds", type=float, default=4.0)
    a = ap.parse_args(argv)
    with ExitStack() as stack:
        if a.simula:
            from rci.simula.process import SimulaProcess
            urls = {name: stack.enter_context(SimulaProcess(
                "-p", "--zenoh", f"lab/{name}", "--zenoh-listen", free_endpoint(), robot=robot, lockstep=False)).url
                for name, robot in ROBOTS.items()}
        elif len(a.urls) == 2:
            urls = dict(zip(ROBOTS, a.urls))
        else:
            ap.error("give two link URLs (PUMA, Microbo) or --simula")
        reports = plan(urls, a.bus or free_endpoint(), a.seconds)
    print(f"{len(reports)} reports from the Microbo's process")
    return 0 if reports else 1


if __name__ == "__main__":
    sys.exit(_cli())
