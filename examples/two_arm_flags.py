"""Two arms coordinated by event flag triples (thesis 5.6.3), checked by a Petri net before they move.

A PUMA 260 goes over a part; the Microbo goes under it the sample the PUMA arrives
(``start=a``); then both leave together (``start_ev`` on two postponed motions). The
planning function ``plan`` is written once against the event-flag primitives: given
``rccl.events`` and real arms it runs; given ``rccl.petri``'s recorder it only records the
flag triples, from which the static check builds the program's Petri net and proves it
free of deadlocks before anything moves.

    python examples/two_arm_flags.py --check-only       # the static check alone: prints the net's report
    python examples/two_arm_flags.py --simula           # check, then run on two lockstep, powered simulas
    python examples/two_arm_flags.py URL_PUMA URL_MICROBO  # two powered arms (simula -p --power-on, or real)
    python examples/two_arm_flags.py --bus --simula     # three processes on the Zenoh bus (below)
    python -m rccl.petri examples/two_arm_flags.py:plan puma microbo     # the same check, from the shell

With ``--bus`` the same ``plan`` runs in this (planning) process against arms served by two
arm processes (``python -m rccl.bus.arm``), each driving its robot over its own link
(``--simula``: two real-time simulas -p --power-on serving on the bus, ``zenoh/KEY``): the
flags cross the bus (rccl.bus.planning), each arm process reports the end of each motion to
the planning level on a channel, and the planning process is the bus's hub the arm
processes connect to (``--listen ENDPOINT``, by default a free loopback port).
"""
from __future__ import annotations

import argparse
import sys
from contextlib import ExitStack

from rccl import petri
from rci.bus.link import free_endpoint


def plan(ev, puma, mic, pos=None) -> dict:
    """The planning level. ``pos`` maps names to positions (names stand for themselves when recording)."""
    pos = pos or {}
    p = lambda name: pos.get(name, name)         # noqa: E731
    a = ev.move_ev(puma, p("over_part"))                       # starts when ready
    b = ev.move_ev(mic, p("under_part"), start=a)              # starts the sample the PUMA arrives
    c = ev.move_ev(puma, p("away"), start=None)                # held
    d = ev.move_ev(mic, p("lift"), start=None)                 # held
    ev.wait_ev(b)
    ev.start_ev(7, c, d)                                       # both start together, start code 7
    ev.wait_ev(c)
    ev.wait_ev(d)
    ev.free_ev(a, b, c, d)
    return {"a": a, "b": b, "c": c, "d": d}


def waist(arm, delta: float, name: str):
    """A position with the waist turned by ``delta`` rad (towards the middle of its range)."""
    from rccl.position import joint_position
    q = arm.q.copy()
    q[0] += -abs(delta) if q[0] > 0 else abs(delta)
    return joint_position(name, arm.kinematics, q)


def run(url_puma: str, url_microbo: str, **options) -> dict:
    """Check the flags statically, then run ``plan`` on two RCCL arms; the EFTs, ended."""
    import rccl.adaptive
    from rccl import events as ev
    petri.check(plan, "puma", "microbo")            # raises Deadlock before anything moves
    with rccl.adaptive.open(url_puma, "puma260", **options) as puma, \
            rccl.adaptive.open(url_microbo, "microbo", **options) as mic:
        ev.attach(puma, "puma")
        ev.attach(mic, "microbo")
        try:
            pos = {"over_part": waist(puma, 0.3, "over_part"), "under_part": waist(mic, 0.2, "under_part")}
            pos["away"] = waist(puma, 0.15, "away")
            pos["lift"] = waist(mic, 0.1, "lift")
            efts = plan(ev, puma, mic, pos)
            return {k: (e.status, e.t_started, e.t_ended) for k, e in efts.items()}
        finally:
            ev.detach(puma)
            ev.detach(mic)


CELL = "two-arm-flags"
ARMS = {"puma": "puma260", "microbo": "microbo"}
ARM_START_S = 60.0     # s: how long run_bus waits for an arm process it started to serve its arm


