"""Event flag triples across processes and hosts, on the Zenoh bus (thesis 5.6.3 over 2.4.3).

The thesis's planning level issues motions with event flags to the trajectory levels of
several arms. When each arm's control task runs in its own process (or on its own host),
each arm process serves its RCCL arm on the bus (``rccl.bus.arm``), and the planning
process drives them through :class:`BusEvents`, which has the API of ``rccl.events``:

    from rci.bus import Bus
    from rccl.bus.planning import BusEvents
    with Bus("lab", tasks=("planning",), listen=("tls/10.0.0.1:7447",), config="cell.json5") as bus:
        ev = BusEvents(bus)
        puma, mic = ev.arm("puma"), ev.arm("microbo")        # served by their processes
        a = ev.move_ev(puma, p1)                              # starts when ready
        b = ev.move_ev(mic, p2, start=a)                      # starts when the PUMA's motion ends
        ev.wait_ev(b); ev.free_ev(a, b)

so a planning function written against ``rccl.events`` (``plan(ev, puma, mic, pos)`` in
examples/two_arm_flags.py) runs unchanged against arms in other processes.

**What crosses the bus.** Every change of an EFT's flags (queued, start set, begun, stop
set, ended) is published by the arm's process; the planning process and the other arm
processes keep the latest of each. ``move_ev(arm_b, q, start=eft_a)`` asks B's process
to queue the motion held, and B's process sets its start flag itself when it learns
that A's motion ended (DONE, LIMIT, MONITOR or any code a program gave; not FAULT or
ABORTED, as in one process): no round trip through the planning level. The latency is
one bus hop (A's process to B's, through the process they both connect to) plus at most
one sample of B (its trajectory level looks at its queue once per sample). ``start_ev``
and ``stop_ev`` are one message that sets the flags of EFTs of several arms at once;
each arm acts on it at its next sample (arms with independent clocks: within one sample
of each other, plus the bus's spread of a few hundred microseconds). The message carries
this planning level's id and a sequence number; each arm applies it once and acknowledges
every copy with the flags of its EFTs named; ``start_ev`` / ``stop_ev`` send it again every
``RESEND_S`` until every arm addressed has acknowledged it (a lost message or a lost
acknowledgement costs ``RESEND_S``, nothing is applied twice) or is lost (``ArmLost``).

**Faults** (docs/zenoh.md, "Faults"): each side watches the other's liveliness token and
heartbeat (every ``HEARTBEAT_S``); a dead or silent arm process (``silence`` s) is lost
(``ArmLost`` from every request and wait on it, the robot holds the arm), a fault ends in
``RemoteFault``; an arm process gives up a dead or silent planning level (it aborts the
motions it queued, the arm holds) and refuses it from then on (``PlannerLost``).

**Holding an arm** (``rccl.bus.hold``): the first request that is not ``info`` takes the arm
with a key agreed with its process; every later request is sealed under it and each
start_ev / stop_ev message carries a MAC per arm: an arm process obeys the planning level
that holds it and nobody else; ``close()`` releases the arms.

Key expressions and what crosses the bus: ``rccl.bus.wire``.
"""
from __future__ import annotations

import threading
import time
from typing import Any

from rci.bus import Bus, decode, encode
from rci.bus.link import undeclare

from .heartbeat import HEARTBEAT_S, Heartbeat
from .hold import PlannerHolds
from .remote import RemoteArm, RemoteEFT
from .wire import (KNOWN_ERRORS, ArmLost, PlannerLost, RemoteFault, arm_key, check_name, flags_key, planner_key,
                       position_to_wire, set_key)
from .wire import position_from_wire  # noqa: F401 - part of this module's API, as before the split
from ..events import (ABORTED, NULL, START, Deadlock, EventError, UnknownEvent, check_start_code, check_stop_code,
                      code_name, never_starts)
from ..position import Position

REQUEST_TIMEOUT_S = 5.0
REFRESH_S = 1.0          # a wait that hears nothing for this long asks the arms for the latest flags (s)
MUTE_REFRESHES = 3       # ... and gives an arm up as lost after this many unanswered asks in a row
SILENCE_S = 0.5          # the planning level gives up an arm it has not heard from for this long, and the
                         # arm processes give up a planning level they have not heard from for as long (s)
