"""Fault injection against a real simula: one fault class, injected into a running control, measured.

Each case starts ``simula -p --power-on --warm`` (real time or lockstep), the fault proxy
(``rci.simula.proxy``) between it and the controller, and a control program that moves
the arm in both joint modes at once: joint 1 in current mode (a velocity loop in f1
holding about 20 deg/s) and joint 2 in position mode (a POS ramp at 10 deg/s), the other
joints held with POS. Half a second in, the fault is injected: into the link by the proxy
(flip, truncate, drop, duplicate, delay, cut), into the control functions (exception,
overrun, hang, bad command), or by killing or stopping a process. Then it measures:

* detection: when the controller (or, for faults only the robot can see, simula) ended
  the control, after the injection, in ms and in periods;
* the termination code and whether it is severe;
* the arm's motion after the error, measured by simula: the joint angles at the moment
  the error was detected against the angles at rest afterwards. Real time: simula's own
  record of when each HOW was sent and when the control ended (one clock for both
  processes), interpolated at the detection instant. Lockstep: the angles of the HOW the
  controller was answering when it ended the control (simulated time does not follow the
  wall clock). Also the joint 1 motion since the injection, and one period's travel of
  the moving joints just before the fault (the bound of docs/safety.md);
* power after the fault, and whether anything hung (the control thread, the session's
  close, simula's answers, a lockstep simula left "running").

``python -m bench.faults`` runs every case in both modes and writes reports/faults.md; the
tests in tests/test_faults*.py run the cases one by one. ``python -m rci.simula.faults
--controller URL`` is the control program alone (the kill/stop cases run it as a process).
"""
from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field

import numpy as np

from .. import codes
from ..chg import CUR, POS
from ..conversions import Conversions
from ..exceptions import ControlTerminated, RobotBusy
from ..session import Session
from .process import SimulaProcess
from .proxy import ProxyProcess

RATE_HZ = 100
J1_SPEED = np.radians(20.0)       # current-mode joint, rad/s
J2_SPEED = np.radians(10.0)       # position-mode joint, rad/s
SETTLE_S = 0.3                    # wall time the arm is left alone before its rest position is read
RUN_BEFORE_S = 0.5                # control time before the fault (lockstep: simulated seconds)
SURVIVE_S = 0.5                   # how long a control must keep going to count as having survived


@dataclass(frozen=True)
class Case:
    """One fault class: what is done, and by whom it should be caught."""

    name: str
    what: str                     # how it is injected, for the report
    proxy: str = ""               # a proxy fault spec, or ""
    user: str = ""                # "raise-f2", "overrun", "hang", "badcmd"
    process: str = ""             # "kill-controller", "stop-controller", "kill-simula", "stop-simula"
    busy: bool = False            # a second controller tries to connect
    lockstep_proxy: str = ""      # a different proxy spec in lockstep, if the real-time one means nothing there


CASES: tuple[Case, ...] = (
    Case("HOW corrupted", "one bit flipped in a HOW (robot -> controller)", proxy="down flip type=HOW"),
    Case("CHG corrupted", "one bit flipped in a CHG (controller -> robot)", proxy="up flip type=CHG"),
    Case("HOW truncated", "a HOW cut to half its bytes", proxy="down truncate type=HOW"),
    Case("CHG truncated", "a CHG cut to half its bytes", proxy="up truncate type=CHG"),
    Case("HOW lost", "one HOW dropped", proxy="down drop type=HOW"),
    Case("CHG lost", "one CHG dropped", proxy="up drop type=CHG"),
    Case("CHG link dead", "every CHG from now on dropped (the release too)", proxy="up drop type=CHG count=forever"),
    Case("HOW duplicated", "one HOW sent twice", proxy="down dup type=HOW"),
    Case("CHG duplicated", "one CHG sent twice", proxy="up dup type=CHG"),
    Case("HOW delayed", "one HOW (and what follows it) held 0.1 s (lockstep 0.5 s)", proxy="down delay type=HOW delay=0.1",
         lockstep_proxy="down delay type=HOW delay=0.5"),
    Case("HOW late", "one HOW held half a period", proxy="down delay type=HOW delay=0.005"),
    Case("CHG late, always", "every CHG held 1.5 periods", proxy="up delay type=CHG delay=0.015 count=forever"),
    Case("link cut", "both connections closed by the proxy", proxy="up cut type=CHG"),
    Case("exception in f2", "f2 raises after the cycle's CHG went out", user="raise-f2"),
    Case("overrun", "f1 takes 1.5 periods, every cycle", user="overrun"),
    Case("hung function", "f1 never returns", user="hang"),
    Case("bad command", 'f1 sets chg.motion[0].value = "12" (text)', user="badcmd"),
    Case("second controller", "another program opens a session while the control runs", busy=True),
    Case("controller killed", "SIGKILL to the controller process", process="kill-controller"),
    Case("controller stopped", "SIGSTOP to the controller process", process="stop-controller"),
    Case("simula stopped", "SIGSTOP to simula for 0.3 s", process="stop-simula"),
    Case("simula killed", "SIGKILL to simula", process="kill-simula"),
)


