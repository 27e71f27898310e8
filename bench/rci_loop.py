"""Bench: the RCI control loop against simula in real-time mode at 36, 250 and 1000 Hz.

For each rate: start ``simula -p --power-on`` (real time, its own clock), open a session
(SCHED_FIFO, mlockall, frozen GC where the OS allows), run a control whose f1 does what a
minimal real program does (encoder counts -> angles, hold every joint with POS), for
``--seconds`` each, and report: cycles, missed cycles (robot-side late/missing CHG plus
sequence gaps), controller overruns, period jitter (|HOW inter-arrival - period|) p50/p99/max,
RCI's own work per cycle and the share of the period left to user code.

    python bench/rci_loop.py                      # 36, 250, 1000 Hz x 30 s, then the stress run -> reports/bench-rci.md
    python bench/rci_loop.py --seconds 5 --rates 1000 --stress-seconds 10 --out /tmp/b.md
    python bench/rci_loop.py --cpu -1            # let the scheduler place both processes

The stress run (issue 13, item 5) is a control at 1 kHz for ``--stress-seconds`` (60 s) with
two CPU hogs (busy-looping processes at normal priority, unpinned) and the session's
default lateness policy (``overrun="auto"``: the control ends after ``late_limit`` late
cycles in a row, 20 at 1 kHz): it counts the terminations (a terminated control is
started again at once, so the run always lasts its time), the missed cycles and the
longest run of late cycles. Target: 0 terminations, missed cycles <= 0.5 %.

By default simula and the controller are pinned to the machine's last CPU (see
``rci.realtime.pin_to_cpus`` for why); ``--cpu N`` picks another one, ``--cpu -1`` none.
"""
from __future__ import annotations

import argparse
import os
import platform
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import subprocess  # noqa: E402

from rci.exceptions import ControlTerminated  # noqa: E402
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


def hold_program(s: Session, conv: Conversions):
    """f1 of a minimal real program: encoder counts -> angles, every joint held with POS where it started."""
    hold: dict[str, np.ndarray] = {}

    def f1() -> None:
        q = conv.counts_to_angles(s.how.pos)
        if "q" not in hold:
            hold["q"] = q
        conv.command_positions(s.chg, hold["q"])
    return f1


def _link_args(link: str, keys_dir: str) -> tuple[tuple[str, ...], str]:
    """simula's options for the link under test and what the controller adds to simula's address:
    TCP (default), the Zenoh bus on loopback, or the Zenoh bus with the security of docs/security.md
    (``zenoh-secure``: mutual TLS, access control, a cell made by ``python -m rci.bus.keys`` in
    ``keys_dir``; the link's frames are encrypted and authenticated on every Zenoh link)."""
    if link == "socket":
        return (), ""
    from rci.bus.link import free_endpoint
    if link == "zenoh":
        return ("--zenoh", "bench/puma260", "--zenoh-listen", free_endpoint()), ""
    from rci.bus.keys import make_cell
    port = int(free_endpoint().rsplit(":", 1)[1])
    keys = make_cell(keys_dir, ["bench/puma260"], ["127.0.0.1"], port)
    return ("--zenoh", "bench/puma260", "--zenoh-config", str(keys["robot"])), f"&config={keys['controller']}"


def _pin_threads(pid: int, cpu: int) -> None:
    """Every thread of process ``pid`` (simula's Zenoh threads, which it started before the
    bench pinned its main thread) to ``cpu``, as the controller's Zenoh threads are (they
    inherit the control thread's CPU). Each frame passes from a Zenoh thread to the main
    thread; on one CPU that hand-off is a wake-up where the sender runs (see
    ``rci.realtime.pin_to_cpus``)."""
    for tid in os.listdir(f"/proc/{pid}/task"):
        pin_to_cpus({cpu}, int(tid))


