"""Bench: the RCI control loop against simula in real-time mode at 36, 250 and 1000 Hz.

For each rate: start ``simula -p --power-on`` (real time, its own clock), open a session
(SCHED_FIFO, mlockall, frozen GC where the OS allows), run a control whose f1 does what a
minimal real program does (encoder counts -> angles, hold every joint with POS), for
``--seconds`` each, and report: cycles, missed cycles (robot-side late/missing CHG plus
sequence gaps), controller overruns, period jitter (|HOW inter-arrival - period|) p50/p99/max,
RCI's own work per cycle and the share of the period left to user code.

    python bench/rci_loop.py                      # 36, 250, 1000 Hz x 30 s -> reports/bench-rci.md
    python bench/rci_loop.py --seconds 5 --rates 1000 --out /tmp/b.md
    python bench/rci_loop.py --cpu -1            # let the scheduler place both processes

By default simula and the controller are pinned to the machine's last CPU (see
``rci.realtime.pin_to_cpus`` for why); ``--cpu N`` picks another one, ``--cpu -1`` none.
"""
from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from rci.chg import POS  # noqa: E402
from rci.conversions import Conversions  # noqa: E402
from rci.realtime import pin_to_cpus  # noqa: E402
from rci.session import Session  # noqa: E402
from rci.simula.process import SimulaProcess  # noqa: E402


def _steal_ticks() -> int:
    """The machine's cumulative steal time (USER_HZ ticks, /proc/stat), or -1."""
    try:
        with open("/proc/stat") as f:
            fields = f.readline().split()
        return int(fields[8])
    except (OSError, IndexError, ValueError):
        return -1


def kernel_preemption() -> str:
    """The kernel's preemption model, as far as this process can tell."""
    try:
        with open("/sys/kernel/debug/sched/preempt") as f:
            return "preempt " + f.read().strip()
    except OSError:
        pass
    model = ""
    try:
        import gzip
        with gzip.open("/proc/config.gz", "rt") as f:
            for line in f:
                if line.startswith(("CONFIG_PREEMPT_NONE=y", "CONFIG_PREEMPT_VOLUNTARY=y", "CONFIG_PREEMPT=y",
                                    "CONFIG_PREEMPT_RT=y", "CONFIG_PREEMPT_LAZY=y")):
                    model = line.strip().removeprefix("CONFIG_").replace("=y", "")
    except OSError:
        pass
    try:
        with open("/proc/cmdline") as f:
            boot = [w for w in f.read().split() if w.startswith("preempt=")]
    except OSError:
        boot = []
    return (f"{platform.version()}, default model {model or 'unknown'}"
            + (f", booted with {boot[0]}" if boot else ", no preempt= on the boot line"))


