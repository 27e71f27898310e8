"""Bench: event flags across processes on the Zenoh bus, and how fast a lost peer is noticed -> reports/bench-flags.md.

    python -m bench.zenoh_flags                        # 20 plans, 50 Hz, 5 runs of each fault
    python -m bench.zenoh_flags --runs 5 --fault-runs 1 --out -

Real processes on loopback, as ``tests/test_zenoh_flags.py`` and
``tests/test_zenoh_flag_faults.py`` run them: two real-time simulas (``-p --power-on``,
a PUMA 260 and a Microbo), two arm processes (``python -m rccl.bus.arm``) driving them over
sockets, and the planning level in this process, the bus's hub. The plan is
``examples/two_arm_flags.py``'s ``plan`` (a; b starts when a ends; c and d held, then
started together by one ``start_ev``) with small moves (a few hundredths of a radian),
``--runs`` times on the same processes. Times are each process's ``time.monotonic()``,
one clock on one host:

- *bus hop*: A's motion ended (A's process) -> B's start flag set (B's process, told by
  A's publication through the hub);
- *A ended -> B began*: the hop plus the wait for B's next sample;
- *start_ev spread*: c and d (two arms, two independent sample clocks) began apart;
- *start_ev round trip*: ``start_ev(7, c, d)`` returned: its message out, both arms'
  acknowledgements back (rccl.bus.planning re-sends until they come).

Faults (``--fault-runs`` each, fresh processes each time):

- *planning process killed*: ``tests/bus_planner.py`` (the hub) SIGKILLed while its motion
  runs -> the arm process prints that it aborted that planner's motions (its own clock);
- *planning process stopped*: ``tests/bus_planner.py`` (a client of the bench's hub)
  SIGSTOPped while its motion runs -> the arm process prints that it gave that planner up
  and aborted its motions (its own clock; the planner's heartbeat's silence,
  ``rccl.bus.planning.SILENCE_S``);
- *arm process stopped*: SIGSTOP while the plan waits on its motion -> ``wait_ev`` raises
  ``ArmLost`` (the heartbeat's silence, ``rccl.bus.planning.SILENCE_S``).
"""
from __future__ import annotations

import argparse
import importlib.util
import os
import platform
import signal
import subprocess
import sys
import time
from contextlib import ExitStack
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from bench.output import emit, progress  # noqa: E402
from rccl.bus import arm as bus_arm  # noqa: E402
from rccl.bus.planning import HEARTBEAT_S, RESEND_S, SILENCE_S, ArmLost, BusEvents  # noqa: E402
from rccl.position import joint_position  # noqa: E402
from rci.bus import Bus  # noqa: E402
from rci.bus.link import free_endpoint  # noqa: E402
from rci.simula.process import SimulaProcess  # noqa: E402

COMMAND = "make bench  (python -m bench.zenoh_flags)"
HOW_TIMEOUT_S = 0.25     # the arm processes' wait for a HOW (a loaded 2-core machine)
WATCHDOG_S = 0.25        # simula's watchdog
PLANNER = ROOT / "tests" / "bus_planner.py"


