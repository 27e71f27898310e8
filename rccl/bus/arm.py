"""An arm process: one RCCL arm served on the Zenoh bus, for a planning level in another process.

The other half of ``rccl.bus.planning`` (key expressions and semantics there). The arm's
process opens its RCCL arm (its control task runs here, at the arm's rate), attaches it
to ``rccl.events`` under its name, and then:

* answers the planning level's requests on ``rcci/CELL/arm/ARM/request`` (move with an
  event flag triple, info, free, abort, close), one at a time, in this process's serving
  thread (``ArmServer.serve``);
* publishes every change of its EFTs' flags on ``rcci/CELL/flags/ARM/SERIAL`` (from a
  publishing thread: the control level only hands a copy over, it never waits for the
  network) and answers queries for the latest;
* applies ``start_ev`` / ``stop_ev`` messages (``rcci/CELL/flags/set``) to its EFTs, once
  each, and acknowledges every copy (``rcci/CELL/arm/ARM/ack``);
* starts a motion queued with ``start=`` an EFT of another arm the moment it learns,
  from that arm's publication, that the motion ended (or at once if it already had);
* says it is alive every ``HEARTBEAT_S`` (``rcci/CELL/arm/ARM/alive``);
* watches the planning levels' liveliness tokens and heartbeats: when one's token ends, or
  it has not been heard for its silence (it is stopped, hung or cut off), it gives that
  planning level up: it aborts the motions that planning level queued (the arm holds),
  says why (``rcci/CELL/arm/ARM/held``, and a line on stdout) and refuses what that
  planning level asks afterwards (``PlannerLost``); obeys only the planning level that
  holds the arm (``rccl.bus.hold``: sealed requests, start_ev / stop_ev with a MAC; anything
  else refused, counted and reported once per flood), and answers its requests ahead of
  anyone else's (a flood of others' requests delays the holder's by one answer at most); when this process finds itself stalled
  longer than a planning level's silence, it aborts that planning level's motions too;
* publishes ``rcci/CELL/arm/ARM/fault`` and ends (exit status 1) when its arm's control
  ends with a fault.

Its liveliness token ``rcci/CELL/arm/ARM`` is declared once it serves and ends with the
process. Run it from the shell:

    python -m rccl.bus.arm --cell lab --bus tcp/10.0.0.1:7447 puma 'zenoh/lab/puma260?connect=...' puma260

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
from rci.bus.guard import Episodes, Lanes, TokenBucket
from rci.bus.link import undeclare

from .. import events as ev
from .heartbeat import HEARTBEAT_S, Heartbeat
from .hold import ArmHold
from .wire import (PlannerLost, arm_key, check_name, error_reply, flags_key, flags_of, planner_key,
                       position_from_wire, set_key)
from ..events import ABORTED, FAULT, EventError

POLL_S = 0.05          # the serving thread looks at the arm's faults this often (s)
REQUEST_QUEUE = 32     # requests waiting for the serving thread; more are dropped (counted, reported once)
HOLDER_QUEUE = 8       # ... and the holder's own (sealed by it), answered ahead of the others
REQUEST_RATE = 200.0   # requests answered a second at most
GONE_TOLD = 16         # the heartbeat names this many of the planning levels given up last
BUS_PRIORITY = 70      # SCHED_FIFO of the flags' way out and in (below the control thread's 80)


class ArmServer:
    """Serve ``arm`` (an open RCCL arm) as ``name`` on ``bus`` (its cell); ``serve()`` runs it.

    ``report_to``: a task (default the planning level) that gets, on the bus channel
    ``ARM -> report_to``, one message per motion that ends: ``{"serial", "where", "status",
    "q"}`` with the joint angles the robot reported then (rad); None for no reports.
    ``priority`` > 0: the threads that publish the flags and the heartbeat run under
    SCHED_FIFO at it. ``lose_sets`` / ``lose_acks``: a test hook, the first that many
    start_ev / stop_ev messages (their acknowledgements) are dropped here, as if the bus
    had lost them.

    The planning levels are watched: when one's liveliness token ends (its process died or
    left the bus), or its heartbeat (``rcci/CELL/planner/ID/alive``) has not come for longer
    than its silence (the one it sends with its requests), that planning level is given up:
    every motion it queued here that has not ended is stopped with ABORTED (a running one
    halts at the next sample, queued ones are deleted), the arm holds where it is, under
    this process's control, the reason is printed and published on
    ``rcci/CELL/arm/ARM/held``, and the planning level's later requests and start_ev /
    stop_ev are refused (``PlannerLost``). Its motions are also aborted (the planning level
    not given up) when this process itself was stalled (stopped, or starved) longer than a
    planning level's silence: that planning level may have given the arm up, and nothing it
    queued may go on unseen."""

    def __init__(self, arm, bus: Bus, name: str, report_to: str | None = "planning", priority: int = 0,
                 lose_sets: int = 0, lose_acks: int = 0) -> None:
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
        # a bounded hand-over: a flood of requests costs a Zenoh thread (normal priority: see run())
        # one put each and this process's serving thread at most REQUEST_RATE answers a second;
        # the holder's own requests (their seal checked) in a lane of their own, taken first
        self._requests = Lanes(HOLDER_QUEUE, REQUEST_QUEUE)
        self._request_bucket = TokenBucket(REQUEST_RATE, REQUEST_QUEUE)
        self.hold = ArmHold(self.cell, self.name)         # the planning level that holds this arm, its keys
        self._floods = [Episodes(f"{name}: a flood of requests (more than {REQUEST_QUEUE} waiting, at most "
                                 f"{REQUEST_RATE:.0f}/s answered)", lambda: self._requests.dropped, lambda: "dropped"),
                        Episodes(f"{name}: requests and start_ev/stop_ev messages not from the planning level that "
                                 "holds the arm", lambda: self.hold.refused, lambda: "refused")]
        self._stop = threading.Event()
        self._block = zenoh.CongestionControl.BLOCK
        self._kind_delete = zenoh.SampleKind.DELETE
        self._owner: dict[int, str] = {}                  # EFT serial -> the planning level that queued it
        self._planners: dict[str, float] = {}             # planning level -> its silence (s)
        self._planner_heard: dict[str, float] = {}        # planning level -> time.monotonic() of its last beat
        self._planners_gone: dict[str, str] = {}          # planning level given up -> why
        self._applied: dict[tuple[str, int], None] = {}   # start_ev / stop_ev messages applied (planner, seq)
        self.lose_sets, self.lose_acks = int(lose_sets), int(lose_acks)
        self.held: list[dict] = []                        # what was aborted for a lost planning level, and why
        self.reports = bus.channel(name, report_to, capacity=16) if report_to else None
        s = bus.session
        self._publisher = threading.Thread(target=self._publish_loop, name=f"flags-{name}", daemon=True)
        self._publisher.start()
        self._heart = Heartbeat(s, arm_key(self.cell, name, "alive"), self._beat, self._on_beat, priority,
                                f"alive-{name}")
        ev.add_listener(self._changed)
        self._declared = [
            s.declare_subscriber(f"rcci/{self.cell}/flags/*/*", self._on_flags),
            s.declare_subscriber(set_key(self.cell), self._on_set),
            s.declare_queryable(flags_key(self.cell, name, "*"), self._on_flags_query),
            s.liveliness().declare_subscriber(planner_key(self.cell, "*"), self._on_planner, history=True),
            s.declare_subscriber(planner_key(self.cell, "*", "alive"), self._on_planner_alive),
        ]
        self._declared.append(s.declare_queryable(arm_key(self.cell, name, "request"), self._offer_request))
        self._token = s.liveliness().declare_token(arm_key(self.cell, name))
        self._heart.start()

    # -- the flags out ------------------------------------------------------------------------
    def _changed(self, eft: ev.EFT) -> None:
        """rccl.events listener (under its lock, maybe at the control level): hand a copy over."""
        if eft.arm == self.name:
            self._out.put(flags_of(eft, self.name))

    def _realtime(self) -> None:
        if self.priority > 0:          # what this thread sends leaves as soon as it is handed over
            try:
                os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(self.priority))
            except (OSError, AttributeError):
                pass

    def _put(self, key: str, data: bytes) -> None:
        """Publish from a thread of this server's (never from the control level)."""
        try:
            self.bus.session.put(key, data, congestion_control=self._block, express=True)
        except Exception as exc:
            if not self.bus.session.is_closed():
                print(f"{self.name}: not published on {key}: {exc}", file=sys.stderr)

    def _publish_loop(self) -> None:
        self._realtime()
        while True:
            flags = self._out.get()
            if flags is None:
                return
            if isinstance(flags, tuple):            # (key, data): an acknowledgement, a notice
                self._put(*flags)
                continue
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
        """start_ev / stop_ev from the planning level: set the flags of this arm's EFTs named,
        once per message (``planner``, ``seq``), and acknowledge every copy with their flags."""
        try:
            m = decode(sample.payload.to_bytes())
            flag, code = m["flag"], int(m["code"])
            named = [int(s) for a, s in m["efts"] if a == self.name]
            msg_id = (str(m.get("planner")), int(m.get("seq", 0)))
        except (ValueError, KeyError, TypeError, AttributeError):
            return
        if not named:
            return
        with self._lock:
            refused = self._planners_gone.get(msg_id[0])
        if refused is not None:        # nothing of a planning level given up is applied; it is told why
            ack = {"planner": msg_id[0], "seq": msg_id[1], "arm": self.name, "flags": [], "refused": refused}
            self._out.put((arm_key(self.cell, self.name, "ack"), encode(ack)))
            return
        if not self.hold.set_ok(m):    # not from the planning level that holds the arm: dropped, counted
            return
        with self._lock:
            if self.lose_sets > 0:                # the test hook: as if the bus lost it
                self.lose_sets -= 1
                print(f"{self.name}: test hook: {flag}_ev message {msg_id[1]} dropped", file=sys.stderr, flush=True)
                return
            first = msg_id not in self._applied
            self._applied[msg_id] = None
            while len(self._applied) > 1024:
                self._applied.pop(next(iter(self._applied)))
            mine = [self.efts[s] for s in named if s in self.efts]
        if first:
            try:
                (ev.start_ev if flag == "start" else ev.stop_ev)(code, *mine)
            except EventError:
                pass                   # freed meanwhile; the planning level checked the rest
        with self._lock:
            if self.lose_acks > 0:
                self.lose_acks -= 1
                print(f"{self.name}: test hook: acknowledgement of message {msg_id[1]} dropped", file=sys.stderr,
                      flush=True)
                return
        ack = {"planner": msg_id[0], "seq": msg_id[1], "arm": self.name, "flags": [flags_of(e, self.name) for e in mine]}
        self._out.put((arm_key(self.cell, self.name, "ack"), encode(ack)))   # after the flags it changed

    # -- the planning levels and this process's own stalls --------------------------------------
    def _on_planner(self, sample) -> None:
        planner = str(sample.key_expr).rsplit("/", 1)[-1]
        if sample.kind != self._kind_delete:
            return
        self._give_up(planner, f"the planning process {planner} left the bus (its liveliness token ended)")

    def _on_planner_alive(self, sample) -> None:
        """A planning level's heartbeat: heard now."""
        planner = str(sample.key_expr).split("/")[-2]
        now = time.monotonic()
        with self._lock:
            if planner in self._planners:
                self._planner_heard[planner] = now

    def _give_up(self, planner: str, why: str, tell: bool = False) -> None:
        """Give ``planner`` up: abort what it queued here (the arm holds) and refuse it from now
        on. ``tell``: say so even if nothing of it was left to abort."""
        with self._lock:
            if planner in self._planners_gone:
                return
            self._planners_gone[planner] = why
            while len(self._planners_gone) > 1024:
                self._planners_gone.pop(next(iter(self._planners_gone)))
            self._planners.pop(planner, None)
            self._planner_heard.pop(planner, None)
        self._hold(lambda p: p == planner, why, planner, tell)

    def _hold(self, whose, why: str, planner: str | None = None, tell: bool = False) -> None:
        """Stop (ABORTED) every motion not ended that a planning level ``whose(planner)`` queued:
        the arm holds where it is; say why (printed, and published on ``.../held`` with the
        ``planner`` given up, if one was). ``tell``: say it even if there was nothing to abort.
        The notice leaves before the motions' ABORTED flags: a planning level given up learns
        why before it could read the status of a motion it waits for."""
        t = time.monotonic()
        with self._lock:
            efts = [e for s, e in self.efts.items() if whose(self._owner.get(s)) and e.status >= 0 and not e.freed]
        if not efts and not tell:
            return
        notice = {"arm": self.name, "why": why, "aborted": [e.serial for e in efts], "t": t, "planner": planner}
        self.held.append(notice)
        self._out.put((arm_key(self.cell, self.name, "held"), encode(notice)))
        if efts:
            try:
                ev.stop_ev(ABORTED, *efts)
            except EventError:              # one freed meanwhile (its motion had ended): the others
                ev.stop_ev(ABORTED, *[e for e in efts if not e.freed])
        what = (f"motion(s) {', '.join(f'#{e.serial}' for e in efts)} aborted, the arm holds" if efts
                else "nothing of it to abort")
        print(f"{self.name}: {why}: {what} (t={t:.6f})", flush=True)

    def _beat(self, n: int, now: float) -> dict:
        """The heartbeat's payload: it names the planning levels given up last."""
        with self._lock:
            return {"n": n, "t": now, "gone": list(self._planners_gone)[-GONE_TOLD:]}

    def _on_beat(self, now: float, gap: float) -> None:
        """Before each heartbeat: a beat that comes late by more than a planning level's silence
        means this process was stalled and that planning level has given the arm up: hold what
        it queued. Then give up the planning levels not heard for longer than their silence."""
        with self._lock:
            late = {p for p, silence in self._planners.items() if gap > silence}
        if late:
            self._hold(lambda p: p in late, f"this process was stalled {gap:.3f} s, longer than its planning "
                                            "level's silence: that planning level may have given the arm up")
        self._watch_planners(now, gap)

    def _watch_planners(self, now: float, gap: float) -> None:
        """Give up every planning level whose heartbeat has not come for longer than its silence.
        After a beat of this thread's own that came late by more than a heartbeat (this process
        stalled or starved: the planning levels' beats may be waiting to be read), their
        silences count from now."""
        with self._lock:
            if gap > 2 * HEARTBEAT_S:
                for p in self._planners:
                    self._planner_heard[p] = now
                return
            silent = {p: now - self._planner_heard.get(p, now) for p, silence in self._planners.items()
                      if now - self._planner_heard.get(p, now) > silence}
            silences = dict(self._planners)
        for p, quiet in silent.items():
            self._give_up(p, f"the planning process {p} went silent: no heartbeat for {quiet:.3f} s (> its silence "
                             f"{silences[p]} s: it is stopped, hung or cut off)", tell=True)

    # -- requests -------------------------------------------------------------------------------
    def _offer_request(self, query) -> None:
        """On a Zenoh thread: queue a request for the serving thread (the holder's ahead), or drop it (counted)."""
        payload = query.payload.to_bytes() if query.payload is not None else b""
        self._requests.offer(query, first=self.hold.from_holder(payload))

    def _answer(self, query) -> None:
        try:
            request = decode(query.payload.to_bytes()) if query.payload is not None else {}
            answer = self._do(request)
        except Exception as exc:   # every refusal goes back to the planning level, named
            answer = error_reply(exc)
        query.reply(query.key_expr, encode(answer))

    def _do(self, r: dict) -> dict:
        op = r.get("op")
        planner = r.get("planner")
        if planner is not None:
            planner = str(planner)
            with self._lock:
                why = self._planners_gone.get(planner)
                if why is None:
                    self._planners[planner] = float(r.get("silence", 1e9))
                    self._planner_heard.setdefault(planner, time.monotonic())
            if why is not None:
                raise PlannerLost(f"arm {self.name!r} gave the planning level {planner} up ({why}): the motions it "
                                  "queued here were aborted, the arm holds; a new planning level (a new BusEvents) "
                                  "drives it")
        if op == "hold":
            return self.hold.take(r, lambda p: p in self._planners_gone)
        if op != "info":
            r = self.hold.open(r)                     # the holder's own request, or ArmHeld
            op = r.get("op")
        if op == "info":                              # anyone's, or the holder's sealed
            return {"robot": self.arm.robot, "rate_hz": self.arm.rate_hz, "q": self.arm.q}
        if op == "release":
            self.hold.release(str(planner))
            return {"released": True}
        if op == "move":
            return self._move(r)
        if op == "free":
            ev.free_ev(*[self._eft(s) for s in r["serials"]])
            with self._lock:
                for s in r["serials"]:
                    self.efts.pop(int(s), None)
                    self._latest.pop(int(s), None)
                    self._owner.pop(int(s), None)
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
        with self._lock:
            self.efts[eft.serial] = eft
            if r.get("planner") is not None:
                self._owner[eft.serial] = str(r["planner"])
        return {"serial": eft.serial, "flags": flags_of(eft, self.name)}

    # -- the serving loop -------------------------------------------------------------------------
    def serve(self) -> None:
        """Answer requests until ``close`` (or ``stop()``); raise the arm's fault after publishing it."""
        while not self._stop.is_set():
            query = self._requests.take(POLL_S)
            if query is not None and not self._request_bucket.take():
                time.sleep(self._request_bucket.wait_time())
                self._request_bucket.take()
            for line in filter(None, (e.poll() for e in self._floods)):
                print(line, flush=True)
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
        self._stop.set()
        ev.remove_listener(self._changed)
        undeclare(self._token, *self._declared)
        self._out.put(None)
        self._publisher.join(2.0)
        self._heart.stop()
        ev.detach(self.arm)


