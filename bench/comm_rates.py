"""Thesis Table 2.1 for this implementation: the traffic between the planning level and the
control level of RCCL programs, in messages and bytes per second of robot time.

    python -m bench.comm_rates                      # -> reports/comm-rates.md (a few minutes)
    python -m bench.comm_rates --program guarded --out -

The thesis measured RCCL programs whose levels shared memory, and gave "the data rates ...
required if the information were instead transferred over a channel" (Table 2.1's footnote).
So here: each program of ``PROGRAMS`` (the examples that match Table 2.1's rows) runs
against its own lockstep simula, and this process counts what crosses between its levels:

- c1, planning -> control: every motion request put on the motion queue
  (``rccl.queue.MotionQueue.put``, counted by wrapping it in this process only), sized as the
  JSON that carries the same request over the Zenoh bus when the levels are two processes
  (``rccl.bus.wire.position_to_wire``: joint angles or the T6, plus the motion parameters);
- c3, control -> planning: one completion flag per request (the event flag the trajectory
  level sets when the request ends), sized as the JSON of its serial, status and time.

c2 (the planning level sampling the arm's state, at its own discretion) is a read of shared
memory whose rate is the program's choice, not counted. Robot time is the control cycles run
divided by the sample rate.
"""
from __future__ import annotations

import argparse
import dataclasses
import importlib.util
import os
import sys
from dataclasses import dataclass
from pathlib import Path

from bench.output import emit
from rccl.bus.wire import position_to_wire
from rccl.queue import MotionQueue
from rci.bus import encode

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "examples"

# (key, Table 2.1's row it stands for, example module, what it does)
PROGRAMS = (
    ("conveyor", "RCCL conveyor tracking program", "adaptive_conveyor", "tracks a moving conveyor (5.5)"),
    ("guarded", "RCCL guarded motion program", "adaptive_guarded_move", "moves down until a force limit (5.4.1)"),
    ("edge", "RCCL compliant edge detection program", "adaptive_edge_follow", "follows a tray's edge under compliance (5.4.3)"),
    ("move534", "none (no example picks and places)", "rccl_program_534", "thesis 5.3.4: to p0 and back to park"),
)
THESIS_2_1 = {  # Table 2.1 as printed: (Kbytes/s, messages/s); the rates lost their decimal point in the
    # OCR (".52" read "52": the text says "on the order of 1 Kbyte/second")
    "RCCL conveyor tracking program": (0.52, 1.9), "RCCL pick and place program": (0.40, 2.1),
    "RCCL guarded motion program": (0.23, 1.2), "RCCL compliant edge detection program": (0.26, 1.0),
    "Gravity loading measurement program": (0.14, 1.2), "Manual teach mode program": (0.03, 1.3)}


@dataclass
class Traffic:
    """What crossed between the levels during one program."""

    requests: list          # the requests put on the queue, in order
    request_bytes: int      # c1, bytes as the bus would carry them
    seconds: float          # robot time (control cycles / rate)

    @property
    def flag_bytes(self) -> int:
        return sum(len(encode({"serial": r.serial, "status": r.status, "t": r.finished_t})) for r in self.requests)


def request_wire_bytes(request) -> int:
    """The JSON size of ``request`` as it would cross the bus: its position and motion parameters."""
    params = request.params
    fields = dataclasses.asdict(params) if dataclasses.is_dataclass(params) else dict(vars(params))
    fields = {k: v for k, v in fields.items() if isinstance(v, (int, float, str, bool, type(None)))}
    return len(encode({"op": "move", "position": position_to_wire(request.position), "params": fields}))


def measure(module: str) -> Traffic:
    """Run example ``module``'s ``main`` on its own simula with the queue counted; the traffic."""
    sys.path.insert(0, str(EXAMPLES))
    spec = importlib.util.spec_from_file_location(f"comm_{module}", EXAMPLES / f"{module}.py")
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    seen: list = []
    sizes: list[int] = []
    put = MotionQueue.put

    def counted_put(queue, item) -> None:
        seen.append(item)
        sizes.append(request_wire_bytes(item))
        put(queue, item)

    MotionQueue.put = counted_put
    try:
        if hasattr(example, "ENV"):
            from adaptive_sim import run_main
            result = run_main(example.main, None, *example.ENV)
        else:
            from rci.simula.process import SimulaProcess
            with SimulaProcess("-p", "--power-on", lockstep=True) as sim:
                result = example.main(sim.url)
    finally:
        MotionQueue.put = put
    arm = result[0] if isinstance(result, tuple) else result
    session = arm.rci
    return Traffic(seen, sum(sizes), session.how.cycle / session.rate_hz)


def render(rows: list[tuple[str, str, str, Traffic]], command: str, load: tuple[float, float]) -> str:
    lines = ["# Table 2.1 for this implementation: planning <-> control traffic of RCCL programs", "",
             f"Generated by `{command}` (load average {load[0]:.1f} before, {load[1]:.1f} after; lockstep "
             "simula, so the rates are per second of robot time and do not depend on the load).", "",
             __doc__.split("\n\n", 2)[2].strip(), "",
             "| program (example) | Table 2.1 row | robot time (s) | c1 requests | c1 bytes | c3 flags | c3 bytes "
             "| messages/s | Kbytes/s | thesis messages/s | thesis Kbytes/s |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for key, row, what, t in rows:
        msgs = 2 * len(t.requests)
        total = t.request_bytes + t.flag_bytes
        th = THESIS_2_1.get(row)
        ths = f"{th[1]:.1f} | {th[0]:.2f}" if th else "- | -"
        lines.append(f"| {key}: {what} | {row} | {t.seconds:.1f} | {len(t.requests)} | {t.request_bytes} | "
                     f"{len(t.requests)} | {t.flag_bytes} | {msgs / t.seconds:.2f} | {total / t.seconds / 1e3:.3f} | {ths} |")
    lines += ["", "Thesis rows not measured here: the pick and place program (no example does pick and place), "
              "the gravity loading measurement and the manual teach program (RCI programs: their levels "
              "share the control function's variables every cycle, there is no queue to count).",
              "Table 2.1's rates read \"52\", \"40\", ..., \"03\" Kbytes/s in the OCR text; the leading zero of \"03\", the text's \"on the order "
              "of 1 Kbyte/second\" and the message rates (1-2 a second) make them 0.52, 0.40, ...: "
              "the columns above print them so.", ""]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--program", action="append", choices=[p[0] for p in PROGRAMS],
                    help="only these programs (repeatable; default all)")
    ap.add_argument("--out", default=str(ROOT / "reports" / "comm-rates.md"), help="report file ('-': print only)")
    args = ap.parse_args(argv)
    load0 = os.getloadavg()[0]
    rows = [(key, row, what, measure(module)) for key, row, module, what in PROGRAMS
            if not args.program or key in args.program]
    command = "python -m bench.comm_rates" + ("" if argv is None and len(sys.argv) == 1 else
                                               " " + " ".join(sys.argv[1:] if argv is None else argv))
    emit(render(rows, command, (load0, os.getloadavg()[0])), args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
