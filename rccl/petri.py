"""Petri nets of event flag triples (thesis 1.4.5, 5.6.3): build a program's net, explore it, report what can go wrong.

The thesis proves its three-flag protocol safe with a Petri net (Figure 5.6) and its
reachability tree (Figure 5.7). This module does the same for a whole program, before it
runs:

* ``Net``: places, transitions (input and output arcs with weights) and an initial
  marking; ``Net.is_final`` says which dead markings are a proper end.
* ``analyse(net)``: the Karp-Miller coverability tree (finds unbounded places and every
  transition that can ever fire, also for unbounded nets), then, for a bounded net, the
  reachability graph: dead markings that are not final (deadlocks), markings from which
  no final marking can be reached (livelocks), actions that never fire (unreachable).
  Each finding carries the shortest firing sequence that reaches it.
* ``thesis_net()``: the net of Figure 5.6 (one EFT, flags set by anyone in any order).
* ``FlagProgram``: a recorder with the planning-level primitives of ``rccl.events``
  (``move_ev``, ``start_ev``, ``stop_ev``, ``wait_ev``, ``start_after``, ``free_ev``,
  ``move``). Write the planning part of a program as a function of the events module and
  the arms; call it with ``rccl.events`` and real arms to run it, or give it to
  ``record``/``check`` to obtain its flag triples without moving anything.
  ``FlagProgram.net()`` builds the net: the planning level is one sequential process, each
  arm's trajectory level takes its queue in order, each EFT has the thesis's places.
* ``check(plan, *arms)``: record, analyse, raise ``rccl.events.Deadlock`` (or
  ``EventError`` for an unreachable motion) before anything moves.

What the net assumes (as the thesis's does): flags once set are never reset to NULL, a
setting is seen by the trajectory level in the order it was made, every motion that
begins ends (its own duration does not matter); motions do not fault (a FAULT or ABORTED
end, which does not start followers, is the runtime's business: ``wait_ev`` raises
``Deadlock`` then). A recorded program is straight-line: a ``plan`` that branches on
``status_ev`` or loops is recorded along the one path the recorder takes (``status_ev``
returns NULL while recording), so give it a straight-line description or build a ``Net``
by hand (channels, loops: see ``queue_net``).

Why this module is long: one analysis, end to end: the net (places, transitions,
markings), the coverability tree that decides boundedness, the reachability graph with its
firing sequences, and the recorder that turns a planning function's flag calls into a
net; each part is read with the others.
"""
from __future__ import annotations

import importlib.util
import itertools
import math
import sys
from collections import deque
from dataclasses import dataclass, field
from typing import Any, Callable

from .events import START, Deadlock, EventError, check_start_code, check_stop_code

OMEGA = math.inf           # "as many tokens as you like" in a coverability marking

Marking = tuple            # token counts, one per place (OMEGA allowed in coverability markings)


class NetError(EventError):
    """A net that cannot be explored as asked (malformed, or more markings than the limit)."""


@dataclass(frozen=True)
class NetTransition:
    """One transition: ``inputs``/``outputs`` map place names to arc weights.

    ``action`` groups transitions that are one event of the modelled system (e.g. the
    variants of ``start_ev`` for a flag already set or still NULL): an action is
    unreachable when none of its transitions can fire. Defaults to ``name``.
    """

    name: str
    inputs: dict[str, int]
    outputs: dict[str, int]
    action: str = ""

    def __post_init__(self) -> None:
        if not self.action:
            object.__setattr__(self, "action", self.name)


