"""Two arms, one program (thesis 2.4): a PUMA 260 leads, a Microbo Ecureuil follows.

Each arm has its own link to its own robot (or ``simula`` process) and its own control
function, run once per sample. The PUMA's function swings its waist on a slow sine and
publishes its measured joint angles in the workcell's shared data (thesis mode t1: the
latest value, overwritten every sample). The Microbo's function reads them and turns its
own waist the mirror way, as a second arm would keep clear of the first; every
``REPORT_EVERY`` samples it sends a report to the planning level on a channel (mode t3:
bounded, the oldest report is lost if the planning level falls behind). The planning level
prints the reports, then releases both arms.

    python examples/two_arms.py --simula                     # starts two lockstep simulas
    python examples/two_arms.py --simula --sync free         # two real-time simulas, no barrier
    python examples/two_arms.py socket://127.0.0.1:7600 socket://127.0.0.1:7601
    python examples/two_arms.py --simula --rates 72 36        # PUMA at 72 Hz, Microbo at 36 Hz
    python examples/two_arms.py --simula --fail-at 40         # the Microbo's function raises at
                                                              # sample 40: both arms are released
"""
from __future__ import annotations

import argparse
import math
import sys
from contextlib import ExitStack
from dataclasses import dataclass, field

import numpy as np

from rci.chg import POS
from rci.conversions import Conversions
from rci.multi import PLANNING, Workcell

AMPLITUDE = 0.25          # rad, the PUMA waist's swing
SWING_PERIOD = 4.0        # s
REPORT_EVERY = 18         # Microbo samples between reports to the planning level


@dataclass
class Log:
    """What each arm did, one row per control cycle (for plots and the tests)."""

    puma_t: list[float] = field(default_factory=list)
    puma_q: list[np.ndarray] = field(default_factory=list)        # measured (rad)
    microbo_seen: list[np.ndarray | None] = field(default_factory=list)   # PUMA angles it read
    microbo_cmd: list[float] = field(default_factory=list)        # its waist command (rad)
    microbo_q: list[np.ndarray] = field(default_factory=list)
    reports: list[tuple[str, dict]] = field(default_factory=list)


def build(cell: Workcell, log: Log, fail_at: int | None = None):
    """The two control functions, closures over the workcell (they share memory through it)."""
    puma, microbo = cell["puma"], cell["microbo"]
    conv_p, conv_m = Conversions.for_robot(puma.robot), Conversions.for_robot(microbo.robot)
    state = {"p0": None, "m0": None, "pk": 0, "mk": 0}
    to_planner = cell.channel("microbo", PLANNING, capacity=8, overflow="drop_oldest")

    def puma_control() -> None:
        q = conv_p.counts_to_angles(np.asarray(puma.how.pos, dtype=float))
        if state["p0"] is None:
            state["p0"] = q.copy()
            puma.chg.power_on.com = 1
        k = state["pk"]
        state["pk"] = k + 1
        t = k / puma.rate_hz
        cell.shared["puma_q"] = q                         # t1: overwritten every sample
        log.puma_t.append(t)
        log.puma_q.append(q)
        goal = state["p0"].copy()
        goal[0] += AMPLITUDE * math.sin(2.0 * math.pi * t / SWING_PERIOD)
        counts = conv_p.angles_to_counts_int(goal)
        puma.chg.motion[0].issue(POS, int(counts[0]))

    def microbo_control() -> None:
        q = conv_m.counts_to_angles(np.asarray(microbo.how.pos, dtype=float))
        if state["m0"] is None:
            state["m0"] = q.copy()
            microbo.chg.power_on.com = 1
        k = state["mk"]
        state["mk"] = k + 1
        if fail_at is not None and k == fail_at:
            raise RuntimeError(f"microbo's control function gave up at its sample {k} (--fail-at)")
        seen = cell.shared.get("puma_q")                  # the PUMA's latest published angles
        log.microbo_seen.append(seen)
        log.microbo_q.append(q)
        if seen is None or state["p0"] is None:
            log.microbo_cmd.append(float(state["m0"][0]))
            return
        cmd = float(state["m0"][0] - (seen[0] - state["p0"][0]))      # the mirror of the PUMA's swing
        log.microbo_cmd.append(cmd)
        goal = q.copy()
        goal[0] = cmd
        microbo.chg.motion[0].issue(POS, int(conv_m.angles_to_counts_int(goal)[0]))
        if k % REPORT_EVERY == 0:
            to_planner.send({"sample": k, "puma_waist": float(seen[0]), "microbo_waist": float(q[0])})

    return puma_control, microbo_control