def run(name: str, url: str, robot: str, cell: str, bus_endpoints: tuple[str, ...], rate_hz: int = 50,
        lease_ms: int | None = None, timeout: float | None = None, lose_sets: int = 0, lose_acks: int = 0,
        zenoh_config: str | None = None, late_limit: int | None = None) -> int:
    """The arm process: open the arm, serve it until told to stop, release it. ``timeout``: the
    control's wait for a HOW (s; None: two periods, rci.Session's default); ``lose_sets`` /
    ``lose_acks``: ArmServer's test hook."""
    import rccl
    # the bus's Zenoh threads at normal priority: at real-time priority (BUS_PRIORITY) a flood of
    # queries (20,000 info requests from another process) kept them busy past the kernel's
    # real-time budget, which then stopped the control thread with them (50 ms stalls,
    # R_OVERRUN; measured again 2026-11-27 18:39); the flags' own threads stay real time
    with Bus(cell, tasks=(name,), connect=bus_endpoints, lease_ms=lease_ms, priority=0,
             config=zenoh_config) as bus, \
            rccl.open(url, robot, rate_hz=rate_hz, signals=False, lock_memory=False, timeout=timeout,
                      on_error="raise", late_limit=late_limit) as arm:
        server = ArmServer(arm, bus, name, priority=BUS_PRIORITY, lose_sets=lose_sets, lose_acks=lose_acks)
        for sig in (signal.SIGTERM, signal.SIGINT):
            signal.signal(sig, lambda *_: server.stop())
        print(f"{name}: serving", flush=True)
        try:
            server.serve()
            if any(e.status >= 0 for e in server.efts.values()):   # stopped by a signal mid-plan
                ev.stop_abort(arm)
        except Exception as exc:         # the control ended with a fault, published by serve()
            print(f"{name}: the control ended: {type(exc).__name__}: {exc}", flush=True)
            return 1
        finally:
            server.close()
    print(f"{name}: released", flush=True)
    return 0