def run_bus(urls: dict[str, str], listen: str, rate_hz: int = 50, how_timeout: float | None = None,
            silence: float | None = None) -> dict:
    """Check the flags statically, start the two arm processes, run ``plan`` from this process.

    Returns ``{"efts": {name: RemoteEFT}, "reports": [(arm, report), ...], "targets": {name: q}}``:
    the EFTs (ended and freed), what the arm processes reported on their channels, and the
    joint angles each motion aimed at."""
    from rccl.bus import arm as bus_arm
    from rccl.bus.planning import BusEvents
    from rci.bus import Bus
    petri.check(plan, "puma", "microbo")            # raises Deadlock before anything moves
    with Bus(CELL, tasks=("planning",), listen=(listen,), priority=bus_arm.BUS_PRIORITY) as bus, \
            ExitStack() as stack:
        channels = {name: bus.channel(name, "planning", capacity=16) for name in ARMS}
        for name, robot in ARMS.items():
            proc = bus_arm.spawn(name, urls[name], robot, CELL, (listen,), rate_hz, how_timeout=how_timeout)
            stack.callback(_end, proc)
        # silence: how long the arms wait for this planning level's heartbeat before giving it up
        # (BusEvents' default when None; longer where this process may wait for a CPU)
        ev = BusEvents(bus) if silence is None else BusEvents(bus, silence=silence)
        stack.callback(ev.close)
        # the arm processes were just started: on a loaded machine their start (imports, the
        # link, the bus) took over the default 10 s, so wait for each as long as a start may take
        puma, mic = ev.arm("puma", timeout=ARM_START_S), ev.arm("microbo", timeout=ARM_START_S)
        pos = {"over_part": waist(puma, 0.3, "over_part"), "under_part": waist(mic, 0.2, "under_part")}
        pos["away"] = waist(puma, 0.15, "away")
        pos["lift"] = waist(mic, 0.1, "lift")
        efts = plan(ev, puma, mic, pos)
        puma.close()
        mic.close()
        reports = []
        for name, ch in channels.items():
            while len([r for r in reports if r[0] == name]) < 2 and (msg := ch.receive(timeout=2.0)) is not None:
                reports.append((name, msg))
        return {"efts": efts, "reports": reports, "targets": {k: p.joints for k, p in pos.items()}}


def _end(proc) -> None:
    """Wait for an arm process told to close; kill it if it does not end."""
    try:
        proc.wait(10)
    except Exception:
        proc.kill()
        proc.wait(5)


def _bus_main(a, ap) -> int:
    with ExitStack() as stack:
        if a.simula:
            from rci.simula.process import SimulaProcess
            urls = {name: stack.enter_context(SimulaProcess("-p", "--power-on", "--zenoh", f"lab/{name}",
                                                            "--zenoh-listen", free_endpoint(),
                                                            "--watchdog-time", str(a.watchdog), robot=robot,
                                                            lockstep=False)).url
                    for name, robot in ARMS.items()}
        elif len(a.urls) == 2:
            urls = dict(zip(ARMS, a.urls))
        else:
            ap.error("give two link URLs (PUMA, Microbo) or --simula")
        out = run_bus(urls, a.listen or free_endpoint(), a.rate, a.how_timeout)
    for arm, r in out["reports"]:
        print(f"{arm} reports: motion #{r['serial']} to {r['where']} ended {r['status']}, "
              f"waist at {r['q'][0]:+.4f} rad")
    e = out["efts"]
    for k, x in e.items():
        print(f"motion {k} ({x.arm}): status {x.status}, began {x.t_started:.3f} s, ended {x.t_ended:.3f} s (monotonic)")
    print(f"b began {1e3 * (e['b'].t_started - e['a'].t_ended):.1f} ms after a ended; "
          f"c and d began {1e3 * abs(e['c'].t_started - e['d'].t_started):.1f} ms apart")
    return 0


def _cli(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("urls", nargs="*", help="PUMA link URL, Microbo link URL (arms with power on)")
    ap.add_argument("--simula", action="store_true", help="start two lockstep simulas (-p --power-on) for the run")
    ap.add_argument("--check-only", action="store_true", help="only the static Petri-net check")
    ap.add_argument("--bus", action="store_true", help="planning here, each arm in its own process, on the Zenoh bus")
    ap.add_argument("--listen", help="with --bus: the Zenoh endpoint this process listens on (default: free loopback port)")
    ap.add_argument("--rate", type=int, default=50, help="with --bus: the arms' sample rate (Hz)")
    ap.add_argument("--how-timeout", type=float, default=None,
                    help="with --bus: the arm processes' wait for a HOW (s; default two periods)")
    ap.add_argument("--watchdog", type=float, default=0.1,
                    help="with --bus and --simula, the watchdog of the simulas started "
                         "(s without a CHG before they hold the arm)")
    a = ap.parse_args(argv)
    result = petri.analyse(petri.record(plan, "puma", "microbo").net())
    print(result.report())
    if a.check_only or not result.ok:
        return 0 if result.ok else 1
    if a.bus:
        return _bus_main(a, ap)
    with ExitStack() as stack:
        if a.simula:
            from rci.simula.process import SimulaProcess
            urls = [stack.enter_context(SimulaProcess("-p", "--power-on", robot=r, lockstep=True)).url for r in ("puma260", "microbo")]
        elif len(a.urls) == 2:
            urls = a.urls
        else:
            ap.error("give two link URLs (PUMA, Microbo), --simula or --check-only")
        ended = run(urls[0], urls[1], lockstep_timeout=2.0)
    for k, (status, t0, t1) in ended.items():
        print(f"motion {k}: status {status}, began {t0:.3f} s, ended {t1:.3f} s (monotonic)")
    return 0


if __name__ == "__main__":
    sys.exit(_cli())