@dataclass
class Net:
    """A place/transition net with an initial marking (``initial``: place -> tokens, absent = 0)."""

    places: list[str]
    transitions: list[NetTransition]
    initial: dict[str, int]
    is_final: Callable[[dict[str, int]], bool] | None = None    # None: the net is meant to run forever
    name: str = "net"

    def __post_init__(self) -> None:
        index = {p: i for i, p in enumerate(self.places)}
        if len(index) != len(self.places):
            raise NetError(f"{self.name}: a place is named twice")
        for t in self.transitions:
            for p, w in list(t.inputs.items()) + list(t.outputs.items()):
                if p not in index:
                    raise NetError(f"{self.name}: transition {t.name!r} has an arc to unknown place {p!r}")
                if not isinstance(w, int) or w <= 0:
                    raise NetError(f"{self.name}: transition {t.name!r}: arc weight {w!r} to {p!r} is not a positive int")
        for p in self.initial:
            if p not in index:
                raise NetError(f"{self.name}: initial marking names unknown place {p!r}")
        self._index = index
        self._pre = [tuple((index[p], w) for p, w in t.inputs.items()) for t in self.transitions]
        self._post = [tuple((index[p], w) for p, w in t.outputs.items()) for t in self.transitions]

    def marking(self, tokens: dict[str, int]) -> Marking:
        return tuple(tokens.get(p, 0) for p in self.places)

    def named(self, m: Marking) -> dict[str, int]:
        """The marked places of ``m``, by name."""
        return {p: m[i] for i, p in enumerate(self.places) if m[i]}

    def enabled(self, m: Marking) -> list[int]:
        return [k for k, pre in enumerate(self._pre) if all(m[i] >= w for i, w in pre)]

    def fire(self, m: Marking, k: int) -> Marking:
        out = list(m)
        for i, w in self._pre[k]:
            out[i] -= w
        for i, w in self._post[k]:
            out[i] += w
        return tuple(out)


@dataclass
class Finding:
    """One thing found: what, where (a marking by place name) and the firing sequence from the initial marking."""

    what: str
    marking: dict[str, Any]
    sequence: list[str]

    def __str__(self) -> str:
        seq = " -> ".join(self.sequence) if self.sequence else "(the initial marking)"
        marked = ", ".join(p if n == 1 else f"{p} x{'w' if n == OMEGA else n}" for p, n in self.marking.items())
        return f"{self.what}\n    reached by: {seq}\n    marking: {{{marked}}}"


@dataclass
class Analysis:
    """What ``analyse`` found. ``ok`` = bounded, no deadlock, no livelock, every action can fire."""

    net: Net
    bounded: bool
    bound: int | float                      # the most tokens any place holds (OMEGA if unbounded)
    markings: int                           # reachable markings (coverability nodes if unbounded)
    final: list[dict[str, int]]             # the dead markings that are proper ends
    unbounded: list[Finding] = field(default_factory=list)
    deadlocks: list[Finding] = field(default_factory=list)
    livelocks: list[Finding] = field(default_factory=list)
    unreachable: list[str] = field(default_factory=list)       # actions that can never fire
    not_live: list[Finding] = field(default_factory=list)      # (nets that run forever) an action lost for good

    @property
    def safe(self) -> bool:
        """1-bounded: no place ever holds more than one token (the thesis's flags are booleans)."""
        return self.bounded and self.bound <= 1

    @property
    def ok(self) -> bool:
        return self.bounded and not (self.deadlocks or self.livelocks or self.unreachable or self.not_live)

    @property
    def live(self) -> bool:
        """A net that runs forever: every action can fire again from every reachable marking (L4).
        A net that ends (``is_final``): every action can fire in some run and every run ends properly
        (the thesis's "the motion is guaranteed to complete")."""
        return self.ok

    def report(self) -> str:
        lines = [f"{self.net.name}: {len(self.net.places)} places, {len(self.net.transitions)} transitions, "
                 f"{self.markings} {'reachable markings' if self.bounded else 'coverability nodes'}; "
                 + (f"bounded ({self.bound} token(s) at most{', safe' if self.safe else ''})" if self.bounded
                    else "UNBOUNDED")]
        for f in self.unbounded:
            lines.append(f"  unbounded: {f}")
        for f in self.deadlocks:
            lines.append(f"  deadlock: {f}")
        for f in self.livelocks:
            lines.append(f"  livelock: {f}")
        for a in self.unreachable:
            lines.append(f"  unreachable: {a} can never happen")
        for f in self.not_live:
            lines.append(f"  not live: {f}")
        if self.bounded and self.net.is_final is None:
            lines.append("  runs forever; " + ("live: every action can always fire again" if self.live else "NOT live"))
        elif self.bounded:
            lines.append(f"  {len(self.final)} final marking(s)"
                         + ("; every run ends in one" if not (self.deadlocks or self.livelocks) else ""))
        return "\n".join(lines)


def _path(parent: dict, node, label: Callable[[int], str]) -> list[str]:
    seq = []
    while parent[node] is not None:
        node, k = parent[node]
        seq.append(label(k))
    return seq[::-1]