def run_rate(rate: int, seconds: float, cpu: int | None = None) -> dict:
    conv = Conversions.for_robot("puma260")
    load0, steal0 = os.getloadavg()[0], _steal_ticks()
    with SimulaProcess("-p", "--power-on", "--rate", str(rate), lockstep=False) as sim:
        pinned: bool | str = "no"
        if cpu is not None:
            pinned = pin_to_cpus({cpu}, sim.proc.pid)          # simula's (single) thread
            if pinned is True:
                pinned = pin_to_cpus({cpu})                    # this thread: the control thread inherits it
        with Session(sim.url, "puma260", rate_hz=rate, overrun="count", timeout=0.5, on_error="raise") as s:
            hold: dict[str, np.ndarray] = {}

            def f1() -> None:
                q = conv.counts_to_angles(s.how.pos)
                if "q" not in hold:
                    hold["q"] = q
                    hold["counts"] = conv.angles_to_counts_int(q)
                for j, c in enumerate(hold["counts"]):
                    s.chg.motion[j].issue(POS, int(c))

            s.control(f1)
            s.wait(0.5)                                      # warm-up (first calls, caches)
            warm_missed = s.timing.missed
            s.wait(max(seconds - 0.5, 0.0))
            robot_overruns = s.how.robot_overruns
            s.release()
            summary = s.timing.summary(skip=rate // 2)      # skip the first half second (warm-up)
            n = min(s.timing.count, s.timing.capacity)
            arrivals = s.timing.arrival[:n][rate // 2:] if s.timing.count <= s.timing.capacity else np.array([])
            long_gaps = int(np.sum(np.diff(arrivals) > 2.0 / rate)) if len(arrivals) > 1 else 0
            rt = s.rt_status.summary()
    if cpu is not None and pinned is True:
        pin_to_cpus(set(range(os.cpu_count() or 1)))        # give this process all CPUs back
    steal1 = _steal_ticks()
    d = summary.as_dict()
    d.update(rate=rate, seconds=seconds, robot_overruns=robot_overruns, realtime=rt, load=os.getloadavg()[0],
             load0=load0, steal_ms=(steal1 - steal0) * 1000.0 / os.sysconf("SC_CLK_TCK") if steal0 >= 0 else float("nan"),
             pinned="not pinned" if cpu is None else f"CPU {cpu}" if pinned is True else f"not pinned ({pinned})",
             warm_missed=warm_missed, steady_missed=d["missed"] - warm_missed, long_gaps=long_gaps)
    return d


def render(results: list[dict], command: str) -> str:
    lines = [
        "# RCI control loop bench",
        "",
        f"Generated by `{command}` on {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, "
        f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
        f"Linux {platform.release()}.",
        "",
        "simula runs in real-time mode (`simula -p --power-on`, its own clock, SCHED_FIFO 70) in its own",
        "process; the controller is an `rci.session.Session` whose control thread runs under SCHED_FIFO 80",
        "with mlockall and a frozen GC where the OS allows. f1 converts counts to angles and holds every",
        "joint with POS (a minimal real program). The first half second of each run is left out.",
        f"Both processes: {results[0]['pinned'] if results else 'n/a'}. Kernel: {kernel_preemption()}.",
        "",
        "| rate (Hz) | s | cycles | missed (warm-up / after) | overruns | HOW gaps > 2 periods | jitter p50 (us) | jitter p99 (us) | jitter max (us) "
        "| RCI work p50 / p99 (us) | period left to user code p50 / p99 | load avg (1 min) start / end | steal (ms) |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in results:
        lines.append(
            f"| {r['rate']}{'' if r['pinned'] == results[0]['pinned'] else ' (' + r['pinned'] + ')'} | {r['seconds']:.0f} | {r['cycles']} | {r['warm_missed']} / {r['steady_missed']} | {r['overruns']} | {r['long_gaps']} "
            f"| {r['jitter_p50'] * 1e6:.0f} | {r['jitter_p99'] * 1e6:.0f} | {r['jitter_max'] * 1e6:.0f} "
            f"| {r['overhead_p50'] * 1e6:.0f} / {r['overhead_p99'] * 1e6:.0f} "
            f"| {r['user_share_p50'] * 100:.1f} % / {r['user_share_p99'] * 100:.1f} % | {r['load0']:.1f} / {r['load']:.1f} "
            f"| {r['steal_ms']:.0f} |")
    lines += [
        "",
        "- *missed*: cycles the robot saw without a timely CHG (`how.robot_overruns`) plus HOW sequence gaps,",
        "  in the first 0.5 s (warm-up: first calls, cold caches) and after it.",
        "- *overruns*: cycles whose work (HOW arrival to end of f2) exceeded the period (counted, not fatal here).",
        "- *HOW gaps > 2 periods*: after warm-up, successive HOWs that reached the controller more than two periods",
        "  apart: simula itself (or the link) stalled. The controller missed nothing then, so these are not in",
        "  *missed*, but the simulated robot did not keep its period; they are also the *jitter max*.",
        "- *jitter*: |interval between successive HOW arrivals at the controller - period|; it contains",
        "  simula's own timing error, the socket and the controller's wake-up latency.",
        "- *RCI work*: the control task's own time per cycle (decode, checks, encode, send), user functions excluded;",
        "  *period left to user code* = 1 - RCI work / period.",
        f"- Real-time set-up achieved: {results[0]['realtime'] if results else 'n/a'}.",
        "- *load avg*: the machine's 1-minute load average at the start and the end of the run (2 cores, shared",
        "  with other work): a load above 2 means other processes competed for the CPUs during the measurement.",
        "- *steal*: CPU time the hypervisor took from this VM during the run (/proc/stat), summed over CPUs.",
        "- Target (issue 4): 1 kHz with zero missed cycles and p99 jitter <= 200 us.",
        "",
    ]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rates", type=int, nargs="+", default=[36, 250, 1000])
    ap.add_argument("--seconds", type=float, default=30.0)
    ap.add_argument("--out", default=str(ROOT / "reports" / "bench-rci.md"))
    ap.add_argument("--cpu", type=int, default=(os.cpu_count() or 1) - 1,
                    help="CPU to pin simula and the controller to (default: the last one; -1: no pinning)")
    ap.add_argument("--unpinned-too", action="store_true",
                    help="after the pinned runs, run the highest rate once more without pinning (for comparison)")
    args = ap.parse_args(argv)
    results = []
    for rate in args.rates:
        r = run_rate(rate, args.seconds, None if args.cpu < 0 else args.cpu)
        print(f"{rate:5d} Hz: cycles {r['cycles']}, missed {r['warm_missed']} (warm-up) + {r['steady_missed']}, overruns {r['overruns']}, "
              f"jitter p50/p99/max {r['jitter_p50'] * 1e6:.0f}/{r['jitter_p99'] * 1e6:.0f}/{r['jitter_max'] * 1e6:.0f} us, "
              f"RCI work p99 {r['overhead_p99'] * 1e6:.0f} us, left to user p99 {r['user_share_p99'] * 100:.1f} %, "
              f"HOW gaps > 2 periods {r['long_gaps']}, load {r['load0']:.1f} -> {r['load']:.1f}, steal {r['steal_ms']:.0f} ms, {r['pinned']}",
              flush=True)
        results.append(r)
        if args.unpinned_too and rate == max(args.rates) and args.cpu >= 0:
            r = run_rate(rate, args.seconds, None)
            print(f"{rate:5d} Hz unpinned: missed {r['warm_missed']} (warm-up) + {r['steady_missed']}, "
                  f"jitter p50/p99/max {r['jitter_p50'] * 1e6:.0f}/{r['jitter_p99'] * 1e6:.0f}/{r['jitter_max'] * 1e6:.0f} us, "
                  f"load {r['load0']:.1f} -> {r['load']:.1f}", flush=True)
            results.append(r)
    command = "python bench/rci_loop.py" + ("" if argv is None and len(sys.argv) == 1 else " " + " ".join(sys.argv[1:] if argv is None else argv))
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(render(results, command))
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