def case(name: str) -> Case:
    for c in CASES:
        if c.name == name:
            return c
    raise KeyError(f"no fault case {name!r}: {', '.join(c.name for c in CASES)}")


@dataclass
class Result:
    """What one case measured (angles in degrees, times in ms)."""

    case: str
    mode: str
    rate_hz: int
    outcome: str = ""              # "ended" or "survived"
    code: int = 0
    code_name: str = ""
    severe: bool = False
    detail: str = ""
    detected_by: str = ""          # "controller", "simula", ""
    detect_ms: float = float("nan")
    detect_cycles: float = float("nan")
    motion_cur_deg: float = float("nan")      # joint 1 (current mode) after the error
    motion_pos_deg: float = float("nan")      # joint 2 (position mode) after the error
    motion_cur_since_fault_deg: float = float("nan")
    motion_after_reaction_deg: float = float("nan")   # max over joints after the robot applied the end
    period_travel_deg: float = float("nan")   # max over joints 1, 2 of one period's travel before the fault
    power_after: str = ""
    hung: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    invalid: str = ""              # the run did not test the fault (e.g. the control ended before it)

    @property
    def ok(self) -> bool:
        """The acceptance rule of docs/safety.md: nothing hung, and after an error each moving
        joint moved at most one period's travel, and not at all once the robot had applied the
        end of the control (current-mode joint included: it is held, not left with its current)."""
        if self.hung:
            return False
        if self.outcome != "ended" or np.isnan(self.motion_cur_deg):
            return True
        bound = self.period_travel_deg + 1e-9
        return (self.motion_cur_deg <= bound and self.motion_pos_deg <= bound
                and self.motion_after_reaction_deg <= 1e-4)


# --- the control program --------------------------------------------------------------------
class FaultProgram:
    """The control functions every case runs, with switches for the user faults."""

    def __init__(self, s: Session, rate_hz: int) -> None:
        self.s = s
        self.conv = Conversions.for_robot(s.robot)
        self.rate = rate_hz
        self.hold: np.ndarray | None = None
        self.q_prev: np.ndarray | None = None
        self.j2 = 0.0
        self.fault = ""                 # the user fault to start doing
        self.fault_time = 0.0           # monotonic time the user fault began
        self.fault_cycle: int | None = None
        self.release_hang = threading.Event()

    def _begin(self) -> None:
        if not self.fault_time:
            self.fault_time = time.monotonic()
            self.fault_cycle = self.s.how.cycle

    def f1(self) -> None:
        s = self.s
        q = self.conv.counts_to_angles(s.how.pos)
        if self.hold is None:
            self.hold = s.how.pos.copy()
            self.q_prev = q
            self.j2 = float(q[1])
            s.chg.power_on.com = 1
        v = (q[0] - self.q_prev[0]) * self.rate
        self.q_prev = q
        dac = -70.0 - 1000.0 * (J1_SPEED - v)           # joint 1: positive current turns it negatively
        s.chg.motion[0].issue(CUR, int(np.clip(dac, -2000, 2000)))
        self.j2 += J2_SPEED / self.rate
        target = q.copy()
        target[1] = self.j2
        counts = self.conv.angles_to_counts_int(target)
        s.chg.motion[1].issue(POS, int(counts[1]))
        for j in range(2, len(counts)):
            s.chg.motion[j].issue(POS, int(self.hold[j]))
        if self.fault == "overrun":
            self._begin()
            time.sleep(1.5 / self.rate)
        elif self.fault == "hang":
            self._begin()
            self.release_hang.wait(10.0)
            self.fault = ""
        elif self.fault == "badcmd":
            self._begin()
            s.chg.motion[0].value = "12"

    def f2(self) -> None:
        if self.fault == "raise-f2":
            self._begin()
            self.fault = ""
            raise RuntimeError("injected fault in f2")