def analyse(net: Net, *, limit: int = 200_000) -> Analysis:
    """Explore ``net`` from its initial marking; at most ``limit`` markings (``NetError`` beyond)."""
    label = lambda k: net.transitions[k].name           # noqa: E731
    m0 = net.marking(net.initial)

    # 1. Karp-Miller coverability tree (duplicates pruned): unbounded places, transitions that can fire
    nodes: list[tuple[Marking, int | None, int | None]] = [(m0, None, None)]   # marking, parent node, transition
    seen = {m0}
    fired: set[int] = set()
    omega_at: dict[int, int] = {}                                            # place -> first node with OMEGA
    todo = deque([0])
    while todo:
        n = todo.popleft()
        m = nodes[n][0]
        for k in net.enabled(m):
            fired.add(k)
            new = list(net.fire(m, k))
            a = n
            while a is not None:                                             # accelerate over ancestors
                am = nodes[a][0]
                if all(x <= y for x, y in zip(am, new)) and tuple(am) != tuple(new):
                    for i, (x, y) in enumerate(zip(am, new)):
                        if x < y:
                            new[i] = OMEGA
                a = nodes[a][1]
            new = tuple(new)
            if new in seen:
                continue
            if len(nodes) >= limit:
                raise NetError(f"{net.name}: more than {limit} coverability nodes; raise limit= or simplify the net")
            seen.add(new)
            nodes.append((new, n, k))
            for i, x in enumerate(new):
                if x == OMEGA and i not in omega_at:
                    omega_at[i] = len(nodes) - 1
            todo.append(len(nodes) - 1)

    def node_path(n: int) -> list[str]:
        seq = []
        while nodes[n][1] is not None:
            seq.append(label(nodes[n][2]))
            n = nodes[n][1]
        return seq[::-1]

    unreachable = sorted({t.action for t in net.transitions}
                         - {net.transitions[k].action for k in fired})
    if omega_at:
        unb = [Finding(f"place {net.places[i]!r} can hold any number of tokens", net.named(nodes[n][0]), node_path(n))
               for i, n in sorted(omega_at.items(), key=lambda x: x[1])]
        return Analysis(net, False, OMEGA, len(nodes), [], unbounded=unb, unreachable=unreachable)

    # 2. bounded: the reachability graph (breadth first, so each sequence found is a shortest one)
    parent: dict[Marking, tuple[Marking, int] | None] = {m0: None}
    succ: dict[Marking, list[Marking]] = {}
    order = [m0]
    todo = deque([m0])
    while todo:
        m = todo.popleft()
        succ[m] = []
        for k in net.enabled(m):
            m2 = net.fire(m, k)
            succ[m].append(m2)
            if m2 not in parent:
                if len(parent) >= limit:
                    raise NetError(f"{net.name}: more than {limit} reachable markings; raise limit= or simplify the net")
                parent[m2] = (m, k)
                order.append(m2)
                todo.append(m2)
    bound = max((max(m) if m else 0) for m in order)
    is_final = net.is_final or (lambda m: False)
    final = [m for m in order if not succ[m] and is_final(net.named(m))]
    deadlocks = [Finding("no transition can fire and this is not a proper end", net.named(m), _path(parent, m, label))
                 for m in order if not succ[m] and not is_final(net.named(m))]
    pred: dict[Marking, list[Marking]] = {m: [] for m in order}
    for m, outs in succ.items():
        for m2 in outs:
            pred[m2].append(m)
    if net.is_final is None:
        not_live = [] if deadlocks else _lost_actions(net, order, pred, parent, label)
        return Analysis(net, True, bound, len(order), [], deadlocks=deadlocks, unreachable=unreachable,
                        not_live=not_live)
    # markings from which no final marking is reachable, other than the deadlocks themselves
    can_end = set(final)
    stack = list(final)
    while stack:
        for p in pred[stack.pop()]:
            if p not in can_end:
                can_end.add(p)
                stack.append(p)
    dead_set = {m for m in order if not succ[m]}
    stuck = [m for m in order if m not in can_end and m not in dead_set]
    # report only the first stuck marking of each run into trouble (its predecessors can still end)
    livelocks = [Finding("no proper end can be reached from here (the net cycles or runs into a deadlock)",
                         net.named(m), _path(parent, m, label))
                 for m in stuck if parent[m] is None or parent[m][0] in can_end]
    if deadlocks:        # a marking that can only run into a reported deadlock is that deadlock, not a livelock
        livelocks = [f for f in livelocks if _cycles_from(net, f.marking, succ)]
    return Analysis(net, True, bound, len(order), [net.named(m) for m in final],
                    deadlocks=deadlocks, livelocks=livelocks, unreachable=unreachable)


