"""An arm process: one RCCL arm served on the Zenoh bus, for a planning level in another process.

The other half of ``rccl.bus_events`` (key expressions and semantics there). The arm's
process opens its RCCL arm (its control task runs here, at the arm's rate), attaches it
to ``rccl.events`` under its name, and then:

* answers the planning level's requests on ``rcci/CELL/arm/ARM/request`` (move with an
  event flag triple, info, free, abort, close), one at a time, in this process's serving
  thread (``ArmServer.serve``);
* publishes every change of its EFTs' flags on ``rcci/CELL/flags/ARM/SERIAL`` (from a
  publishing thread: the control level only hands a copy over, it never waits for the
  network) and answers queries for the latest;
* applies ``start_ev`` / ``stop_ev`` publications (``rcci/CELL/flags/set``) to its EFTs;
* starts a motion queued with ``start=`` an EFT of another arm the moment it learns,
  from that arm's publication, that the motion ended (or at once if it already had);
* publishes ``rcci/CELL/arm/ARM/fault`` and ends when its arm's control ends with a fault.

Its liveliness token ``rcci/CELL/arm/ARM`` is declared once it serves and ends with the
process. Run it from the shell:

    python -m rccl.bus_arm --cell lab --bus tcp/10.0.0.1:7447 puma 'zenoh/lab/puma260?connect=...' puma260

It prints ``ARM: serving`` when ready and serves until the planning level sends ``close``,
its arm faults, or it gets SIGTERM/SIGINT (then it releases the arm).
"""
from __future__ import annotations

import argparse
import os
import queue
import select
import signal
import subprocess
import sys
import threading
import time
from typing import Any

from rci.bus import Bus, decode, encode
from rci.zenoh_bus import undeclare

from . import events as ev
from .bus_events import arm_key, check_name, error_reply, flags_key, flags_of, position_from_wire, set_key
from .events import ABORTED, FAULT, EventError

POLL_S = 0.05          # the serving thread looks at the arm's faults this often (s)
BUS_PRIORITY = 70      # SCHED_FIFO of the flags' way out and in (below the control thread's 80)


