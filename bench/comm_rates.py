"""Thesis Table 2.1 for this implementation: the traffic between the planning level and the
control level of RCCL and RCI programs, in messages and bytes per second of robot time.

    python -m bench.comm_rates                      # -> reports/comm-rates.md (a few minutes)
    python -m bench.comm_rates --program guarded --out -

The thesis measured programs whose levels shared memory, and gave "the data rates ...
required if the information were instead transferred over a channel" (Table 2.1's footnote).
So here: each program of ``PROGRAMS`` (the examples and calib program that match Table 2.1's
rows) runs against its own lockstep simula, and this process counts what crosses between
its levels, each message sized as JSON (``rci.bus.encode``), as the Zenoh bus would carry it:

- RCCL programs (conveyor, pick and place, guarded, edge, 5.3.4). c1, planning -> control:
  every motion request put on the motion queue (``rccl.queue.MotionQueue.put``, counted by
  wrapping it in this process only), sized as the request on the bus
  (``rccl.bus.wire.position_to_wire``: joint angles or the T6, plus the motion parameters);
  c3, control -> planning: one completion flag per request (the event flag the trajectory
  level sets when the request ends: its serial, status and time).
- The teach program (``examples/teach.py``, an RCI program, driven by a scripted operator):
  c1, every joint goal the planning level writes into the control function's variable
  (a joint vector); c3, the arrival it then waits for (one flag). Its rate is the scripted
  operator's: keys given at once, each jog waited for; a person typing sends fewer.
- The gravity loading measurement (``rcci.calib.program.run_plan`` with calib's first PUMA 260
  Table 4.7 sweep, its 100 s warm-up included): c1, the plan, handed to the control function
  once (its path segments, warm-up, notes); c3, the end of the run the planning level waits
  for. Every cycle's record goes from the control function to the log file, not to the
  planning level, and is not counted.

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
import tempfile
import threading
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bench.output import emit
from rccl.bus.wire import position_to_wire
from rccl.queue import MotionQueue
from rci.bus import encode

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "examples"

TEACH_KEYS = "2++++r3---r5++r1--rq"    # a scripted operator: 11 jogs, 4 poses recorded
# (key, Table 2.1's row it stands for, how it is measured, what it does)
PROGRAMS = (
    ("conveyor", "RCCL conveyor tracking program", "adaptive_conveyor", "tracks a moving conveyor (5.5)"),
    ("pickplace", "RCCL pick and place program", "pick_and_place", "takes 3 parts from a feeder to 3 places"),
    ("guarded", "RCCL guarded motion program", "adaptive_guarded_move", "moves down until a force limit (5.4.1)"),
    ("edge", "RCCL compliant edge detection program", "adaptive_edge_follow", "follows a tray's edge under compliance (5.4.3)"),
    ("gravity", "Gravity loading measurement program", "gravity", "calib's first Table 4.7 sweep, warm-up included (4.5.6)"),
    ("teach", "Manual teach mode program", "teach", f"examples/teach.py driven by the keys {TEACH_KEYS!r}"),
    ("move534", "none (thesis 5.3.4, not in Table 2.1)", "rccl_program_534", "to p0 and back to park"),
)
THESIS_2_1 = {  # Table 2.1 as printed: (Kbytes/s, messages/s); the rates lost their decimal point in the
    # OCR (".52" read "52": the text says "on the order of 1 Kbyte/second")
    "RCCL conveyor tracking program": (0.52, 1.9), "RCCL pick and place program": (0.40, 2.1),
    "RCCL guarded motion program": (0.23, 1.2), "RCCL compliant edge detection program": (0.26, 1.0),
    "Gravity loading measurement program": (0.14, 1.2), "Manual teach mode program": (0.03, 1.3)}


@dataclass
class Traffic:
    """What crossed between the levels during one program: the size (bytes, as JSON on the bus)
    of every c1 message (planning -> control) and every c3 flag (control -> planning)."""

    c1: list[int]
    c3: list[int]
    seconds: float                                     # robot time (control cycles / rate)
    requests: list = field(default_factory=list)       # RCCL programs: the queued requests

    @property
    def messages(self) -> int:
        return len(self.c1) + len(self.c3)

    @property
    def bytes(self) -> int:
        return sum(self.c1) + sum(self.c3)


def jsonable(value):
    """``value`` with arrays, tuples and dataclasses turned into JSON types (to size it as JSON)."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: jsonable(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, np.ndarray):
        return [jsonable(x) for x in value.tolist()]
    if isinstance(value, (list, tuple)):
        return [jsonable(x) for x in value]
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, np.generic):
        return value.item()
    return value