def _backward(start: list, pred: dict) -> set:
    """Every marking from which one of ``start`` can be reached."""
    out = set(start)
    stack = list(start)
    while stack:
        for p in pred[stack.pop()]:
            if p not in out:
                out.add(p)
                stack.append(p)
    return out


def _lost_actions(net: Net, order: list, pred: dict, parent: dict, label: Callable) -> list[Finding]:
    """For a net that runs forever: the first marking (breadth-first) after which an action never fires again."""
    out = []
    for action in sorted({t.action for t in net.transitions}):
        ks = [k for k, t in enumerate(net.transitions) if t.action == action]
        can = _backward([m for m in order if any(k in net.enabled(m) for k in ks)], pred)
        lost = next((m for m in order if m not in can), None)
        if lost is not None and len(can):
            out.append(Finding(f"{action!r} can never fire again", net.named(lost), _path(parent, lost, label)))
    return out


def _cycles_from(net: Net, marking: dict[str, int], succ: dict) -> bool:
    """True when a cycle is reachable from ``marking`` (so the trouble there is not only a deadlock)."""
    start = net.marking(marking)
    colour: dict = {}
    stack = [(start, iter(succ[start]))]
    colour[start] = 1
    while stack:
        m, it = stack[-1]
        nxt = next(it, None)
        if nxt is None:
            colour[m] = 2
            stack.pop()
        elif colour.get(nxt) == 1:
            return True
        elif nxt not in colour:
            colour[nxt] = 1
            stack.append((nxt, iter(succ[nxt])))
    return False


# --- the thesis's net (Figure 5.6) ------------------------------------------------------------------
THESIS_PLACES = {
    "p1": "start flag set", "p2": "stop flag set", "p3": "motion pending", "p4": "motion active",
    "p5": "motion completed", "p6": "status = start code", "p7": "status = stop code",
    "p1'": "start flag NULL", "p2'": "stop flag NULL",
}


def thesis_net() -> Net:
    """The three-flag protocol of one EFT (Figure 5.6), flags set by anyone in any order.

    p1..p7 are the thesis's places. The figure itself is lost in the OCR; the net is rebuilt
    from the prose: "tokens may appear in [p1, p2] but not disappear" (rule 5) and a flag is
    set once as far as the protocol can tell (setting it again to another non-NULL code
    changes nothing), so each flag has a complement place (p1', p2' = still NULL) that its
    setting consumes; the complement also gives rule 3 (stop before start deletes the
    motion) its test: the motion begins only while p2' holds.
    """
    t = [
        NetTransition("set start", {"p1'": 1}, {"p1": 1}),
        NetTransition("set stop", {"p2'": 1}, {"p2": 1}),
        NetTransition("begin (rule 1)", {"p1": 1, "p2'": 1, "p3": 1}, {"p1": 1, "p2'": 1, "p4": 1, "p6": 1}),
        NetTransition("natural end: default stop code (rule 2)", {"p4": 1, "p6": 1, "p2'": 1}, {"p5": 1, "p7": 1, "p2": 1}),
        NetTransition("stopped (rule 2)", {"p4": 1, "p6": 1, "p2": 1}, {"p5": 1, "p7": 1, "p2": 1}),
        NetTransition("deleted: stop before start (rule 3)", {"p3": 1, "p2": 1}, {"p5": 1, "p7": 1, "p2": 1}),
    ]
    return Net(list(THESIS_PLACES), t, {"p1'": 1, "p2'": 1, "p3": 1},
               is_final=lambda m: m.get("p5", 0) == 1 and m.get("p7", 0) == 1, name="thesis Figure 5.6")