def controller_main(url: str, rate_hz: int) -> int:
    """The control program as a process of its own: prints ``running`` once it controls, then waits."""
    s = Session(url, "puma260", rate_hz=rate_hz, on_error="raise", signals=False, lock_memory=False)
    with s:
        prog = FaultProgram(s, rate_hz)
        s.control(prog.f1, prog.f2)
        print("running", flush=True)
        try:
            s.wait(60.0)
        except ControlTerminated as e:
            print(f"terminated {e.termination.code}", flush=True)
            return 1
    return 0


# --- measuring ------------------------------------------------------------------------------
def _interp(points: list[tuple[float, np.ndarray]], t: float) -> np.ndarray:
    """Joint angles at wall time t from simula's (time, q) record (piecewise linear, clamped)."""
    points = sorted(points, key=lambda p: p[0])
    if t <= points[0][0]:
        return points[0][1]
    for (t0, q0), (t1, q1) in zip(points, points[1:]):
        if t0 <= t <= t1:
            return q0 if t1 == t0 else q0 + (q1 - q0) * (t - t0) / (t1 - t0)
    return points[-1][1]


def _travel(ticks: list, before: float | None, before_seq: int | None) -> float:
    """One period's travel (deg, max over joints 1 and 2) from the last two HOWs before the fault."""
    rows = [r for r in ticks if r[1] is not None and (before is None or r[1] <= before)
            and (before_seq is None or ((before_seq - r[0]) & 0xFFFFFFFF) < 0x80000000)]
    if len(rows) < 2:
        return float("nan")
    a, b = np.asarray(rows[-2][2]), np.asarray(rows[-1][2])
    return float(np.degrees(np.max(np.abs(b[:2] - a[:2]))))