def request_wire_bytes(request) -> int:
    """The JSON size of ``request`` as it would cross the bus: its position and motion parameters."""
    params = request.params
    fields = dataclasses.asdict(params) if dataclasses.is_dataclass(params) else dict(vars(params))
    fields = {k: v for k, v in fields.items() if isinstance(v, (int, float, str, bool, type(None)))}
    return len(encode({"op": "move", "position": position_to_wire(request.position), "params": fields}))


def load_example(module: str):
    """Import ``examples/<module>.py`` as a module (the examples are scripts, not a package)."""
    if str(EXAMPLES) not in sys.path:
        sys.path.insert(0, str(EXAMPLES))
    spec = importlib.util.spec_from_file_location(f"comm_{module}", EXAMPLES / f"{module}.py")
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    return example


def measure(module: str) -> Traffic:
    """Run RCCL example ``module``'s ``main`` on its own simula with the queue counted; the traffic."""
    example = load_example(module)
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
    flags = [len(encode({"serial": r.serial, "status": r.status, "t": r.finished_t})) for r in seen]
    return Traffic(sizes, flags, session.how.cycle / session.rate_hz, seen)


def measure_teach(keys: str = TEACH_KEYS, rate_hz: int = 36) -> Traffic:
    """examples/teach.py's loop on a lockstep simula, driven by ``keys``. c1: every joint goal
    the planning level writes into the servo (the control function's variable), one joint
    vector; c3: the arrival the planning level waits for after each jog, one flag. Selecting
    a joint, the jog step and recording a pose stay at the planning level (a pose is read
    from the sampled state: c2, not counted)."""
    teach = load_example("teach")
    from rci.session import Session
    from rci.simula.process import SimulaProcess
    c1: list[int] = []
    c3: list[int] = []
    planning = threading.current_thread()

    class CountedServo(teach.Servo):
        def __setattr__(self, name, value) -> None:
            if name == "goal" and value is not None and threading.current_thread() is planning:
                c1.append(len(encode({"op": "goal", "q": jsonable(value)})))
                self._flagged = False
            object.__setattr__(self, name, value)

        def arrived(self, tol: float = 3e-4) -> bool:
            done = super().arrived(tol)
            if done and not getattr(self, "_flagged", True):
                c3.append(len(encode({"flag": "arrived", "t": self.s.how.cycle / self.s.rate_hz})))
                self._flagged = True
            return done

    servo_class, teach.Servo = teach.Servo, CountedServo
    try:
        with SimulaProcess("-p", lockstep=True) as sim, Session(sim.url, "puma260", rate_hz=rate_hz) as s:
            poses = teach.teach(s, iter(keys), echo=lambda _m: None)
            seconds = s.how.cycle / s.rate_hz
    finally:
        teach.Servo = servo_class
    if len(poses) != keys.count("r"):
        raise RuntimeError(f"teach recorded {len(poses)} poses for {keys.count('r')} 'r' keys")
    return Traffic(c1, c3, seconds)


def gravity_plan(warmup: bool = True, segments: int | None = None):
    """calib's first gravity plan for the PUMA 260 (a Table 4.7 sweep), with or without its warm-up;
    ``segments``: only the sweep's first so many segments (a shorter run, for tests)."""
    from rcci.calib.experiments import gravity_plans
    from rcci.calib.robot import robot_info
    info = robot_info("puma260")
    plan = gravity_plans(info.regressor, info.lower, info.upper)[0]
    if segments is not None:
        plan = dataclasses.replace(plan, path=dataclasses.replace(plan.path, segments=plan.path.segments[:segments]))
    return plan if warmup else dataclasses.replace(plan, warmup=None)