def queue_net(slots: int | None) -> Net:
    """The one-way queue between two tasks of thesis Figure 2.8: ``slots`` free places, or None for
    a queue without them (the producer never waits: the queue place is unbounded)."""
    t = [NetTransition("producer puts an item", {"producer ready": 1} | ({"free slots": 1} if slots else {}),
                    {"producer ready": 1, "items": 1}),
         NetTransition("consumer takes an item", {"consumer ready": 1, "items": 1},
                    {"consumer ready": 1} | ({"free slots": 1} if slots else {}))]
    places = ["producer ready", "consumer ready", "items"] + (["free slots"] if slots else [])
    init = {"producer ready": 1, "consumer ready": 1} | ({"free slots": slots} if slots else {})
    return Net(places, t, init, name=f"queue (Figure 2.8), {slots or 'no'} free slots")


def token_passing_net() -> Net:
    """Thesis Figure 2.7: two tasks pass one token to take turns at shared data."""
    t = [NetTransition("task 1 takes the data", {"token at 1": 1}, {"1 in data": 1}),
         NetTransition("task 1 passes the token", {"1 in data": 1}, {"token at 2": 1}),
         NetTransition("task 2 takes the data", {"token at 2": 1}, {"2 in data": 1}),
         NetTransition("task 2 passes the token", {"2 in data": 1}, {"token at 1": 1})]
    return Net(["token at 1", "1 in data", "token at 2", "2 in data"], t, {"token at 1": 1},
               name="token passing (Figure 2.7)")


# --- a program's flag triples -------------------------------------------------------------------------
@dataclass(eq=False)
class RecordedEFT:
    """A flag triple as the recorder saw it: which arm, where to, how its start flag is set."""

    serial: int
    arm: str
    where: str
    plain: bool = False               # a plain move(): no EFT, starts when ready

    def describe(self) -> str:
        kind = "plain motion" if self.plain else "motion"
        return f"{kind} #{self.serial} of arm {self.arm!r} to {self.where}"

    def __repr__(self) -> str:
        return f"RecordedEFT({self.describe()})"


@dataclass
class Statement:
    kind: str                                      # move_ev, start_ev, stop_ev, wait_ev, start_after, free_ev
    efts: tuple[RecordedEFT, ...]
    code: int | None = None
    source: RecordedEFT | None = None              # move_ev(start=source) / start_after(target, source)
    started: bool = False

    def describe(self) -> str:
        names = ", ".join(f"#{e.serial}" for e in self.efts)
        if self.kind in ("move_ev", "move"):
            e = self.efts[0]
            how = (f", start after #{self.source.serial}" if self.source is not None
                   else (", start postponed" if self.code is None else ""))
            return f"{self.kind}({e.arm} to {e.where}{how}) -> #{e.serial}"
        if self.kind == "start_after":
            return f"start_after(#{self.efts[0].serial}, #{self.source.serial})"
        if self.kind == "wait_ev":
            return f"wait_ev({names}{', started=True' if self.started else ''})"
        if self.kind in ("start_ev", "stop_ev"):
            return f"{self.kind}({self.code}, {names})"
        return f"{self.kind}({names})"


def _arm_name(arm: Any) -> str:
    if isinstance(arm, str):
        return arm
    return getattr(arm, "name", None) or getattr(arm, "robot", None) or repr(arm)