def spawn(name: str, url: str, robot: str, cell: str, bus_endpoints: tuple[str, ...], rate_hz: int = 50,
          lease_ms: int | None = None, how_timeout: float | None = None, timeout: float = 30.0,
          extra: tuple[str, ...] = ()) -> subprocess.Popen:
    """Start an arm process (``python -m rccl.bus.arm``) and wait until it serves (at most
    ``timeout`` s); the caller ends it (``close`` request, or terminate/kill the Popen).
    ``extra``: more of its options (``--lose-sets N``). Its stdout stays a pipe: after the
    ``serving`` line it tells what it aborted and why (``_hold``)."""
    argv = [sys.executable, "-m", "rccl.bus.arm", name, url, robot, "--cell", cell, "--rate", str(rate_hz)]
    argv += [x for e in bus_endpoints for x in ("--bus", e)]
    argv += ["--lease", str(lease_ms)] if lease_ms is not None else []
    argv += ["--timeout", str(how_timeout)] if how_timeout is not None else []
    argv += list(extra)
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
    ap = argparse.ArgumentParser(prog="python -m rccl.bus.arm", description=__doc__.split("\n\n")[0])
    ap.add_argument("name", help="the name the arm is served under (the planning level's BusEvents.arm(name))")
    ap.add_argument("url", help="the arm's link (zenoh/KEY?connect=..., socket://..., a device)")
    ap.add_argument("robot", help="the robot's model (puma260, microbo)")
    ap.add_argument("--cell", required=True, help="the workcell's name on the bus")
    ap.add_argument("--bus", action="append", default=[], help="Zenoh endpoint of the workcell's bus (repeatable)")
    ap.add_argument("--rate", type=int, default=50, help="the arm's sample rate (Hz)")
    ap.add_argument("--lease", type=int, default=None, help="the bus's lease (ms): how soon a lost peer is noticed")
    ap.add_argument("--zenoh-config", metavar="FILE", default=None,
                    help="the bus's Zenoh configuration file (TLS, authentication, access control; default "
                         "$RCI_ZENOH_CONFIG; docs/security.md); the arm's zenoh/ link takes its own ?config=")
    ap.add_argument("--timeout", type=float, default=None,
                    help="the control's wait for the robot's HOW (s; default two periods)")
    ap.add_argument("--late-limit", type=int, default=None, metavar="N",
                    help="late cycles in a row that end the control (default: the session's, 3)")
    ap.add_argument("--lose-sets", type=int, default=0, metavar="N",
                    help="test hook: drop the first N start_ev/stop_ev messages, as if the bus lost them")
    ap.add_argument("--lose-acks", type=int, default=0, metavar="N",
                    help="test hook: drop the acknowledgements of the first N start_ev/stop_ev messages")
    a = ap.parse_args(argv)
    for opt in ("lose_sets", "lose_acks"):
        if getattr(a, opt) < 0:
            ap.error(f"--{opt.replace('_', '-')} must be >= 0, got {getattr(a, opt)}")
    return run(a.name, a.url, a.robot, a.cell, tuple(a.bus), a.rate, a.lease, a.timeout, a.lose_sets, a.lose_acks,
               a.zenoh_config, a.late_limit)


if __name__ == "__main__":
    sys.exit(_cli())