def measure_gravity(warmup: bool = True, segments: int | None = None) -> Traffic:
    """rcci.calib.program.run_plan (the measurement program) for one gravity sweep on a lockstep simula.
    c1: the plan, handed to the control function once (its path segments, warm-up and notes);
    c3: the end of the run the planning level waits for (one flag, with the records and cycles
    counts). The control function itself writes every cycle's record to the log file: data
    that does not cross to the planning level, so not counted."""
    from rcci.calib.program import run_plan
    from rci.simula.process import SimulaProcess
    plan = gravity_plan(warmup, segments)
    c1 = [len(encode({"op": "plan", "name": plan.name, "path": jsonable(plan.path), "warmup": jsonable(plan.warmup),
                      "via": jsonable(plan.via), "meta": jsonable(plan.meta)}))]
    with tempfile.TemporaryDirectory() as tmp, SimulaProcess("-p", "--warm", lockstep=True, seed=7) as sim:
        run = run_plan(sim.url, plan, os.path.join(tmp, "gravity.rcilog"), rate_hz=plan.rate_hz)
    c3 = [len(encode({"flag": "done", "records": run.records, "cycles": run.cycles}))]
    return Traffic(c1, c3, run.cycles / plan.rate_hz)


def measure_program(how: str) -> Traffic:
    """The traffic of the program ``how`` names in PROGRAMS."""
    if how == "teach":
        return measure_teach()
    if how == "gravity":
        return measure_gravity()
    return measure(how)


def render(rows: list[tuple[str, str, str, Traffic]], command: str, load: tuple[float, float]) -> str:
    lines = ["# Table 2.1 for this implementation: planning <-> control traffic", "",
             f"Generated by `{command}` (load average {load[0]:.1f} before, {load[1]:.1f} after; lockstep "
             "simula, so the rates are per second of robot time and do not depend on the load).", "",
             __doc__.split("\n\n", 2)[2].strip(), "",
             "| program | Table 2.1 row | robot time (s) | c1 messages | c1 bytes | c3 flags | c3 bytes "
             "| messages/s | Kbytes/s | thesis messages/s | thesis Kbytes/s |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for key, row, what, t in rows:
        th = THESIS_2_1.get(row)
        ths = f"{th[1]:.1f} | {th[0]:.2f}" if th else "- | -"
        lines.append(f"| {key}: {what} | {row} | {t.seconds:.1f} | {len(t.c1)} | {sum(t.c1)} | {len(t.c3)} | "
                     f"{sum(t.c3)} | {t.messages / t.seconds:.2f} | {t.bytes / t.seconds / 1e3:.3f} | {ths} |")
    lines += ["", "Table 2.1's rates read \"52\", \"40\", ..., \"03\" Kbytes/s in the OCR text; the leading zero "
              "of \"03\", the text's \"on the order of 1 Kbyte/second\" and the message rates (1-2 a second) make "
              "them 0.52, 0.40, ...: the columns above print them so.", ""]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--program", action="append", choices=[p[0] for p in PROGRAMS],
                    help="only these programs (repeatable; default all)")
    ap.add_argument("--out", default=str(ROOT / "reports" / "comm-rates.md"), help="report file ('-': print only)")
    args = ap.parse_args(argv)
    load0 = os.getloadavg()[0]
    rows = [(key, row, what, measure_program(how)) for key, row, how, what in PROGRAMS
            if not args.program or key in args.program]
    command = "python -m bench.comm_rates" + ("" if argv is None and len(sys.argv) == 1 else
                                               " " + " ".join(sys.argv[1:] if argv is None else argv))
    emit(render(rows, command, (load0, os.getloadavg()[0])), args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