class FlagProgram:
    """Records a planning level's event-flag calls: the recording form of ``rccl.event_flags.EventFlags``
    (same names, arguments and code rules as ``rccl.events``).

    Arms may be names (``"puma"``) or any object (its ``name`` or ``robot`` names it);
    positions may be names or anything with a ``name``.
    """

    def __init__(self, name: str = "program") -> None:
        self.name = name
        self.statements: list[Statement] = []
        self.efts: list[RecordedEFT] = []
        self._names: dict[int, str] = {}

    # the primitives ---------------------------------------------------------------------------
    def attach(self, arm: Any, name: str | None = None) -> str:
        n = name or _arm_name(arm)
        self._names[id(arm)] = n
        return n

    def _arm(self, arm: Any) -> str:
        return self._names.get(id(arm)) or _arm_name(arm)

    def _new(self, arm: Any, position: Any, plain: bool) -> RecordedEFT:
        where = position if isinstance(position, str) else getattr(position, "name", repr(position))
        e = RecordedEFT(len(self.efts) + 1, self._arm(arm), str(where), plain)
        self.efts.append(e)
        return e

    def _own(self, e: Any, where: str) -> RecordedEFT:
        if not isinstance(e, RecordedEFT) or e not in self.efts:
            raise EventError(f"{self.name}: {where}: {e!r} is not an EFT this program's move_ev returned")
        return e

    def move_ev(self, arm: Any, position: Any, *, start: int | RecordedEFT | None = START,
                after_code: int = START) -> RecordedEFT:
        source = self._own(start, "move_ev(start=...)") if isinstance(start, RecordedEFT) else None
        if source is not None:
            check_start_code(after_code, "move_ev(after_code=...)")
        elif start is not None:
            check_start_code(start, "move_ev(start=...)")
        e = self._new(arm, position, plain=False)
        self.statements.append(Statement("move_ev", (e,), None if start is None or source else start, source))
        return e

    def move(self, arm: Any, position: Any) -> None:
        """A plain ``arm.move(position)``: queued, starts when ready, no flags to wait on."""
        e = self._new(arm, position, plain=True)
        self.statements.append(Statement("move", (e,), START))

    def start_after(self, target: RecordedEFT, source: RecordedEFT, code: int = START) -> None:
        check_start_code(code, "start_after(code)")
        self.statements.append(Statement("start_after", (self._own(target, "start_after(target)"),), code,
                                         self._own(source, "start_after(source)")))

    def start_ev(self, code: int, *efts: RecordedEFT) -> None:
        check_start_code(code, "start_ev")
        self.statements.append(Statement("start_ev", tuple(self._own(e, "start_ev") for e in efts), code))

    def stop_ev(self, code: int, *efts: RecordedEFT) -> None:
        check_stop_code(code, "stop_ev")
        self.statements.append(Statement("stop_ev", tuple(self._own(e, "stop_ev") for e in efts), code))

    def wait_ev(self, eft: RecordedEFT, *, started: bool = False, timeout: float | None = None,
                poll: float = 0.02) -> int:
        self.statements.append(Statement("wait_ev", (self._own(eft, "wait_ev"),), started=started))
        return START if started else -1

    def status_ev(self, eft: RecordedEFT) -> int:
        self._own(eft, "status_ev")
        return 0

    def free_ev(self, *efts: RecordedEFT) -> None:
        self.statements.append(Statement("free_ev", tuple(self._own(e, "free_ev") for e in efts)))

    def stop_abort(self, arm: Any) -> None:
        raise EventError(f"{self.name}: stop_abort is not modelled by the static check (its ABORTED ends start "
                         "no followers); check the program without it")

    # the net ----------------------------------------------------------------------------------
    def net(self) -> Net:
        return _program_net(self)


def _flag_variants(flags: list[tuple[str, str]]) -> list[tuple[dict, dict]]:
    """Setting several flags at once: one (inputs, outputs) per combination of each flag being NULL
    (its NULL place is consumed, its set place marked) or already set (read: consumed and put back)."""
    out = []
    for choice in itertools.product((0, 1), repeat=len(flags)):
        ins: dict[str, int] = {}
        outs: dict[str, int] = {}
        for (null, setp), already in zip(flags, choice):
            if already:
                ins[setp] = 1
            else:
                ins[null] = 1
            outs[setp] = 1
        out.append((ins, outs))
    return out


def _merge(*ds: dict) -> dict:
    out: dict[str, int] = {}
    for d in ds:
        for k, v in d.items():
            out[k] = max(out.get(k, 0), v)    # a read arc and a consumption of the same place are one arc
    return out