def run_rate(rate: int, seconds: float, cpu: int | None = None, link: str = "socket") -> dict:
    conv = Conversions.for_robot("puma260")
    load0, steal0 = os.getloadavg()[0], _steal_ticks()
    keys_dir = tempfile.mkdtemp(prefix="rcci-bench-cell-")
    simula_args, url_tail = _link_args(link, keys_dir)
    with SimulaProcess("-p", "--power-on", "--rate", str(rate), *simula_args, lockstep=False) as sim:
        pinned: bool | str = "no"
        if cpu is not None:
            pinned = pin_to_cpus({cpu}, sim.proc.pid)          # simula's thread (over the socket, its only one)
            if link.startswith("zenoh") and pinned is True:
                _pin_threads(sim.proc.pid, cpu)                # simula's Zenoh threads with it
            if pinned is True:
                pinned = pin_to_cpus({cpu})                    # this thread: the control thread inherits it
        with Session(sim.url + url_tail, "puma260", rate_hz=rate, overrun="count", timeout=0.5,
                     on_error="raise") as s:
            s.control(hold_program(s, conv))
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
    shutil.rmtree(keys_dir, ignore_errors=True)
    if cpu is not None and pinned is True:
        pin_to_cpus(set(range(os.cpu_count() or 1)))        # give this process all CPUs back
    steal1 = _steal_ticks()
    d = summary.as_dict()
    d.update(rate=rate, link=link, seconds=seconds, robot_overruns=robot_overruns, realtime=rt, load=os.getloadavg()[0],
             load0=load0, steal_ms=(steal1 - steal0) * 1000.0 / os.sysconf("SC_CLK_TCK") if steal0 >= 0 else float("nan"),
             pinned="not pinned" if cpu is None else f"CPU {cpu}" if pinned is True else f"not pinned ({pinned})",
             warm_missed=warm_missed, steady_missed=d["missed"] - warm_missed, long_gaps=long_gaps)
    return d


ECHO = """
import sys
from rci.bus import Bus
with Bus("bench-echo", tasks=("echo",), connect=(sys.argv[1],)) as bus:
    inbox, outbox = bus.channel("planning", "echo", 64, "block"), bus.channel("echo", "planning", 64, "block")
    print("ready", flush=True)
    while True:
        msg = inbox.receive(timeout=5.0)
        if msg is None or msg == "stop":
            break
        outbox.send(msg)
"""


def bus_round_trip(n: int = 2000) -> dict:
    """Round trip of a channel message between two processes over the Zenoh bus (rci.bus):
    planning -> echo process -> planning, one message in flight, a 6-float payload."""
    from rci.bus import Bus
    from rci.bus.link import free_endpoint

    endpoint = free_endpoint()
    with Bus("bench-echo", tasks=("planning",), listen=(endpoint,)) as bus:
        out, back = bus.channel("planning", "echo", 64, "block"), bus.channel("echo", "planning", 64, "block")
        proc = subprocess.Popen([sys.executable, "-c", ECHO, endpoint], stdout=subprocess.PIPE, text=True,
                                cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT)})
        try:
            assert proc.stdout.readline().strip() == "ready"
            time.sleep(0.2)
            rtt = []
            q = np.zeros(6)
            for i in range(n + 100):
                t0 = time.perf_counter()
                out.send({"i": i, "q": q})
                msg = back.receive(timeout=2.0)
                if msg is None:
                    raise RuntimeError(f"bus round trip: message {i} not echoed within 2 s")
                if i >= 100:                                  # the first 100 warm up
                    rtt.append(time.perf_counter() - t0)
            out.send("stop")
            proc.wait(5)
        finally:
            if proc.poll() is None:
                proc.kill()
    r = np.array(rtt) * 1e6
    return {"n": n, "p50": float(np.percentile(r, 50)), "p90": float(np.percentile(r, 90)),
            "p99": float(np.percentile(r, 99)), "max": float(r.max())}


def start_hogs(n: int) -> list[subprocess.Popen]:
    """``n`` processes that only burn CPU (normal priority, any CPU)."""
    return [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(n)]