class ArmServer:
    """Serve ``arm`` (an open RCCL arm) as ``name`` on ``bus`` (its cell); ``serve()`` runs it.

    ``report_to``: a task (default the planning level) that gets, on the bus channel
    ``ARM -> report_to``, one message per motion that ends: ``{"serial", "where", "status",
    "q"}`` with the joint angles the robot reported then (rad); None for no reports.
    ``priority`` > 0: the thread that publishes the flags runs under SCHED_FIFO at it."""

    def __init__(self, arm, bus: Bus, name: str, report_to: str | None = "planning", priority: int = 0) -> None:
        import zenoh
        self.arm = arm
        self.bus = bus
        self.name = check_name(name, "ArmServer")
        self.cell = bus.cell
        self.priority = priority
        ev.attach(arm, name)
        self.efts: dict[int, ev.EFT] = {}
        self._lock = threading.Lock()
        self._latest: dict[int, bytes] = {}                 # own EFTs' flags as last published
        self._remote: dict[tuple[str, int], dict] = {}      # other arms' EFTs' flags, latest seen
        self._waiting: dict[tuple[str, int], list[tuple[ev.EFT, int]]] = {}
        self._out: queue.Queue = queue.Queue()
        self._requests: queue.Queue = queue.Queue()
        self._stop = threading.Event()
        self._block = zenoh.CongestionControl.BLOCK
        self.reports = bus.channel(name, report_to, capacity=16) if report_to else None
        s = bus.session
        self._publisher = threading.Thread(target=self._publish_loop, name=f"flags-{name}", daemon=True)
        self._publisher.start()
        ev.add_listener(self._changed)
        self._declared = [
            s.declare_subscriber(f"rcci/{self.cell}/flags/*/*", self._on_flags),
            s.declare_subscriber(set_key(self.cell), self._on_set),
            s.declare_queryable(flags_key(self.cell, name, "*"), self._on_flags_query),
            s.declare_queryable(arm_key(self.cell, name, "request"), self._requests.put),
        ]
        self._token = s.liveliness().declare_token(arm_key(self.cell, name))

    # -- the flags out ------------------------------------------------------------------------
    def _changed(self, eft: ev.EFT) -> None:
        """rccl.events listener (under its lock, maybe at the control level): hand a copy over."""
        if eft.arm == self.name:
            self._out.put(flags_of(eft, self.name))

    def _publish_loop(self) -> None:
        if self.priority > 0:          # the flags leave as soon as the control level hands them over
            try:
                os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(self.priority))
            except (OSError, AttributeError):
                pass
        while True:
            flags = self._out.get()
            if flags is None:
                return
            data = encode(flags)
            with self._lock:
                self._latest[flags["serial"]] = data
            try:
                self.bus.session.put(flags_key(self.cell, self.name, flags["serial"]), data,
                                     congestion_control=self._block, express=True)
            except Exception as exc:
                if self.bus.session.is_closed():
                    return             # the process is ending: nothing more to tell
                print(f"{self.name}: flags of EFT #{flags['serial']} not published: {exc}", file=sys.stderr)
            if self.reports is not None and flags["status"] < 0:
                try:
                    self.reports.send({"serial": flags["serial"], "where": flags["where"], "status": flags["status"],
                                       "q": self.arm.measured_q()})
                except Exception as exc:     # a report lost is no reason to stop publishing flags
                    print(f"{self.name}: report of EFT #{flags['serial']} not sent: {exc}", file=sys.stderr)

    def _on_flags_query(self, query) -> None:
        wanted = str(query.key_expr).rsplit("/", 1)[-1]       # a serial, or * for all
        with self._lock:
            latest = dict(self._latest)
        for serial, data in latest.items():
            if wanted in ("*", "**", str(serial)):
                query.reply(flags_key(self.cell, self.name, serial), data)

    # -- the flags in ---------------------------------------------------------------------------
    def _on_flags(self, sample) -> None:
        """Another arm's EFT changed: start the motions here that wait for its end."""
        try:
            f = decode(sample.payload.to_bytes())
            key = (str(f["arm"]), int(f["serial"]))
        except (ValueError, KeyError, TypeError):
            return
        if key[0] == self.name:
            return
        with self._lock:
            old = self._remote.get(key)
            if old is None or f.get("version", 0) >= old.get("version", 0):
                self._remote[key] = f
            ready = self._waiting.pop(key, []) if f.get("status", 0) < 0 else []
        self._fire(f, ready)

    def _fire(self, source: dict, followers: list[tuple[ev.EFT, int]]) -> None:
        if source.get("status") in (FAULT, ABORTED):      # as in one process: a failed motion starts nothing
            return
        for eft, code in followers:
            try:
                ev.start_ev(code, eft)
            except ev.UnknownEvent:
                pass                                       # freed meanwhile

    def _follow(self, key: tuple[str, int], eft: ev.EFT, code: int, told: dict | None) -> None:
        """``eft`` (queued held) starts when EFT ``key`` of another arm ends."""
        with self._lock:
            known = self._remote.get(key)
            if told is not None and (known is None or told.get("version", 0) > known.get("version", 0)):
                known = self._remote[key] = told
            if known is None or known.get("status", 0) >= 0:
                self._waiting.setdefault(key, []).append((eft, code))
                ready = []
            else:
                ready = [(eft, code)]
        if known is None:      # nothing heard of it yet: ask its arm's process for the latest
            for reply in self.bus.session.get(flags_key(self.cell, *key), timeout=1.0):
                if reply.ok is not None:
                    self._on_flags(reply.ok)
        elif ready:
            self._fire(known, ready)

    def _on_set(self, sample) -> None:
        """start_ev / stop_ev from the planning level: set the flags of this arm's EFTs named."""
        try:
            m = decode(sample.payload.to_bytes())
            flag, code = m["flag"], int(m["code"])
            mine = [self.efts[int(s)] for a, s in m["efts"] if a == self.name and int(s) in self.efts]
        except (ValueError, KeyError, TypeError):
            return
        try:
            (ev.start_ev if flag == "start" else ev.stop_ev)(code, *mine)
        except EventError:
            pass                   # freed meanwhile; the planning level checked the rest

    # -- requests -------------------------------------------------------------------------------
    def _answer(self, query) -> None:
        try:
            request = decode(query.payload.to_bytes()) if query.payload is not None else {}
            answer = self._do(request)
        except Exception as exc:   # every refusal goes back to the planning level, named
            answer = error_reply(exc)
        query.reply(query.key_expr, encode(answer))

    def _do(self, r: dict) -> dict:
        op = r.get("op")
        if op == "info":
            return {"robot": self.arm.robot, "rate_hz": self.arm.rate_hz, "q": self.arm.q}
        if op == "move":
            return self._move(r)
        if op == "free":
            ev.free_ev(*[self._eft(s) for s in r["serials"]])
            with self._lock:
                for s in r["serials"]:
                    self.efts.pop(int(s), None)
                    self._latest.pop(int(s), None)
            return {"freed": len(r["serials"])}
        if op == "abort":
            ev.stop_abort(self.arm)
            return {"flags": [flags_of(e, self.name) for e in self.efts.values()]}
        if op == "close":
            self._stop.set()
            return {"closing": True}
        raise EventError(f"arm {self.name!r}: unknown request {op!r} (info, move, free, abort, close)")

    def _eft(self, serial: Any) -> ev.EFT:
        try:
            return self.efts[int(serial)]
        except (KeyError, ValueError, TypeError):
            raise ev.UnknownEvent(f"arm {self.name!r} has no EFT #{serial}") from None

    def _move(self, r: dict) -> dict:
        position = position_from_wire(r.get("position"), self.arm.kinematics)
        start = r.get("start")
        if isinstance(start, dict):
            src_arm, src_serial = str(start["after"][0]), int(start["after"][1])
            code = int(start["code"])
            if src_arm == self.name:
                eft = ev.move_ev(self.arm, position, start=self._eft(src_serial), after_code=code)
            else:
                eft = ev.move_ev(self.arm, position, start=None)
                self.efts[eft.serial] = eft
                self._follow((src_arm, src_serial), eft, code, start.get("flags"))
        else:
            eft = ev.move_ev(self.arm, position, start=start)
        self.efts[eft.serial] = eft
        return {"serial": eft.serial, "flags": flags_of(eft, self.name)}

    # -- the serving loop -------------------------------------------------------------------------
    def serve(self) -> None:
        """Answer requests until ``close`` (or ``stop()``); raise the arm's fault after publishing it."""
        while not self._stop.is_set():
            try:
                query = self._requests.get(timeout=POLL_S)
            except queue.Empty:
                query = None
            if query is not None:
                self._answer(query)
                del query                                  # the query is finished when dropped
            try:
                self.arm.check()
            except Exception as exc:
                self.bus.session.put(arm_key(self.cell, self.name, "fault"), f"{type(exc).__name__}: {exc}".encode(),
                                     congestion_control=self._block)
                raise

    def stop(self) -> None:
        self._stop.set()

    def close(self) -> None:
        ev.remove_listener(self._changed)
        undeclare(self._token, *self._declared)
        self._out.put(None)
        self._publisher.join(2.0)
        ev.detach(self.arm)


