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
    python -m rccl.petri examples/two_arm_flags.py:plan puma microbo     # the same check, from the shell
"""
from __future__ import annotations

import argparse
import sys
from contextlib import ExitStack

from rccl import petri


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


def _cli(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("urls", nargs="*", help="PUMA link URL, Microbo link URL (arms with power on)")
    ap.add_argument("--simula", action="store_true", help="start two lockstep simulas (-p --power-on) for the run")
    ap.add_argument("--check-only", action="store_true", help="only the static Petri-net check")
    a = ap.parse_args(argv)
    result = petri.analyse(petri.record(plan, "puma", "microbo").net())
    print(result.report())
    if a.check_only or not result.ok:
        return 0 if result.ok else 1
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