def _program_net(prog: FlagProgram) -> Net:
    places: list[str] = []
    trans: list[NetTransition] = []
    init: dict[str, int] = {}

    def P(e: RecordedEFT, what: str) -> str:
        return f"#{e.serial}.{what}"

    for e in prog.efts:
        places += [P(e, w) for w in ("start NULL", "start set", "stop NULL", "stop set",
                                     "pending", "active", "completed", "status start", "status stop")]
        init[P(e, "start NULL")] = 1
        init[P(e, "stop NULL")] = 1
    n = len(prog.statements)
    places += [f"planning at {k}" for k in range(n + 1)]
    init["planning at 0"] = 1

    # who may start whom (move_ev(start=src) / start_after): a registration place per pair
    followers: dict[int, list[RecordedEFT]] = {}
    for s in prog.statements:
        if s.source is not None:
            tgt = s.efts[0]
            followers.setdefault(s.source.serial, []).append(tgt)
            places += [f"#{tgt.serial} after #{s.source.serial}", f"#{tgt.serial} not yet after #{s.source.serial}"]
            init[f"#{tgt.serial} not yet after #{s.source.serial}"] = 1
    stopped = {e.serial for s in prog.statements if s.kind == "stop_ev" for e in s.efts}

    # the planning level: one transition (or several variants) per statement
    for k, s in enumerate(prog.statements):
        here, nxt = {f"planning at {k}": 1}, {f"planning at {k + 1}": 1}
        act = f"planning: {s.describe()}"
        if s.kind in ("move_ev", "move"):
            e = s.efts[0]
            base_in, base_out = here, nxt | {P(e, "pending"): 1}
            if s.code is not None:
                base_in, base_out = base_in | {P(e, "start NULL"): 1}, base_out | {P(e, "start set"): 1}
            if s.source is None:
                trans.append(NetTransition(act, base_in, base_out))
            else:
                trans += _register(e, s.source, s.code, base_in, base_out, act, P)
        elif s.kind == "start_after":
            trans += _register(s.efts[0], s.source, s.code, here, nxt, act, P)
        elif s.kind in ("start_ev", "stop_ev"):
            w = "start" if s.kind == "start_ev" else "stop"
            for i, (ins, outs) in enumerate(_flag_variants([(P(e, f"{w} NULL"), P(e, f"{w} set")) for e in s.efts])):
                trans.append(NetTransition(f"{act} [variant {i}]", here | ins, nxt | outs, act))
        elif s.kind == "wait_ev":
            e = s.efts[0]
            for st in (("active", "completed") if s.started else ("completed",)):
                trans.append(NetTransition(f"{act} [{st}]", here | {P(e, st): 1}, nxt | {P(e, st): 1}, act))
        elif s.kind == "free_ev":
            done = {P(e, "completed"): 1 for e in s.efts}
            trans.append(NetTransition(act, here | done, nxt | done))

    # each arm's trajectory level: its queue in order; a motion begins (or is deleted) once the one before it ended
    prev: dict[str, RecordedEFT] = {}
    for e in prog.efts:
        before = {P(prev[e.arm], "completed"): 1} if e.arm in prev else {}
        prev[e.arm] = e
        who = f"{e.arm}: #{e.serial} to {e.where}"
        trans.append(NetTransition(f"{who} begins (rule 1)",
                                _merge(before, {P(e, "start set"): 1, P(e, "stop NULL"): 1, P(e, "pending"): 1}),
                                _merge(before, {P(e, "start set"): 1, P(e, "stop NULL"): 1, P(e, "active"): 1,
                                                P(e, "status start"): 1})))
        ends = [("ends naturally (rule 2)", {P(e, "active"): 1, P(e, "status start"): 1, P(e, "stop NULL"): 1})]
        if e.serial in stopped:
            ends += [("is stopped (rule 2)", {P(e, "active"): 1, P(e, "status start"): 1, P(e, "stop set"): 1}),
                     ("is deleted: stop before start (rule 3)",
                      _merge(before, {P(e, "pending"): 1, P(e, "stop set"): 1}))]
        fol = followers.get(e.serial, [])
        for how, ins in ends:
            base_out = {P(e, "completed"): 1, P(e, "status stop"): 1, P(e, "stop set"): 1}
            if "deleted" in how:
                base_out = _merge(before, base_out)
            for combo in itertools.product((0, 1, 2), repeat=len(fol)):
                fi, fo = {}, {}
                for f, c in zip(fol, combo):
                    reg, unreg = f"#{f.serial} after #{e.serial}", f"#{f.serial} not yet after #{e.serial}"
                    if c == 0:                       # not registered yet: nothing to start
                        fi[unreg] = fo[unreg] = 1
                    elif c == 1:                     # registered, start NULL: set it
                        fi |= {reg: 1, P(f, "start NULL"): 1}
                        fo |= {reg: 1, P(f, "start set"): 1}
                    else:                            # registered, already started by someone else
                        fi |= {reg: 1, P(f, "start set"): 1}
                        fo |= {reg: 1, P(f, "start set"): 1}
                suffix = f" [followers {combo}]" if fol else ""
                trans.append(NetTransition(f"{who} {how}{suffix}", _merge(ins, fi), _merge(base_out, fo), f"{who} ends"))

    def final(m: dict[str, int]) -> bool:
        return m.get(f"planning at {n}", 0) == 1 and all(m.get(P(e, "completed"), 0) == 1 for e in prog.efts)

    return Net(places, trans, init, is_final=final, name=prog.name)