def _example():
    spec = importlib.util.spec_from_file_location("bench_two_arm_flags", ROOT / "examples" / "two_arm_flags.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _simula(stack: ExitStack, robot: str) -> SimulaProcess:
    return stack.enter_context(SimulaProcess("-p", "--power-on", "--watchdog-time", str(WATCHDOG_S), robot=robot,
                                             lockstep=False))


def _end(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        os.kill(proc.pid, signal.SIGCONT)
        proc.kill()
        proc.wait(5)


class _TimedStart:
    """The planning level's BusEvents, with the time each ``start_ev`` took (s) kept."""

    def __init__(self, ev: BusEvents) -> None:
        self._ev = ev
        self.start_ev_s: list[float] = []

    def start_ev(self, code: int, *efts) -> None:
        t0 = time.monotonic()
        self._ev.start_ev(code, *efts)
        self.start_ev_s.append(time.monotonic() - t0)

    def __getattr__(self, name: str):
        return getattr(self._ev, name)


def flag_latencies(runs: int, rate_hz: int) -> dict[str, list[float]]:
    """Run the two-arm plan ``runs`` times; each latency's samples (s)."""
    ex = _example()
    out: dict[str, list[float]] = {"hop": [], "began": [], "spread": [], "start_ev": []}
    with ExitStack() as stack:
        sims = {name: _simula(stack, robot) for name, robot in ex.ARMS.items()}
        listen = free_endpoint()
        bus = stack.enter_context(Bus("bench-flags", tasks=("planning",), listen=(listen,),
                                      priority=bus_arm.BUS_PRIORITY))
        for name, robot in ex.ARMS.items():
            proc = bus_arm.spawn(name, sims[name].url, robot, "bench-flags", (listen,), rate_hz,
                                 how_timeout=HOW_TIMEOUT_S)
            stack.callback(_end, proc)
        ev = BusEvents(bus)
        stack.callback(ev.close)
        timed = _TimedStart(ev)
        puma, mic = ev.arm("puma"), ev.arm("microbo")
        for _ in progress(range(runs), "flag latencies"):
            pos = {"over_part": ex.waist(puma, 0.04, "over_part"), "under_part": ex.waist(mic, 0.03, "under_part")}
            pos["away"] = ex.waist(puma, 0.02, "away")
            pos["lift"] = ex.waist(mic, 0.02, "lift")
            e = ex.plan(timed, puma, mic, pos)
            out["hop"].append(e["b"].t_start_set - e["a"].t_ended)
            out["began"].append(e["b"].t_started - e["a"].t_ended)
            out["spread"].append(abs(e["c"].t_started - e["d"].t_started))
        out["start_ev"] = timed.start_ev_s
        puma.close()
        mic.close()
    return out


def _line(proc: subprocess.Popen, want: str, timeout: float) -> str:
    """The next line of ``proc``'s stdout containing ``want``."""
    import select
    deadline, buf = time.monotonic() + timeout, b""
    while True:
        lines = buf.split(b"\n")
        for line in lines[:-1]:
            if want in line.decode(errors="replace"):
                return line.decode(errors="replace")
        ready, _, _ = select.select([proc.stdout], [], [], max(0.0, deadline - time.monotonic()))
        data = os.read(proc.stdout.fileno(), 4096) if ready else b""
        if not data:
            raise RuntimeError(f"no line with {want!r} from pid {proc.pid} within {timeout} s")
        buf += data


def planner_killed(rate_hz: int) -> float:
    """SIGKILL the planning process mid-motion; seconds until the arm process held the arm."""
    with ExitStack() as stack:
        sim = _simula(stack, "puma260")
        listen = free_endpoint()
        planner = subprocess.Popen([sys.executable, str(PLANNER), "bench-orphan", listen, "puma", "0.3"],
                                   stdout=subprocess.PIPE, stdin=subprocess.DEVNULL)
        stack.callback(_end, planner)
        _line(planner, "listening", 30.0)
        proc = bus_arm.spawn("puma", sim.url, "puma260", "bench-orphan", (listen,), rate_hz, how_timeout=HOW_TIMEOUT_S)
        stack.callback(_end, proc)
        _line(planner, "moving", 30.0)
        time.sleep(0.1)
        t_kill = time.monotonic()                  # before the signal: the figure can only be too long
        os.kill(planner.pid, signal.SIGKILL)
        said = _line(proc, "aborted, the arm holds", 5.0)
        return float(said.rsplit("t=", 1)[1].rstrip(")")) - t_kill


def planner_stopped(rate_hz: int) -> float:
    """SIGSTOP the planning process mid-motion; seconds until the arm process held the arm."""
    with ExitStack() as stack:
        sim = _simula(stack, "puma260")
        listen = free_endpoint()
        stack.enter_context(Bus("bench-mute", tasks=("hub",), listen=(listen,)))
        proc = bus_arm.spawn("puma", sim.url, "puma260", "bench-mute", (listen,), rate_hz, how_timeout=HOW_TIMEOUT_S)
        stack.callback(_end, proc)
        planner = subprocess.Popen([sys.executable, str(PLANNER), "bench-mute", listen, "puma", "0.3", "--connect"],
                                   stdout=subprocess.PIPE, stdin=subprocess.DEVNULL)
        stack.callback(_end, planner)
        _line(planner, "moving", 30.0)
        time.sleep(0.1)
        t_stop = time.monotonic()                  # before the signal: the figure can only be too long
        os.kill(planner.pid, signal.SIGSTOP)
        said = _line(proc, "aborted, the arm holds", 5.0)
        if "went silent" not in said:
            raise RuntimeError(f"the arm process held the arm for another reason: {said}")
        return float(said.rsplit("t=", 1)[1].rstrip(")")) - t_stop


def arm_stopped(rate_hz: int) -> float:
    """SIGSTOP the arm process while the plan waits on its motion; seconds until ``ArmLost``."""
    with ExitStack() as stack:
        sim = _simula(stack, "puma260")
        listen = free_endpoint()
        bus = stack.enter_context(Bus("bench-stall", tasks=("planning",), listen=(listen,)))
        proc = bus_arm.spawn("puma", sim.url, "puma260", "bench-stall", (listen,), rate_hz, how_timeout=HOW_TIMEOUT_S)
        stack.callback(_end, proc)
        ev = BusEvents(bus)
        stack.callback(ev.close)
        puma = ev.arm("puma")
        q = puma.q.copy()
        q[0] += 0.3 if q[0] < 0 else -0.3
        a = ev.move_ev(puma, joint_position("long_way", puma.kinematics, q))
        ev.wait_ev(a, started=True, timeout=5.0)
        time.sleep(0.1)
        t_stop = time.monotonic()                  # before the signal: the figure can only be too long
        os.kill(proc.pid, signal.SIGSTOP)
        try:
            ev.wait_ev(a, timeout=10.0)
        except ArmLost:
            return time.monotonic() - t_stop
        raise RuntimeError("the stopped arm process was not given up")


def _stats(xs: list[float], rate_hz: int) -> str:
    a = np.asarray(xs) * 1e3
    sample_ms = 1e3 / rate_hz
    return (f"{a.min():.1f} | {np.median(a):.1f} | {a.max():.1f} | {np.max(a) / sample_ms:.2f} | {len(a)}")


def render(lat: dict[str, list[float]], faults: dict[str, list[float]], rate_hz: int, command: str,
           load: tuple[float, float]) -> str:
    sample_ms = 1e3 / rate_hz
    spread = np.asarray(lat["spread"]) * 1e3
    lines = [
        "# Event flags across processes on the Zenoh bus",
        "",
        f"Generated by `{command}` on {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {platform.machine()}, "
        f"{os.cpu_count()} cores, Python {platform.python_version()}; load average (1 min) {load[0]:.1f} at the start, "
        f"{load[1]:.1f} at the end (the machine is shared).",
        "",
        f"Real processes on loopback: two real-time simulas (PUMA 260, Microbo), two arm processes "
        f"(`python -m rccl.bus.arm`, {rate_hz} Hz: one sample is {sample_ms:.0f} ms) linked to them by sockets, the "
        "planning level in the bench's process (the bus's hub). The plan is `examples/two_arm_flags.py`'s `plan` with "
        "small moves, run on the same processes each time. Times are the processes' `time.monotonic()` (one host, "
        "one clock). See the module's docstring (`bench/zenoh_flags.py`) for each row's definition.",
        "",
        "| | min (ms) | median (ms) | max (ms) | max (samples) | runs |",
        "|---|---|---|---|---|---|",
        f"| bus hop: A's motion ended -> B's start flag set | {_stats(lat['hop'], rate_hz)} |",
        f"| A's motion ended -> B's motion began | {_stats(lat['began'], rate_hz)} |",
        f"| `start_ev(7, c, d)`: c and d began apart | {_stats(lat['spread'], rate_hz)} |",
        f"| `start_ev(7, c, d)` returned (message out, both acknowledgements back) | "
        f"{_stats(lat['start_ev'], rate_hz)} |",
        "",
        f"c and d began within one sample of each other in {int(np.sum(spread <= sample_ms))} of {len(spread)} runs.",
        "The arm processes are the same in every run, so their two sample clocks (two simulas, one rate) keep one "
        "phase: the waits for a next sample (B began, c and d apart) are nearly constant within a run and differ "
        "from run to run of the bench, between 0 and one sample; the bus hop and the round trip do not depend on it.",
    ]
    if not any(faults.values()):
        return "\n".join(lines) + "\n"
    lines += [
        "",
        "## A peer lost",
        "",
        f"Heartbeats (arm processes and planning levels) every {HEARTBEAT_S * 1e3:.0f} ms, silence "
        f"{SILENCE_S * 1e3:.0f} ms both ways (`rccl.bus.planning`), a "
        f"start_ev / stop_ev re-sent after {RESEND_S * 1e3:.0f} ms without acknowledgement; simula's watchdog "
        f"{WATCHDOG_S * 1e3:.0f} ms. Fresh processes for each run.",
        "",
        "| fault | noticed by | min (ms) | median (ms) | max (ms) | max (samples) | runs |",
        "|---|---|---|---|---|---|---|",
    ]
    if faults["planner"]:
        lines.append("| planning process (the hub) killed mid-motion | the arm process: the planner's liveliness "
                     f"token ends; it aborts that planner's motions and holds | {_stats(faults['planner'], rate_hz)} |")
    if faults.get("planner_stopped"):
        lines.append("| planning process stopped (SIGSTOP) mid-motion | the arm process: no heartbeat of the planner "
                     "for its silence; it gives that planner up, aborts its motions and holds | "
                     f"{_stats(faults['planner_stopped'], rate_hz)} |")
    if faults["stopped"]:
        lines.append("| arm process stopped (SIGSTOP) while the plan waits on it | the planning level: no heartbeat "
                     f"for the silence; `wait_ev` raises `ArmLost` | {_stats(faults['stopped'], rate_hz)} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=20, help="plans run (flag latencies)")
    ap.add_argument("--fault-runs", type=int, default=5, help="runs of each fault (0: none)")
    ap.add_argument("--rate", type=int, default=50, help="the arms' sample rate (Hz)")
    ap.add_argument("--out", default=str(ROOT / "reports" / "bench-flags.md"), help="'-' to print only")
    a = ap.parse_args(argv)
    if a.runs < 1 or a.fault_runs < 0 or a.rate < 1:
        ap.error("--runs >= 1, --fault-runs >= 0, --rate >= 1")
    load0 = os.getloadavg()[0]
    lat = flag_latencies(a.runs, a.rate)
    faults = {"planner": [planner_killed(a.rate) for _ in progress(range(a.fault_runs), "planner killed")],
              "planner_stopped": [planner_stopped(a.rate) for _ in progress(range(a.fault_runs), "planner stopped")],
              "stopped": [arm_stopped(a.rate) for _ in progress(range(a.fault_runs), "arm stopped")]}
    command = COMMAND if argv is None and sys.argv[1:] == [] else "python -m bench.zenoh_flags " + " ".join(
        sys.argv[1:] if argv is None else argv)
    emit(render(lat, faults, a.rate, command, (load0, os.getloadavg()[0])), a.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