class _Run:
    """One case in one mode: the processes, the controller, the measurements."""

    def __init__(self, c: Case, lockstep: bool, rate_hz: int) -> None:
        self.c = c
        self.lockstep = lockstep
        self.rate = rate_hz
        self.res = Result(c.name, "lockstep" if lockstep else "real time", rate_hz)
        self.t_inject = 0.0
        self.t_detect = 0.0
        self.term: codes.Termination | None = None
        self.inject_seq: int | None = None
        self.injected = False

    # the pieces ---------------------------------------------------------------------------
    def run(self) -> Result:
        with SimulaProcess("-p", "--power-on", "--warm", lockstep=self.lockstep) as sim:
            self.sim = sim
            with ProxyProcess(sim.url) as proxy:
                self.proxy = proxy
                if self.c.process in ("kill-controller", "stop-controller"):
                    self._external_controller()
                else:
                    self._inprocess_controller()
                if self.c.proxy:
                    applied = proxy.applied()
                    if applied:
                        self.t_inject, self.inject_seq = applied[0]["wall"], applied[0]["seq"]
                    else:
                        self.res.invalid = self.res.invalid or "the proxy applied no fault"
                if sim.alive():
                    self._measure_arm()
                else:
                    self.res.notes.append("simula is gone, and the simulated arm with it: nothing left to measure "
                                          "(a real arm's controller stops on its own watchdog)")
                self._detection()
        self.res.notes.extend(self._notes())
        return self.res

    def _session(self) -> Session:
        # lockstep: a simulated second is far less wall time, so the run is counted in cycles
        return Session(self.proxy.url, "puma260", rate_hz=self.rate, on_error="raise", signals=False,
                       lock_memory=False)

    def _wait_cycles(self, s: Session, seconds: float) -> None:
        c0 = s.how.cycle
        s.wait(seconds=max(seconds, 0.0) * (1 if not self.lockstep else 20),
               until=lambda: (s.how.cycle - c0) >= int(seconds * self.rate))

    def _inprocess_controller(self) -> None:
        s = self._session()
        res = self.res
        ended = threading.Event()

        def on_end(t: codes.Termination) -> None:
            self.t_detect = time.monotonic()
            self.term = t
            ended.set()

        s.termination_listeners.append(on_end)
        prog = FaultProgram(s, self.rate)
        try:
            s.open()
            s.control(prog.f1, prog.f2)
            self._wait_cycles(s, RUN_BEFORE_S)
            self.inject_seq = s.how.cycle
            self._inject(s, prog)
            try:
                if self.c.busy:
                    self._second_controller()
                # lockstep: SURVIVE_S of simulated time (far less wall clock; more would drive the
                # joints into their limits), but up to 3 s of wall clock for a hung function,
                # which the controller catches after 2 s there (docs/rci.md)
                c_inj = s.how.cycle
                s.wait(seconds=SURVIVE_S if not self.lockstep else 3.0,
                       until=lambda: ended.is_set() or (self.lockstep and s.how.cycle - c_inj >= SURVIVE_S * self.rate))
            except ControlTerminated:
                pass
            if not ended.is_set() and self.c.process == "stop-simula":
                ended.wait(1.0)
        except ControlTerminated:
            pass
        finally:
            if self.c.process == "stop-simula" and self.sim.alive():
                os.kill(self.sim.proc.pid, signal.SIGCONT)
            prog.release_hang.set()
            task = s.control_task
            if ended.is_set():
                res.outcome = "ended"
                if task is not None and not task.finished.wait(3.0):
                    res.hung.append("control thread still in a user function 3 s after the end")
            else:
                res.outcome = "survived"
                if not s.in_control:
                    res.hung.append("control not running and no termination")
            t0 = time.monotonic()
            try:
                if s.in_control:
                    s.release()
                s.close()
            except Exception as e:  # noqa: BLE001 - the report says what went wrong
                res.notes.append(f"close: {type(e).__name__}: {e}")
            if time.monotonic() - t0 > 3.0:
                res.hung.append(f"session close took {time.monotonic() - t0:.1f} s")
            summary = s.timing.summary()
            if res.outcome == "survived":
                res.notes.append(f"late cycles {summary.late_cycles}, longest run {summary.late_run_max} "
                                 f"(limit {summary.late_limit or 'none'}), duplicate HOWs {summary.duplicates}")
        if self.term is not None and (not self.injected or (self.t_inject and self.t_detect < self.t_inject)):
            res.invalid = f"the control ended before the fault was injected: {self.term}"
        if self.term is not None:
            res.detected_by = "controller"
            res.code, res.code_name, res.severe = self.term.code, self.term.name, self.term.severe
            res.detail = self.term.detail
        if prog.fault_time:
            self.t_inject = prog.fault_time
            self.inject_seq = prog.fault_cycle
        elif self.c.user and self.term is not None:
            res.invalid = f"the control ended before the fault was injected: {self.term}"

    def _external_controller(self) -> None:
        res = self.res
        proc = subprocess.Popen([sys.executable, "-m", "rci.simula.faults", "--controller", self.proxy.url,
                                 "--rate", str(self.rate)], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                                text=True)
        try:
            line = proc.stdout.readline()
            if line.strip() != "running":
                res.hung.append(f"controller process did not start: {line!r}")
                return
            time.sleep(RUN_BEFORE_S if not self.lockstep else 0.2)
            state = self.sim.command("state")
            self.inject_seq = state["cycle"]
            if not state["running"]:
                res.invalid = "the control ended before the fault was injected"
                return
            # the fault's time is the signal's, not the state query's before it (a loaded
            # machine can take tens of ms to answer it, and the arm moves on meanwhile)
            self.t_inject = time.monotonic()
            os.kill(proc.pid, signal.SIGKILL if self.c.process == "kill-controller" else signal.SIGSTOP)
            ev = self._wait_event(5.0)
            if ev is None:
                res.outcome = "survived"
                res.hung.append("simula did not end the control within 5 s")
                return
            res.outcome = "ended"
            res.detected_by = "simula"
            self.t_detect = ev["wall"]
            res.code_name = ev["cause"]
        finally:
            if proc.poll() is None:
                proc.kill()
            proc.wait(5.0)

    def _second_controller(self) -> None:
        other = Session(self.proxy.url, "puma260", rate_hz=self.rate, on_error="raise", signals=False,
                        lock_memory=False, client="second")
        try:
            other.open()
            self.res.notes.append("second controller was let in")
            other.close()
        except RobotBusy as e:
            self.res.notes.append(f"second controller refused: {e.text[:90]}...")

    def _inject(self, s: Session, prog: FaultProgram) -> None:
        c = self.c
        self.t_inject = time.monotonic()
        if c.proxy:
            spec = c.lockstep_proxy if self.lockstep and c.lockstep_proxy else c.proxy
            self.proxy.fault(spec)
        elif c.user:
            prog.fault = c.user
            self.t_inject = 0.0             # set by the control function when it misbehaves
        elif c.process == "kill-simula":
            os.kill(self.sim.proc.pid, signal.SIGKILL)
            self.sim.proc.wait(5.0)
        elif c.process == "stop-simula":
            os.kill(self.sim.proc.pid, signal.SIGSTOP)
            threading.Timer(0.3, lambda: os.kill(self.sim.proc.pid, signal.SIGCONT)).start()
        self.injected = True

    def _wait_event(self, within: float) -> dict | None:
        t0 = time.monotonic()
        while time.monotonic() - t0 < within:
            ev = self.sim.command("events")["events"]
            mine = [e for e in ev if e["wall"] >= self.t_inject - 1e-3]
            if mine:
                return mine[0]
            time.sleep(0.01)
        return None

    def _detection(self) -> None:
        res = self.res
        if res.outcome == "ended" and self.t_detect and self.t_inject:
            res.detect_ms = (self.t_detect - self.t_inject) * 1e3
            res.detect_cycles = res.detect_ms / 1e3 * self.rate

    def _measure_arm(self) -> None:
        res = self.res
        time.sleep(SETTLE_S)
        try:
            info = self.sim.command("events", timeout=2.0)
            state = self.sim.command("state", timeout=2.0)
        except Exception as e:  # noqa: BLE001
            res.hung.append(f"simula does not answer: {e}")
            return
        if state["running"] and res.outcome == "ended":
            res.hung.append("simula still running the ended control")
        res.power_after = "on" if state["state"]["power"] else "off"
        ticks = info["ticks"]
        events = [e for e in info["events"] if self.t_inject and e["wall"] >= self.t_inject - 1e-3]
        res.period_travel_deg = (_travel(ticks, None, self.inject_seq) if self.lockstep
                                 else _travel(ticks, self.t_inject or None, None))
        if res.outcome != "ended":
            return
        q_rest = np.asarray(state["state"]["q"])
        ev = events[0] if events else None
        if ev is not None and res.detected_by == "controller" and ev["wall"] < self.t_detect:
            # the robot ended the control before the controller heard of it: its reaction is the detection
            res.detected_by = "simula, then controller"
            self.t_detect = ev["wall"]
        if ev is not None:
            res.motion_after_reaction_deg = float(np.degrees(np.max(np.abs(q_rest - np.asarray(ev["q"])))))
        q_err = self._q_at_error(ticks, ev)
        if q_err is not None:
            res.motion_cur_deg = float(np.degrees(abs(q_rest[0] - q_err[0])))
            res.motion_pos_deg = float(np.degrees(abs(q_rest[1] - q_err[1])))
        q_inj = self._q_at(ticks, ev, self.t_inject, self.inject_seq)
        if q_inj is not None:
            res.motion_cur_since_fault_deg = float(np.degrees(abs(q_rest[0] - q_inj[0])))

    def _q_at_error(self, ticks: list, ev: dict | None) -> np.ndarray | None:
        seq = self.term.cycle if self.term is not None and self.term.cycle >= 0 else None
        if self.res.detected_by.startswith("simula") and ev is not None:
            seq = ev["seq"] if self.lockstep else None
        return self._q_at(ticks, ev, self.t_detect, seq)

    def _q_at(self, ticks: list, ev: dict | None, t: float, seq: int | None) -> np.ndarray | None:
        if self.lockstep:
            if seq is not None:
                rows = [r for r in ticks if r[0] == seq]
                if rows:
                    return np.asarray(rows[-1][2])
            return np.asarray(ev["q"]) if ev is not None else None
        points = [(r[1], np.asarray(r[2])) for r in ticks if r[1] is not None]
        if ev is not None:
            points.append((ev["wall"], np.asarray(ev["q"])))
        return _interp(points, t) if points and t else None

    def _notes(self) -> list[str]:
        out = []
        if self.term is not None and self.term.detail:
            out.append(self.term.detail[:320])
        return out