def main(url_puma: str, url_microbo: str, seconds: float = 2.0, *, sync: str = "lockstep",
         rates: tuple[int, int] = (36, 36), fail_at: int | None = None, on_error="raise",
         quiet: bool = True, **session_options) -> tuple[Workcell, Log]:
    """Run the program for ``seconds`` of robot time; return the (closed) workcell and its log.

    ``session_options`` go to each arm's ``rci.Session`` (e.g. ``lockstep_timeout=``).
    """
    log = Log()
    arms = {"puma": (url_puma, "puma260"), "microbo": (url_microbo, "microbo")}
    with Workcell(arms, sync=sync, rates={"puma": rates[0], "microbo": rates[1]}, on_error=on_error,
                  **session_options) as cell:
        f_puma, f_microbo = build(cell, log, fail_at)
        cell.control(puma=f_puma, microbo=f_microbo)                     # RCIcontrol for each arm
        n_cycles = int(round(seconds * cell["microbo"].rate_hz))
        while len(log.microbo_q) < n_cycles:
            cell.wait(0.05, until=lambda: len(log.microbo_q) >= n_cycles)
            while (r := cell.receive()) is not None:                   # receive(0, ...): any sender
                log.reports.append(r)
                if not quiet:
                    sender, msg = r
                    print(f"{sender}: sample {msg['sample']:4d}  PUMA waist {math.degrees(msg['puma_waist']):7.2f} deg"
                          f"  Microbo waist {math.degrees(msg['microbo_waist']):7.2f} deg")
        cell.release()                                                   # RCIrelease for every arm
        while (r := cell.receive()) is not None:
            log.reports.append(r)
    return cell, log


def _cli(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("urls", nargs="*", help="PUMA link URL, Microbo link URL")
    ap.add_argument("--simula", action="store_true",
                    help="start two simulas (-p) for the run: lockstep, or real time with --sync free")
    ap.add_argument("--seconds", type=float, default=4.0)
    ap.add_argument("--sync", choices=("lockstep", "free"), default="lockstep")
    ap.add_argument("--rates", type=int, nargs=2, default=(36, 36), metavar=("PUMA_HZ", "MICROBO_HZ"))
    ap.add_argument("--fail-at", type=int, default=None)
    a = ap.parse_args(argv)
    with ExitStack() as stack:
        if a.simula:
            from rci.simula.process import SimulaProcess
            # free sync lets each arm run on its own robot's clock: real-time simulas then, since two
            # lockstep simulas left free would each run as fast as it is answered, unrelated in time
            urls = [stack.enter_context(SimulaProcess("-p", robot=r, lockstep=a.sync == "lockstep")).url
                    for r in ("puma260", "microbo")]
        elif len(a.urls) == 2:
            urls = a.urls
        else:
            ap.error("give two link URLs (PUMA, Microbo) or --simula")
        cell, log = main(urls[0], urls[1], a.seconds, sync=a.sync, rates=tuple(a.rates), fail_at=a.fail_at,
                         on_error=None, quiet=False)
    print(f"PUMA {len(log.puma_q)} cycles, Microbo {len(log.microbo_q)} cycles, {len(log.reports)} reports")
    return 0


if __name__ == "__main__":
    sys.exit(_cli())