def stress_run(rate: int, seconds: float, hogs: int, cpu: int | None) -> dict:
    """A control at ``rate`` for ``seconds`` with ``hogs`` CPU hogs, default lateness policy;
    a terminated control is counted and started again."""
    conv = Conversions.for_robot("puma260")
    load0 = os.getloadavg()[0]
    hog_procs = start_hogs(hogs)
    terminations: list[str] = []
    totals = dict(cycles=0, missed=0, late_cycles=0, overruns=0, late_run_max=0, late_limit=0, duplicates=0)
    jitter99, dur99 = [], []
    try:
        time.sleep(1.0)                                      # let the hogs reach full speed
        with SimulaProcess("-p", "--power-on", "--rate", str(rate), lockstep=False) as sim:
            if cpu is not None and pin_to_cpus({cpu}, sim.proc.pid) is True:
                pin_to_cpus({cpu})
            with Session(sim.url, "puma260", rate_hz=rate, timeout=0.5, on_error="raise") as s:
                f1 = hold_program(s, conv)

                def collect() -> None:
                    sm = s.timing.summary()
                    for k in ("cycles", "missed", "late_cycles", "overruns", "duplicates"):
                        totals[k] += getattr(sm, k)
                    totals["late_run_max"] = max(totals["late_run_max"], sm.late_run_max)
                    totals["late_limit"] = sm.late_limit
                    if sm.cycles > 1:
                        jitter99.append(sm.jitter_p99)
                        dur99.append(sm.duration_p99)

                t_end = time.monotonic() + seconds
                while time.monotonic() < t_end:
                    try:
                        s.control(f1)
                        s.wait(max(t_end - time.monotonic(), 0.0))
                        s.release()
                    except ControlTerminated as e:
                        terminations.append(f"{e.termination.name}: {e.termination.detail[:120]}")
                    collect()
                rt = s.rt_status.summary()
        if cpu is not None:
            pin_to_cpus(set(range(os.cpu_count() or 1)))
    finally:
        for p in hog_procs:
            p.kill()
            p.wait()
    return dict(rate=rate, seconds=seconds, hogs=hogs, terminations=terminations, load0=load0,
                placement="not pinned" if cpu is None else f"both on CPU {cpu}",
                load=os.getloadavg()[0], realtime=rt, jitter_p99=max(jitter99, default=float("nan")),
                duration_p99=max(dur99, default=float("nan")), **totals)