def _register(tgt: RecordedEFT, src: RecordedEFT, code: int | None, base_in: dict, base_out: dict,
              act: str, P: Callable) -> list[NetTransition]:
    """The statement that makes ``tgt`` start when ``src`` ends: if ``src`` already ended, its start flag
    is set now (when still NULL), else the pair is registered for ``src``'s end."""
    reg, unreg = f"#{tgt.serial} after #{src.serial}", f"#{tgt.serial} not yet after #{src.serial}"
    out = []
    for st in ("pending", "active"):
        out.append(NetTransition(f"{act} [#{src.serial} {st}]", base_in | {unreg: 1, P(src, st): 1},
                              base_out | {reg: 1, P(src, st): 1}, act))
    done = {P(src, "completed"): 1}
    out.append(NetTransition(f"{act} [#{src.serial} ended, start set now]",
                          base_in | done | {unreg: 1, P(tgt, "start NULL"): 1},
                          base_out | done | {reg: 1, P(tgt, "start set"): 1}, act))
    out.append(NetTransition(f"{act} [#{src.serial} ended, start already set]",
                          base_in | done | {unreg: 1, P(tgt, "start set"): 1},
                          base_out | done | {reg: 1, P(tgt, "start set"): 1}, act))
    return out


def record(plan: Callable[..., Any], *arms: Any, name: str | None = None, **kwargs: Any) -> FlagProgram:
    """Run ``plan(events, *arms, **kwargs)`` against a recorder (nothing moves); return the recorded program."""
    prog = FlagProgram(name or getattr(plan, "__name__", "program"))
    plan(prog, *arms, **kwargs)
    return prog


def check(plan: Callable[..., Any] | FlagProgram, *arms: Any, **kwargs: Any) -> Analysis:
    """The static check before a program runs: record ``plan``, analyse its net, raise on trouble.

    Raises ``rccl.events.Deadlock`` (a deadlock or livelock, with its firing sequence) or
    ``EventError`` (a motion or statement that can never happen); returns the ``Analysis``.
    """
    prog = plan if isinstance(plan, FlagProgram) else record(plan, *arms, **kwargs)
    a = analyse(prog.net())
    if a.deadlocks or a.livelocks:
        raise Deadlock(f"{prog.name}: the event flags can deadlock before the program ends:\n{a.report()}")
    if a.unreachable:
        raise EventError(f"{prog.name}: part of the program can never happen:\n{a.report()}")
    return a


def _cli(argv: list[str] | None = None) -> int:
    import argparse
    ap = argparse.ArgumentParser(prog="python -m rccl.petri",
                                 description="Check a planning function's event flags with a Petri net (thesis 5.6.3) "
                                             "before it runs; with no target, analyse the thesis's net (Figure 5.6).")
    ap.add_argument("target", nargs="?", help="FILE.py:FUNCTION, a function plan(events, *arms)")
    ap.add_argument("arms", nargs="*", help="arm names passed to the function")
    a = ap.parse_args(argv)
    if a.target is None:
        res = analyse(thesis_net())
        print(res.report())
        return 0 if res.ok and res.safe else 1
    path, _, fn = a.target.rpartition(":")
    if not path or not fn:
        ap.error(f"target {a.target!r}: give FILE.py:FUNCTION")
    spec = importlib.util.spec_from_file_location("_petri_target", path)
    if spec is None or spec.loader is None:
        ap.error(f"target {a.target!r}: {path} is not a Python file")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    plan = getattr(mod, fn, None)
    if plan is None:
        ap.error(f"target {a.target!r}: {path} has no function {fn!r}")
    res = analyse(record(plan, *a.arms).net())
    print(res.report())
    return 0 if res.ok else 1


if __name__ == "__main__":
    sys.exit(_cli())