RESEND_S = 0.1           # start_ev / stop_ev are sent again after this long without every arm's acknowledgement (s)


class BusEvents:
    """The event-flag primitives of ``rccl.events`` for arms served on the bus of ``bus.cell``.

    ``silence``: an arm whose process has not been heard (its heartbeat, every ``HEARTBEAT_S``)
    for this long (s) is lost: stopped, hung or cut off; and the arm processes give this
    planning level up when they have not heard its heartbeat (``rcci/CELL/planner/ID/alive``)
    for as long. This planning level declares a liveliness token (``rcci/CELL/planner/ID``):
    the arm processes abort the motions it queued when it ends. ``priority``: SCHED_FIFO of
    the heartbeat's thread (default the bus's, 0: none). ``sets_sent`` / ``sets_resent``
    count start_ev / stop_ev messages."""

    def __init__(self, bus: Bus, request_timeout: float = REQUEST_TIMEOUT_S, silence: float = SILENCE_S,
                 priority: int | None = None) -> None:
        import uuid

        import zenoh
        if not silence > HEARTBEAT_S:
            raise EventError(f"BusEvents: silence must be longer than the arms' heartbeat ({HEARTBEAT_S} s), "
                             f"got {silence!r}")
        self.bus = bus
        self.cell = bus.cell
        self.request_timeout = request_timeout
        self.silence = float(silence)
        self.id = uuid.uuid4().hex[:16]                     # this planning level, as the arm processes know it
        self._alive: dict[str, float] = {}                  # arm -> time.monotonic() it was last heard
        self._why_lost: dict[str, str] = {}                 # arm -> why it is lost
        self._acks: dict[int, set[str]] = {}                # set message -> arms that acknowledged it
        self._seq = 0
        self._last_turn = 0.0                               # time.monotonic() of a waiting loop's last turn
        self.sets_sent = 0
        self.sets_resent = 0
        self._cond = threading.Condition()
        self._flags: dict[tuple[str, int], dict] = {}
        self._issued: dict[str, list[RemoteEFT]] = {}      # per arm, in the order move_ev queued them
        self._present: set[str] = set()
        self._lost: dict[str, float] = {}                   # arm -> time.monotonic() its token ended
        self._faults: dict[str, str] = {}
        self._arms: dict[str, RemoteArm] = {}
        self._heard = 0                                     # counts flag changes heard (a wait's sign of life)
        self._mute: dict[str, int] = {}                     # arm -> refreshes in a row it did not answer
        self._given_up: dict[str, str] = {}                 # arm -> why its process gave this planning level up
        self.holds = PlannerHolds(self.cell, self.id, lambda arm, r: self._ask(arm, r, "hold"))
        s = bus.session
        self._kind_delete = zenoh.SampleKind.DELETE
        self._declared = [
            s.declare_subscriber(f"rcci/{self.cell}/flags/*/*", self._on_flags),
            s.declare_subscriber(arm_key(self.cell, "*", "fault"), self._on_fault),
            s.liveliness().declare_subscriber(arm_key(self.cell, "*"), self._on_liveliness, history=True),
            s.declare_subscriber(arm_key(self.cell, "*", "alive"), self._on_alive),
            s.declare_subscriber(arm_key(self.cell, "*", "ack"), self._on_ack),
            s.declare_subscriber(arm_key(self.cell, "*", "held"), self._on_held),
            s.liveliness().declare_token(planner_key(self.cell, self.id)),
        ]
        beat = lambda n, now: {"n": n, "t": now, "silence": self.silence}    # noqa: E731
        self._heart = Heartbeat(s, planner_key(self.cell, self.id, "alive"), beat, self._on_beat,
                                getattr(bus, "priority", 0) if priority is None else priority, f"alive-{self.id}")
        self._heart.start()

    # -- what the bus tells ---------------------------------------------------------------
    def _on_flags(self, sample) -> None:
        try:
            self._absorb(decode(sample.payload.to_bytes()))
        except (ValueError, KeyError, TypeError):
            return

    def _absorb(self, f: dict) -> None:
        """Keep ``f`` (one EFT's flags) if it is newer than what is known."""
        key = (str(f["arm"]), int(f["serial"]))
        with self._cond:
            old = self._flags.get(key)
            if old is None or f.get("version", 0) > old.get("version", 0):
                self._flags[key] = f
                self._heard += 1
            self._cond.notify_all()

    def _on_fault(self, sample) -> None:
        name = str(sample.key_expr).split("/")[-2]
        with self._cond:
            self._faults[name] = sample.payload.to_bytes().decode(errors="replace")
            self._cond.notify_all()

    def _on_liveliness(self, sample) -> None:
        name = str(sample.key_expr).rsplit("/", 1)[-1]
        with self._cond:
            if sample.kind == self._kind_delete:
                self._present.discard(name)
                if name not in self._lost:
                    self._lost[name] = time.monotonic()
                    self._why_lost[name] = "left the bus (its liveliness token ended)"
            else:                         # a process serves it (again): a new process, heard from now
                self._present.add(name)
                self._lost.pop(name, None)
                self._why_lost.pop(name, None)
                self._faults.pop(name, None)
                self._alive[name] = time.monotonic()
            self._cond.notify_all()

    def _on_alive(self, sample) -> None:
        """An arm process's heartbeat. One given up for its silence stays lost (a stale process
        that comes back is ignored: only a new process, a new token, is heard); it names those it gave up."""
        name = str(sample.key_expr).split("/")[-2]
        try:
            gone = decode(sample.payload.to_bytes()).get("gone", [])
        except (ValueError, TypeError, AttributeError):
            gone = []
        with self._cond:
            if name not in self._lost:
                self._alive[name] = time.monotonic()
            if self.id in gone:
                self._told(name, "its process lists this planning level as given up in its heartbeat (not heard "
                                 f"for longer than its silence, {self.silence} s, or its token ended): it aborted "
                                 "the motions queued there and holds the arm")

    def _on_held(self, sample) -> None:
        """An arm process aborted a planning level's motions: this one's, it has given it up."""
        try:
            m = decode(sample.payload.to_bytes())
            planner, arm, why = m.get("planner"), str(m["arm"]), str(m["why"])
        except (ValueError, KeyError, TypeError, AttributeError):
            return
        if planner != self.id:
            return
        with self._cond:
            self._told(arm, f"its process says: {why} (it aborted the motions queued there)")

    def _told(self, arm: str, why: str) -> None:
        """``arm``'s process says it gave this planning level up; if this process was stalled longer
        than its silence, that is the reason (caller holds the condition)."""
        self._check_own_silence(time.monotonic())
        self._given_up.setdefault(arm, why)
        self._cond.notify_all()

    def _on_beat(self, now: float, gap: float) -> None:      # before each heartbeat of this planning level
        with self._cond:
            self._check_own_silence(now, gap)

    def _check_own_silence(self, now: float, gap: float | None = None) -> None:
        """This planning level's heartbeat has not gone out for longer than ``silence`` (its
        process was stopped, hung or starved): every arm process it made requests to has not
        heard it for that long and has given it up (caller holds the condition)."""
        gap = now - self._heart.last if gap is None else gap
        if gap <= self.silence:
            return
        for arm in self._arms:
            self._given_up.setdefault(arm, f"this planning level was silent {gap:.3f} s (its process stopped, hung or "
                                           f"starved), longer than its silence ({self.silence} s): the process serving "
                                           f"arm {arm!r} has aborted the motions it queued there and holds the arm")
        self._cond.notify_all()

    def _check_given_up(self, arm: str, where: str) -> None:
        """Raise ``PlannerLost`` if ``arm``'s process gave this planning level up (caller holds the condition)."""
        self._check_own_silence(time.monotonic())
        why = self._given_up.get(arm)
        if why is not None:
            raise PlannerLost(f"{where}: arm {arm!r} gave this planning level up: {why}; only a new planning level "
                              "(a new BusEvents) drives it again")

    def given_up(self, arm: str) -> str | None:
        """Why ``arm``'s process gave this planning level up (None if it has not, as far as this process knows)."""
        with self._cond:
            self._check_own_silence(time.monotonic())
            return self._given_up.get(arm)

    def _on_ack(self, sample) -> None:
        """An arm process applied (or had already applied) start_ev / stop_ev message ``seq``."""
        try:
            m = decode(sample.payload.to_bytes())
            if m.get("planner") != self.id:
                return
            seq, arm, flags = int(m["seq"]), str(m["arm"]), list(m["flags"])
            refused = m.get("refused")
        except (ValueError, KeyError, TypeError, AttributeError):
            return
        for f in flags:
            self._absorb(f)
        with self._cond:
            if refused is not None:       # not applied: that arm's process gave this planning level up
                self._told(arm, f"its process refused a start_ev / stop_ev: {refused}")
            if seq in self._acks:
                self._acks[seq].add(arm)
            self._cond.notify_all()

    def _watching(self, poll: float) -> bool:
        """A waiting loop's turn: True if the previous turn (of any wait) ran within ``poll`` +
        ``silence``/2, i.e. this process has been watching all along. After a gap (the first turn
        of a wait, or this process itself stopped or starved) the arms' heartbeats may still be
        queued behind it: the turn only primes the watch."""
        now = time.monotonic()
        on_time = now - self._last_turn <= poll + self.silence / 2
        self._last_turn = now
        return on_time

    def _silent(self, arm: str) -> bool:
        """``arm`` has not been heard for ``silence`` s: declare it lost (caller holds the
        condition and has checked ``_watching``)."""
        if arm in self._lost:
            return True
        now = time.monotonic()
        heard = self._alive.get(arm, now)
        if now - heard <= self.silence:
            return False
        self._lost[arm] = heard
        self._why_lost[arm] = (f"went silent: no heartbeat for {now - heard:.3f} s (> {self.silence} s: its process "
                               "is stopped, hung or cut off)")
        return True

    def fault(self, arm: str) -> str | None:
        """The fault ``arm``'s process published when its control ended (None if none)."""
        with self._cond:
            return self._faults.get(arm)

    def flags(self, arm: str, serial: int) -> dict:
        """The latest flags published for EFT ``serial`` of ``arm`` ({} if none yet)."""
        with self._cond:
            return self._flags.get((arm, serial), {})

    # -- arms -------------------------------------------------------------------------------
    def arm(self, name: str, timeout: float = 10.0) -> RemoteArm:
        """The arm served as ``name`` on this cell, once its process is there (at most ``timeout`` s)."""
        check_name(name, "BusEvents.arm")
        if name in self._arms:
            return self._arms[name]
        deadline = time.monotonic() + timeout
        while not self._is_present(name) and time.monotonic() < deadline:
            with self._cond:
                self._cond.wait_for(lambda: name in self._present, min(0.5, max(0.0, deadline - time.monotonic())))
        if not self._is_present(name):
            raise ArmLost(f"no process serves arm {name!r} on {arm_key(self.cell, name)} within {timeout} s "
                          "(is its arm process (python -m rccl.bus.arm) running and connected to this bus?)")
        with self._cond:
            self._alive.setdefault(name, time.monotonic())
        info = self.request(name, {"op": "info"}, "arm")
        self._arms[name] = RemoteArm(self, name, info)
        return self._arms[name]

    def _is_present(self, name: str) -> bool:
        """Its liveliness token is there (seen by the subscriber, or found by asking)."""
        with self._cond:
            if name in self._present:
                return True
        for reply in self.bus.session.liveliness().get(arm_key(self.cell, name), timeout=0.5):
            if reply.ok is not None:
                with self._cond:
                    self._present.add(name)
                return True
        return False

    def attach(self, arm: RemoteArm, name: str | None = None) -> str:
        """As ``rccl.events.attach``: the arm's name (a remote arm's name is the one it is served under)."""
        arm = self._own_arm(arm, "attach")
        if name is not None and name != arm.name:
            raise EventError(f"attach: this arm is served as {arm.name!r}, not {name!r}")
        return arm.name

    def request(self, arm: str, payload: dict, where: str) -> dict:
        """Ask ``arm``'s process; its answer, or the error it names raised here (``ArmLost`` at
        once for an arm whose process left the bus, after ``request_timeout`` s for one that is mute)."""
        with self._cond:
            self._check_given_up(arm, where)
            lost, why = self._lost.get(arm), self._why_lost.get(arm, "left the bus")
        if lost is not None:
            raise ArmLost(f"{where}: arm {arm!r} is lost: its process {why}, {time.monotonic() - lost:.3f} s ago")
        return self._ask(arm, self.holds.wire(arm, {**payload, "planner": self.id, "silence": self.silence}), where)

    def _ask(self, arm: str, wire: dict, where: str) -> dict:
        replies = self.bus.session.get(arm_key(self.cell, arm, "request"), payload=encode(wire),
                                       timeout=self.request_timeout)
        for reply in replies:
            if reply.ok is None:
                continue
            answer = decode(reply.ok.payload.to_bytes())
            if "error" in answer:
                if answer.get("type") == PlannerLost.__name__:
                    with self._cond:
                        self._told(arm, f"its process refused a request: {answer['error']}")
                    raise PlannerLost(f"{where}: arm {arm!r} (its process) says: {answer['error']}")
                cls = KNOWN_ERRORS.get(answer.get("type"), RemoteFault)
                raise cls(f"{where}: arm {arm!r} (its process) says: {answer['error']}")
            return answer
        with self._cond:
            gone = arm in self._lost
        raise ArmLost(f"{where}: arm {arm!r}'s process {'left the bus' if gone else 'did not answer'} "
                      f"(no reply on {arm_key(self.cell, arm, 'request')} within {self.request_timeout} s)")

    def _own_arm(self, arm: Any, where: str) -> RemoteArm:
        if not isinstance(arm, RemoteArm) or arm.events is not self:
            raise EventError(f"{where}: {arm!r} is not an arm of this bus (use BusEvents.arm(name))")
        return arm

    def _live(self, eft: Any, where: str) -> RemoteEFT:
        if not isinstance(eft, RemoteEFT) or eft.events is not self:
            raise UnknownEvent(f"{where}: {eft!r} is not an event flag triple of this bus (use the one move_ev returned)")
        if eft.freed:
            raise UnknownEvent(f"{where}: {eft.describe()} was freed by free_ev; its flags no longer exist")
        return eft

    # -- the primitives ----------------------------------------------------------------------
    def move_ev(self, arm: RemoteArm, position: Position, *, start: int | RemoteEFT | None = START,
                after_code: int = START) -> RemoteEFT:
        """``rccl.events.move_ev`` on an arm of another process (its current motion parameters)."""
        arm = self._own_arm(arm, "move_ev")
        wire_start: Any
        source = None
        if isinstance(start, RemoteEFT):
            source = self._live(start, "move_ev(start=...)")
            check_start_code(after_code, "move_ev(after_code=...)")
            wire_start = {"after": [source.arm, source.serial], "code": after_code,
                          "flags": self.flags(source.arm, source.serial) or None}
        else:
            if start is not None:
                check_start_code(start, "move_ev(start=...)")
            wire_start = start
        answer = self.request(arm.name, {"op": "move", "position": position_to_wire(position), "start": wire_start},
                              "move_ev")
        eft = RemoteEFT(self, arm.name, int(answer["serial"]), position.name)
        eft.after = source
        with self._cond:
            self._issued.setdefault(arm.name, []).append(eft)
        self._absorb(answer["flags"])
        return eft

    def start_ev(self, code: int, *efts: RemoteEFT) -> None:
        """Set the start flag of every EFT given (of any arms) to ``code`` (> 0), in one publication."""
        check_start_code(code, "start_ev")
        checked = [self._live(e, f"start_ev(argument {i + 2})") for i, e in enumerate(efts)]
        for e in checked:
            e.start_sent = int(code)
        self._publish_set("start", code, checked)

    def stop_ev(self, code: int, *efts: RemoteEFT) -> None:
        """Set the stop flag of every EFT given to ``code`` (< 0), in one publication: each motion
        halts at its arm's next sample (or, not started, is deleted from its queue)."""
        check_stop_code(code, "stop_ev")
        checked = [self._live(e, f"stop_ev(argument {i + 2})") for i, e in enumerate(efts)]
        for e in checked:
            if e.status >= 0:
                e.stop_sent = int(code)
        self._publish_set("stop", code, checked)

    def _publish_set(self, flag: str, code: int, efts: list[RemoteEFT], poll: float = 0.02) -> None:
        """Publish one start_ev / stop_ev message and send it again every ``RESEND_S`` until every
        arm it addresses has acknowledged it (each applies a message once: a copy only brings its
        acknowledgement again) or is lost (its token ended, or silent for ``silence`` s); then
        ``ArmLost`` names the arms that did not get it. Returns once all did (one bus round
        trip, a few milliseconds on one host)."""
        import zenoh
        if not efts:
            return
        with self._cond:
            for arm in sorted({e.arm for e in efts}):
                self._check_given_up(arm, f"{flag}_ev({code})")
            self._seq += 1
            seq = self._seq
            self._acks[seq] = set()
        message = {"flag": flag, "code": int(code), "efts": [[e.arm, e.serial] for e in efts],
                   "planner": self.id, "seq": seq}
        addressed = {e.arm for e in efts}
        data = encode({**message, "mac": self.holds.macs(message, addressed)})
        sends = 0
        try:
            while True:
                self.bus.session.put(set_key(self.cell), data, congestion_control=zenoh.CongestionControl.BLOCK,
                                     express=True)
                sends += 1
                self.sets_sent += 1
                self.sets_resent += sends > 1
                resend_at = time.monotonic() + RESEND_S
                with self._cond:
                    while True:
                        pending = addressed - self._acks[seq]
                        if self._watching(poll):
                            for arm in pending:
                                self._silent(arm)
                        lost = {a for a in pending if a in self._lost}
                        if pending <= lost or time.monotonic() >= resend_at:
                            break
                        self._cond.wait(poll)
                with self._cond:
                    for arm in sorted(addressed):
                        self._check_given_up(arm, f"{flag}_ev({code})")
                if not pending:
                    return
                if pending <= lost:
                    raise ArmLost(f"{flag}_ev({code}): not applied by arm(s) " + ", ".join(
                        f"{a!r} (its process {self._why_lost.get(a, 'left the bus')})" for a in sorted(lost)))
                if sends * RESEND_S > self.request_timeout:
                    raise ArmLost(f"{flag}_ev({code}): arm(s) {sorted(pending)} did not acknowledge it in "
                                  f"{sends} sends over {self.request_timeout} s")
        finally:
            with self._cond:
                self._acks.pop(seq, None)

    def status_ev(self, eft: RemoteEFT) -> int:
        """The status flag as last published: NULL pending, > 0 running, < 0 ended."""
        return self._live(eft, "status_ev").status

    def wait_ev(self, eft: RemoteEFT, *, started: bool = False, timeout: float | None = None,
                poll: float = 0.02) -> int:
        """Block until ``eft``'s motion has ended (``started=True``: begun); its status.

        Raises ``Deadlock`` when nothing but this planning level could start it, ``ArmLost``
        when its arm's process (or that of a motion it waits for) left the bus, ``RemoteFault``
        when that arm's control ended with a fault, ``TimeoutError`` after ``timeout`` s.
        """
        eft = self._live(eft, "wait_ev")
        done = (lambda: eft.status != NULL) if started else (lambda: eft.status < 0)
        deadline = None if timeout is None else time.monotonic() + timeout
        heard, quiet_since = self._heard, time.monotonic()
        while True:
            with self._cond:
                for e in self._chain(eft):          # a motion aborted because this planning level was given up
                    if e.status >= 0 or e.status == ABORTED:
                        self._check_given_up(e.arm, f"wait_ev: {eft.describe()}")
                if done():
                    return eft.status
                if self._watching(poll):
                    for e in self._chain(eft):
                        if e.status >= 0:
                            self._silent(e.arm)
                self._check_blocked(eft, started)
                if deadline is not None and time.monotonic() > deadline:
                    raise TimeoutError(f"wait_ev: {eft!r} after {timeout} s")
                self._cond.wait(poll)
                chain = self._chain(eft)
                if self._heard != heard:
                    heard, quiet_since = self._heard, time.monotonic()
            if time.monotonic() - quiet_since > REFRESH_S:     # a publication lost? ask for the latest
                self._refresh(chain, eft)
                quiet_since = time.monotonic()

    def _refresh(self, efts: list[RemoteEFT], waited: RemoteEFT) -> None:
        """Ask the arms' processes for the latest flags of ``efts`` (they answer from what they
        published); an arm that has not answered for ``MUTE_REFRESHES`` refreshes in a row is lost."""
        for e in efts:
            if e.status < 0 or e.arm in self._lost:
                continue
            answered = False
            for reply in self.bus.session.get(flags_key(self.cell, e.arm, e.serial), timeout=0.5):
                if reply.ok is not None:
                    answered = True
                    self._on_flags(reply.ok)
            self._mute[e.arm] = 0 if answered else self._mute.get(e.arm, 0) + 1
            if self._mute[e.arm] >= MUTE_REFRESHES:
                raise ArmLost(f"wait_ev: {waited.describe()}: arm {e.arm!r}'s process has not answered for its "
                              f"flags {MUTE_REFRESHES} times in a row (its token may still be there: unreachable "
                              "through the bus)")

    def free_ev(self, *efts: RemoteEFT) -> None:
        """Give EFTs back (their motions must have ended); their arms' processes forget them."""
        checked = [self._live(e, f"free_ev(argument {i + 1})") for i, e in enumerate(efts)]
        busy = [e for e in checked if e.status >= 0]
        if busy:
            raise EventError("free_ev: " + "; ".join(f"{e.describe()} has not ended (status {code_name(e.status)})"
                                                     for e in busy))
        for arm in sorted({e.arm for e in checked}):
            serials = [e.serial for e in checked if e.arm == arm]
            self.request(arm, {"op": "free", "serials": serials}, "free_ev")
        with self._cond:
            for e in checked:
                e.final = self._flags.pop((e.arm, e.serial), {})
                e.freed = True
                if e in self._issued.get(e.arm, []):
                    self._issued[e.arm].remove(e)

    def stop_abort(self, arm: RemoteArm) -> None:
        """Flush the arm's queue and halt it; its EFTs not yet ended get ABORTED."""
        arm = self._own_arm(arm, "stop_abort")
        answer = self.request(arm.name, {"op": "abort"}, "stop_abort")
        for flags in answer["flags"]:          # what it aborted, known before its publications arrive
            self._absorb(flags)

    def close(self) -> None:
        """Leave the bus: the token ends (the arm processes abort what this planning level
        queued and has not ended), then the heartbeat stops; the arms it holds are released
        (without waiting: a released arm is also freed by the end of the token)."""
        for arm in self.holds.held():
            self.bus.session.get(arm_key(self.cell, arm, "request"), lambda _: None, timeout=1.0, payload=encode(
                self.holds.wire(arm, {"op": "release", "planner": self.id, "silence": self.silence})))
        undeclare(*self._declared)
        self._heart.stop()

    # -- why a wait cannot end (caller holds the condition) ---------------------------------------
    def _check_blocked(self, eft: RemoteEFT, started: bool) -> None:
        for e in self._chain(eft):
            if e.arm in self._faults and e.status >= 0:
                raise RemoteFault(f"wait_ev: {eft.describe()}: the control of arm {e.arm!r} ended with a fault "
                                  f"({self._faults[e.arm]})")
            if e.arm in self._lost and e.status >= 0:
                ago = time.monotonic() - self._lost[e.arm]
                via = "" if e is eft else f" (it waits for {e.describe()})"
                why = self._why_lost.get(e.arm, "left the bus")
                raise ArmLost(f"wait_ev: {eft.describe()} will never {'start' if started else 'end'}{via}: the "
                              f"process serving arm {e.arm!r} {why}, {ago:.3f} s ago; the robot holds that arm")
        why = never_starts(eft, self._predecessor)
        if why is not None:
            raise Deadlock(f"wait_ev: {eft.describe()} can never {'start' if started else 'end'}: {why}")

    def _chain(self, e: RemoteEFT) -> list[RemoteEFT]:
        """``e`` and the motions it waits for (before it on its arm, its start condition), transitively."""
        out, todo, seen = [], [e], set()
        while todo:
            x = todo.pop()
            if id(x) in seen:
                continue
            seen.add(id(x))
            out.append(x)
            if x.status == NULL:
                todo += [d for d in (x.after, self._predecessor(x)) if d is not None]
        return out

    def _predecessor(self, e: RemoteEFT) -> RemoteEFT | None:
        lst = self._issued.get(e.arm, [])
        i = lst.index(e) if e in lst else 0
        for p in reversed(lst[:i]):
            if p.status >= 0:
                return p
        return None