def render_stress(runs: list[dict]) -> list[str]:
    r0 = runs[0]
    lines = [
        "",
        f"## Stress: {r0['rate']} Hz for {r0['seconds']:.0f} s with {r0['hogs']} CPU hogs, default lateness policy",
        "",
        f"{r0['hogs']} processes busy-loop at normal priority on any CPU while a control runs with the session's",
        "defaults (`overrun=\"auto\"`: the control ends after `late_limit` late cycles in a row; "
        f"{r0['late_limit']} at {r0['rate']} Hz).",
        "A terminated control would be counted and started again at once. Once with simula and the controller",
        "pinned to one CPU (as the rows above), once left to the scheduler.",
        "",
        "| simula and controller | terminations | cycles | missed (robot saw no CHG in time) | missed % | late cycles "
        "| longest late run | limit | controller overruns | jitter p99 (us) | cycle work p99 (us) | load avg start / end "
        "| verdict |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in runs:
        missed_pct = 100.0 * r["missed"] / max(r["cycles"] + r["missed"], 1)
        ok = not r["terminations"] and missed_pct <= 0.5
        lines.append(
            f"| {r['placement']} | {len(r['terminations'])} | {r['cycles']} | {r['missed']} | {missed_pct:.3f} % "
            f"| {r['late_cycles']} | {r['late_run_max']} | {r['late_limit']} | {r['overruns']} "
            f"| {r['jitter_p99'] * 1e6:.0f} | {r['duration_p99'] * 1e6:.0f} | {r['load0']:.1f} / {r['load']:.1f} "
            f"| {'meets' if ok else 'MISSES'} the target (0 terminations, missed <= 0.5 %) |")
    lines.append("")
    for r in runs:
        for t in r["terminations"]:
            lines.append(f"- termination ({r['placement']}): {t}")
    lines += ["- *load avg*: includes the two hogs themselves (they add 2).",
              "- Before the lateness policy (commit bd8741e, which ended a control on its first late cycle), the",
              "  same program with two hogs was ended after 6,000-8,000 cycles and, restarted, again and again:",
              "  627 terminations in 20 s not pinned, 2 pinned (measured 2026-11-24, docs/rci.md \"Late cycles\").",
              ""]
    return lines


def render(results: list[dict], command: str, stress: list[dict] | None = None, bus: dict | None = None) -> str:
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
        "| link | rate (Hz) | s | cycles | missed (warm-up / after) | overruns | HOW gaps > 2 periods | jitter p50 (us) | jitter p99 (us) | jitter max (us) "
        "| RCI work p50 / p99 (us) | period left to user code p50 / p99 | load avg (1 min) start / end | steal (ms) |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in results:
        lines.append(
            f"| {r.get('link', 'socket')} | {r['rate']}{'' if r['pinned'] == results[0]['pinned'] else ' (' + r['pinned'] + ')'} | {r['seconds']:.0f} | {r['cycles']} | {r['warm_missed']} / {r['steady_missed']} | {r['overruns']} | {r['long_gaps']} "
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
        "  simula's own timing error, the link and the controller's wake-up latency.",
        "- *link*: `socket` is TCP on loopback (`socket://127.0.0.1:PORT`); `zenoh` is the Zenoh bus",
        "  (`simula --zenoh KEY`, link address `zenoh/KEY?connect=tcp/127.0.0.1:PORT`, peer to peer over TCP on",
        "  loopback, rci/bus/link.py): each frame is a publication, handed to the reader by the Zenoh thread",
        "  that received it; in a pinned run both processes' Zenoh threads share their CPU (real time, priority + 1).",
        "  At 1 kHz that CPU is then busy with real-time work about 95 % of each second, and the kernel's",
        "  real-time throttling (sched_rt_runtime_us) stops its real-time threads ~50 ms once a second",
        "  (HOW gaps, jitter max; docs/zenoh.md \"Speed\").",
        "- *zenoh-secure*: the same with the security of docs/security.md on: mutual TLS (`tls/127.0.0.1:PORT`),",
        "  Zenoh's access control on simula's session, a cell made by `python -m rci.bus.keys`. Every Zenoh row",
        "  has the link's own frame security (each frame encrypted and authenticated, ChaCha20-Poly1305).",
        "- *RCI work*: the control task's own time per cycle (decode, checks, encode, send), user functions excluded;",
        "  *period left to user code* = 1 - RCI work / period.",
        f"- Real-time set-up achieved: {results[0]['realtime'] if results else 'n/a'}.",
        "- *load avg*: the machine's 1-minute load average at the start and the end of the run (2 cores, shared",
        "  with other work): a load above 2 means other processes competed for the CPUs during the measurement.",
        "- *steal*: CPU time the hypervisor took from this VM during the run (/proc/stat), summed over CPUs.",
        "- Target (issue 4): 1 kHz with zero missed cycles and p99 jitter <= 200 us.",
        "",
    ]
    if any(r.get("link", "").startswith("zenoh") for r in results):
        lines += _zenoh_ratios(results)
    if bus:
        lines += ["## A channel message between two processes over the bus", "",
                  f"`rci.bus`: planning -> a second process -> planning, {bus['n']} messages one at a time "
                  "(a dict with a 6-float array, `block` channels), after 100 for warm-up; loopback TCP.", "",
                  "| round trip p50 (us) | p90 (us) | p99 (us) | max (us) |", "|---|---|---|---|",
                  f"| {bus['p50']:.0f} | {bus['p90']:.0f} | {bus['p99']:.0f} | {bus['max']:.0f} |", ""]
    if stress:
        lines += render_stress(stress)
    return "\n".join(lines)


def _zenoh_ratios(results: list[dict]) -> list[str]:
    """Zenoh against the socket at the same rate, same run."""
    out = ["## The link over Zenoh against the socket (same run)", "",
           "| link | rate (Hz) | missed after warm-up socket / zenoh | jitter p50 zenoh / socket | jitter p99 zenoh / socket "
           "| RCI work p99 zenoh / socket |", "|---|---|---|---|---|---|"]
    sock = {r["rate"]: r for r in results if r.get("link", "socket") == "socket"}
    for z in (r for r in results if r.get("link", "").startswith("zenoh")):
        s = sock.get(z["rate"])
        if s is None:
            continue
        ratio = lambda k: z[k] / s[k] if s[k] > 0 else float("nan")      # noqa: E731
        out.append(f"| {z['link']} | {z['rate']} | {s['steady_missed']} / {z['steady_missed']} | {ratio('jitter_p50'):.1f}x "
                   f"| {ratio('jitter_p99'):.1f}x ({z['jitter_p99'] * 1e6:.0f} us) | {ratio('overhead_p99'):.2f}x |")
    return out + ["", "Goal (issues 17 and 26): 1 kHz over Zenoh on loopback, with and without the security on, "
                  "with 0 missed cycles and p99 jitter <= 200 us on a quiet machine.", ""]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rates", type=int, nargs="*", default=[36, 250, 1000])
    ap.add_argument("--seconds", type=float, default=30.0)
    ap.add_argument("--out", default=str(ROOT / "reports" / "bench-rci.md"))
    ap.add_argument("--cpu", type=int, default=(os.cpu_count() or 1) - 1,
                    help="CPU to pin simula and the controller to (default: the last one; -1: no pinning)")
    ap.add_argument("--stress-seconds", type=float, default=60.0,
                    help="length of the 1 kHz run with CPU hogs and the default lateness policy (0: skip it)")
    ap.add_argument("--hogs", type=int, default=2, help="CPU hogs during the stress run")
    ap.add_argument("--only-stress", action="store_true", help="skip the per-rate runs")
    ap.add_argument("--zenoh-rates", type=int, nargs="*", default=[250, 1000],
                    help="rates run once more over the Zenoh link (rci/bus/link.py), for the comparison")
    ap.add_argument("--secure-rates", type=int, nargs="*", default=[1000],
                    help="rates run once more over the Zenoh link with TLS + access control (docs/security.md)")
    ap.add_argument("--unpinned-too", action="store_true",
                    help="after the pinned runs, run the highest rate once more without pinning (for comparison)")
    args = ap.parse_args(argv)
    results = []
    for rate in ([] if args.only_stress else args.rates):
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
    runs = [(rate, "zenoh") for rate in args.zenoh_rates] + [(rate, "zenoh-secure") for rate in args.secure_rates]
    for rate, link in ([] if args.only_stress else runs):
        r = run_rate(rate, args.seconds, None if args.cpu < 0 else args.cpu, link=link)
        print(f"{rate:5d} Hz over {link}: cycles {r['cycles']}, missed {r['warm_missed']} (warm-up) + {r['steady_missed']}, "
              f"jitter p50/p99/max {r['jitter_p50'] * 1e6:.0f}/{r['jitter_p99'] * 1e6:.0f}/{r['jitter_max'] * 1e6:.0f} us, "
              f"RCI work p99 {r['overhead_p99'] * 1e6:.0f} us, HOW gaps > 2 periods {r['long_gaps']}, "
              f"load {r['load0']:.1f} -> {r['load']:.1f}, steal {r['steal_ms']:.0f} ms, {r['pinned']}", flush=True)
        results.append(r)
    bus = None
    if not args.only_stress and args.zenoh_rates:
        bus = bus_round_trip()
        print(f"bus round trip between two processes: p50 {bus['p50']:.0f} us, p99 {bus['p99']:.0f} us", flush=True)
    stress = []
    if args.stress_seconds > 0:
        for cpu in ([args.cpu, None] if args.cpu >= 0 else [None]):
            r = stress_run(1000, args.stress_seconds, args.hogs, cpu)
            print(f"stress 1000 Hz {args.stress_seconds:.0f} s, {args.hogs} hogs, {r['placement']}: terminations "
                  f"{len(r['terminations'])}, cycles {r['cycles']}, missed {r['missed']}, longest late run "
                  f"{r['late_run_max']} (limit {r['late_limit']}), load {r['load0']:.1f} -> {r['load']:.1f}", flush=True)
            stress.append(r)
    command = "python bench/rci_loop.py" + ("" if argv is None and len(sys.argv) == 1 else " " + " ".join(sys.argv[1:] if argv is None else argv))
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(render(results, command, stress, bus))
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