def run(name: str, url: str, robot: str, cell: str, bus_endpoints: tuple[str, ...], rate_hz: int = 50,
        lease_ms: int | None = None, timeout: float | None = None) -> int:
    """The arm process: open the arm, serve it until told to stop, release it. ``timeout``: the
    control's wait for a HOW (s; None: two periods, rci.Session's default)."""
    import rccl
    with Bus(cell, tasks=(name,), connect=bus_endpoints, lease_ms=lease_ms, priority=BUS_PRIORITY) as bus, \
            rccl.open(url, robot, rate_hz=rate_hz, signals=False, lock_memory=False, timeout=timeout) as arm:
        server = ArmServer(arm, bus, name, priority=BUS_PRIORITY)
        for sig in (signal.SIGTERM, signal.SIGINT):
            signal.signal(sig, lambda *_: server.stop())
        print(f"{name}: serving", flush=True)
        try:
            server.serve()
            if any(e.status >= 0 for e in server.efts.values()):   # stopped by a signal mid-plan
                ev.stop_abort(arm)
        finally:
            server.close()
    print(f"{name}: released", flush=True)
    return 0


def spawn(name: str, url: str, robot: str, cell: str, bus_endpoints: tuple[str, ...], rate_hz: int = 50,
          lease_ms: int | None = None, how_timeout: float | None = None, timeout: float = 30.0) -> subprocess.Popen:
    """Start an arm process (``python -m rccl.bus_arm``) and wait until it serves (at most
    ``timeout`` s); the caller ends it (``close`` request, or terminate/kill the Popen)."""
    argv = [sys.executable, "-m", "rccl.bus_arm", name, url, robot, "--cell", cell, "--rate", str(rate_hz)]
    argv += [x for e in bus_endpoints for x in ("--bus", e)]
    argv += ["--lease", str(lease_ms)] if lease_ms is not None else []
    argv += ["--timeout", str(how_timeout)] if how_timeout is not None else []
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stdin=subprocess.DEVNULL)
    deadline, buf = time.monotonic() + timeout, b""
    while b"\n" not in buf:
        ready, _, _ = select.select([proc.stdout], [], [], max(0.0, deadline - time.monotonic()))
        data = os.read(proc.stdout.fileno(), 4096) if ready else b""
        if not data:
            proc.kill()
            proc.wait(5)
            why = "did not say it serves" if not ready else f"ended with code {proc.returncode}"
            raise EventError(f"the arm process for {name!r} ({url}) {why} within {timeout} s: {argv}")
        buf += data
    line = buf.split(b"\n", 1)[0].decode(errors="replace").strip()
    if line != f"{name}: serving":
        proc.kill()
        proc.wait(5)
        raise EventError(f"the arm process for {name!r} said {line!r} instead of serving: {argv}")
    return proc


def _cli(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m rccl.bus_arm", description=__doc__.split("\n\n")[0])
    ap.add_argument("name", help="the name the arm is served under (the planning level's BusEvents.arm(name))")
    ap.add_argument("url", help="the arm's link (zenoh/KEY?connect=..., socket://..., a device)")
    ap.add_argument("robot", help="the robot's model (puma260, microbo)")
    ap.add_argument("--cell", required=True, help="the workcell's name on the bus")
    ap.add_argument("--bus", action="append", default=[], help="Zenoh endpoint of the workcell's bus (repeatable)")
    ap.add_argument("--rate", type=int, default=50, help="the arm's sample rate (Hz)")
    ap.add_argument("--lease", type=int, default=None, help="the bus's lease (ms): how soon a lost peer is noticed")
    ap.add_argument("--timeout", type=float, default=None,
                    help="the control's wait for the robot's HOW (s; default two periods)")
    a = ap.parse_args(argv)
    return run(a.name, a.url, a.robot, a.cell, tuple(a.bus), a.rate, a.lease, a.timeout)


if __name__ == "__main__":
    sys.exit(_cli())