def run_case(c: Case | str, *, lockstep: bool, rate_hz: int = RATE_HZ, attempts: int = 3) -> Result:
    """Run one fault case in one mode and return its measurements.

    A run in which the control ended before the fault was injected (a timing fault of the
    loaded machine, not the one under test) is repeated, up to ``attempts`` runs in all;
    the result says how many were needed.
    """
    c = case(c) if isinstance(c, str) else c
    for i in range(attempts):
        r = _Run(c, lockstep, rate_hz).run()
        if not r.invalid:
            if i:
                r.notes.append(f"run {i + 1} of {attempts}: the earlier ones ended before the fault")
            return r
    return r


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m rci.simula.faults", description=__doc__.splitlines()[0])
    ap.add_argument("--controller", metavar="URL", help="run the control program alone against URL")
    ap.add_argument("--rate", type=int, default=RATE_HZ)
    ap.add_argument("--case", action="append", help="run these cases (default: all) and print the results")
    ap.add_argument("--lockstep", action="store_true")
    a = ap.parse_args(argv)
    if a.controller:
        return controller_main(a.controller, a.rate)
    for name in a.case or [c.name for c in CASES]:
        r = run_case(name, lockstep=a.lockstep, rate_hz=a.rate)
        print(r)
    return 0


if __name__ == "__main__":
    sys.exit(main())
