"""Multi-robot RCI (thesis 2.4): one planning level, one control task per arm, shared data and channels.

A ``Workcell`` drives several arms, each an ordinary ``rci.Session`` on its own link to its
own robot or ``simula`` process (thesis 2.4.4.1: each processor has its own robot; each
control task is one user function driven by its own interrupt, here the arm's HOW). The
planning level is the user's program, as in single-robot RCI.

Thesis -> Python:

* ``RCIload(image, processor_id)``   -> ``Workcell({"puma": (url, "puma260"), ...}).open()``
* ``RCIcontrol(event_id, function)`` -> ``cell.control(puma=f, microbo=(f1, f2))``
* ``RCIrelease(event_id)``           -> ``cell.release("puma")`` or ``cell.release()`` (all)
* multi-robot RCCL on this (5.6.2)     -> ``Workcell({"puma": arm.rci, ...})``, ``cell.start(arm.open, ...)``
* shared memory (c1, c2, t1)          -> ``cell.shared`` (``Shared``: latest value per name)
* channels (t2, t3)                   -> ``cell.channel(sender, receiver, capacity, overflow)``
* ``send(receiver_id, buf, size)``    -> ``cell.send(receiver, message)``
* ``receive(sender_id, buf, size)``   -> ``cell.receive(sender=None)`` -> ``(sender, message)`` or None
* signals from control tasks          -> ``cell.on_error`` gets an ``ArmTermination`` naming the arm

Sample synchronisation (``sync=``):

* ``"free"``: each arm's task runs on its own robot's clock, at its own rate; data in
  ``shared`` and the channels is visible to the others as soon as it is written (t1
  semantics: a reader sees the latest complete value, never a half-written one).
* ``"lockstep"``: the tasks meet at a barrier at the start of every *sync sample*, one
  period of ``gcd(rates)`` (arms at 72 and 36 Hz meet every 2nd and every cycle). Writes
  to ``shared`` and sends on channels made between two barriers become visible to
  everyone at the next barrier, so arm A's function in sample n sees arm B's data of
  sample n - 1 whatever the thread timing: runs against lockstep simulas are then
  deterministic. Against real-time robots with separate clocks the barrier wait counts
  toward the cycle (it can cause overruns); use it with lockstep simulas or robots
  sharing a clock.

An error on any arm (a range check, a dead link, an exception in its function) ends that
arm's control with its own implicit release (A.5), then releases every other arm at once
(stop, power kept: they are healthy), and tells the planning level with the arm's name.
"""
from __future__ import annotations

import itertools
import math
import sys
import threading
import time
from typing import Any, Callable, Iterable

from . import codes
from .exceptions import NoControl, NotOpen, RCIError
from .lifecycle import Delivery, Lifecycle
from .realtime import GCControl, RealtimeSettings, RealtimeStatus, lock_memory, unlock_memory
from .session import Session
from .workcell_data import Channel, ChannelFull, MultiError, Shared
from .workcell_errors import ArmTerminated, ArmTermination, SyncTimeout

__all__ = ["Workcell", "open", "describe", "PLANNING", "ArmTermination", "ArmTerminated", "SyncTimeout", "MultiError",
           "ChannelFull", "Shared", "Channel"]   # live in rci.workcell_data and rci.workcell_errors

PLANNING = "planning"      # the planning level's name as a sender/receiver
SYNC_MODES = ("free", "lockstep")


# --- copying what crosses between tasks ----------------------------------------------
ArmSpec = Session | tuple[str, str] | str


class Workcell:
    """Several arms, one control task each, one planning level (thesis 2.4; Figure 2.10).

    ``arms`` maps a name to a ``(url, robot)`` pair or an unopened ``rci.Session``. A layer
    above may open and control the sessions itself (RCCL: ``Workcell({"puma": arm.rci, ...})``,
    then ``cell.start(arm.open, ...)``, then ``with cell:``): the workcell still names the arm
    in errors, releases the others, and in lockstep puts its barrier around their functions.
    ``sync`` is ``"free"`` or ``"lockstep"`` (module docstring); ``sync_timeout`` (s) how long
    an arm waits at a lockstep barrier for the others (default 1 s against lockstep
    simulas, else two periods of the slowest arm). ``on_error``: None (print and exit 1),
    ``"raise"`` (``ArmTerminated`` in the main thread) or a callable taking an
    ``ArmTermination``. Other keyword arguments go to every ``rci.Session`` (``rate_hz=``,
    ``limits=``, ...); ``rates={"microbo": 18}`` sets one arm's rate.
    """

    def __init__(self, arms: dict[str, ArmSpec], *, sync: str = "free", sync_timeout: float | None = None,
                 on_error: Callable[[ArmTermination], Any] | str | None = None,
                 on_interrupt: Callable[[], Any] | None = None, rates: dict[str, int] | None = None,
                 signals: bool = True, **session_options: Any) -> None:
        if not arms:
            raise MultiError("Workcell: no arms given")
        if sync not in SYNC_MODES:
            raise MultiError(f"Workcell: sync must be one of {SYNC_MODES}, not {sync!r}")
        if PLANNING in arms:
            raise MultiError(f"Workcell: {PLANNING!r} is the planning level's name; choose another arm name")
        unknown = set(rates or {}) - set(arms)
        if unknown:
            raise MultiError(f"Workcell: rates given for unknown arms {sorted(unknown)}; arms are {sorted(arms)}")
        self.sync = sync
        self.sync_timeout = sync_timeout
        self.on_error = on_error
        self.on_interrupt = on_interrupt
        self.lifecycle = Lifecycle(self, signals=signals, interrupt_text="interrupt (every arm released, power off)")
        # process-wide real-time settings are the workcell's, once for all arms: one arm's task
        # starting (gc.collect() of the whole heap) or ending (unfreeze, switch interval back)
        # must not stall or unprotect another arm's running control
        rt = RealtimeSettings(gc=session_options.pop("gc", "freeze"),
                              switch_interval=session_options.pop("switch_interval", 2e-4))
        self._gc = GCControl(rt.gc)
        self._switch_interval = rt.switch_interval
        self._saved_interval: float | None = None
        self._gc_applied = False
        self._rt_lock = threading.Lock()
        self.sessions: dict[str, Session] = {}
        for name, spec in arms.items():
            self.sessions[name] = self._make_session(name, spec, (rates or {}).get(name), session_options)
        deferred = sync == "lockstep"
        self.shared = Shared(deferred=deferred)
        self.channels: dict[tuple[str, str], Channel] = {}
        self.terminations: list[ArmTermination] = []          # every arm error, in order
        self.sample = 0                                       # lockstep: sync samples completed
        self.rt_status = RealtimeStatus()
        self._lock = self.lifecycle.lock
        self._barrier: threading.Barrier | None = None
        self._armed: set[str] = set()
        self._arrived: dict[str, int] = {}
        self._threads: dict[int, str] = {}
        self._stamp = itertools.count()

    @property
    def termination(self) -> ArmTermination | None:
        """The first arm error of the control in progress or of the last one (None: none)."""
        return self.lifecycle.termination

    @property
    def in_control(self) -> bool:
        """True while any arm of the workcell is under control."""
        return any(s.in_control for s in self.sessions.values())

    def _make_session(self, name: str, spec: ArmSpec, rate: int | None, options: dict) -> Session:
        if isinstance(spec, Session):
            if spec.is_open:
                raise MultiError(f"arm {name!r}: give the Workcell an unopened Session (it opens it)")
            s = spec
            # the workcell owns the signals and the process-wide settings (see __init__)
            s.configure(signals=False, gc="leave", switch_interval=None)
        else:
            url, robot = (spec, "puma260") if isinstance(spec, str) else spec
            opts = dict(options)
            if rate is not None:
                opts["rate_hz"] = rate
            opts["signals"] = False          # the workcell owns the signals: one handler for every arm
            opts["lock_memory"] = False      # mlockall is process-wide: the workcell takes it once
            opts["gc"], opts["switch_interval"] = "leave", None
            s = Session(url, robot, **opts)
        s.on_error = lambda _t, _name=name: self._deliver()
        s.termination_listeners.append(lambda t, _name=name: self._arm_terminated(_name, t))
        # whoever starts the control (cell.control, or RCCL's Arm.open under cell.start), the
        # functions pass through the workcell: thread registration, and the lockstep barrier
        s.control_wrapper = lambda f1, f2, _name=name: self._wrap(_name, f1, f2)
        return s

    # --- access -----------------------------------------------------------------------
    def __getitem__(self, name: str) -> Session:
        try:
            return self.sessions[name]
        except KeyError:
            raise MultiError(f"no arm {name!r} in this workcell; arms are {sorted(self.sessions)}") from None

    @property
    def arms(self) -> list[str]:
        return list(self.sessions)

    def current_task(self) -> str:
        """The name of the task running this code: an arm name in its control task, else "planning"."""
        return self._threads.get(threading.get_ident(), PLANNING)

    def _in_control_thread(self) -> bool:
        return threading.get_ident() in self._threads

    # --- RCIload / open ---------------------------------------------------------------
    def open(self) -> "Workcell":
        """Open every arm's link (HELLO/WELCOME); on any failure close the ones already open."""
        with self._primitive():
            done: list[Session] = []
            try:
                for s in self.sessions.values():
                    s.open()
                    done.append(s)
            except BaseException as e:
                for s in done:
                    s.close_quietly(power_off=False)
                name = next(n for n, s in self.sessions.items() if s not in done)
                if isinstance(e, RCIError):
                    try:       # the same error type, its message naming the arm
                        named = type(e)(f"arm {name!r}: {e}")
                    except TypeError:
                        named = None
                    if named is not None:
                        raise named from e
                    e.add_note(f"while opening arm {name!r}")
                raise
            lock_memory(self.rt_status)
            self.lifecycle.install_signals()
            return self

    # --- RCIcontrol ---------------------------------------------------------------------
    def control(self, **functions: Callable[[], Any] | tuple | None) -> None:
        """Start control on the named arms: ``control(puma=f, microbo=(f1, f2))``.

        A single function runs as f2 (after ``chg`` is sent, as ``RCIcontrol(dummy, f)``); a
        pair is (f1, f2). Functions take no arguments (closures share memory). In lockstep
        every arm of the workcell must be started in one call. Returns once every arm ran
        its first cycle.
        """
        with self._primitive():
            if not functions:
                raise MultiError("control(): name at least one arm, e.g. control(puma=f)")
            for name in functions:
                self[name]
            if self.sync == "lockstep":
                if set(functions) != set(self.sessions):
                    raise MultiError(f"control(): a lockstep workcell starts all its arms together "
                                     f"({sorted(self.sessions)}), got {sorted(functions)}")
                if any(s.in_control for s in self.sessions.values()):
                    raise MultiError("control(): release the workcell before starting a lockstep control again")
            self.lifecycle.reset()
            pairs = {}
            for name, fns in functions.items():
                f1, f2 = (fns if isinstance(fns, tuple) else (None, fns))
                for which, f in (("f1", f1), ("f2", f2)):
                    if f is not None and not callable(f):
                        raise MultiError(f"control(): arm {name!r}: {which} = {f!r} is not callable")
                pairs[name] = (f1, f2)
            if self.sync == "lockstep":
                self._prepare_lockstep()
            self._realtime_on()
            started: list[str] = []
            try:
                for name, (f1, f2) in pairs.items():
                    self.sessions[name].control(f1, f2)          # through _wrap (control_wrapper)
                    started.append(name)
            except BaseException:
                if self._barrier is not None:
                    self._barrier.abort()
                for n in started:
                    self._release_quietly(n)
                self._flush()
                raise

    def _prepare_lockstep(self) -> None:
        rates = {n: s.rate_hz for n, s in self.sessions.items()}
        base = math.gcd(*rates.values())
        self._every = {n: r // base for n, r in rates.items()}      # cycles per sync sample
        self._rates = rates
        self.sample = 0
        self._arrived = {n: 0 for n in self.sessions}

        def commit() -> None:
            self.shared.commit()
            for ch in list(self.channels.values()):
                ch.commit()
            self.sample += 1

        self._barrier = threading.Barrier(len(self.sessions), action=commit)
        self._armed = set(self.sessions)        # each arm's next control joins this barrier, once

    def start(self, *openers: Callable[[], Any], timeout: float = 15.0) -> None:
        """Run openers that start the arms' controls themselves, all at once (RCCL arms).

        For sessions a layer above opens and controls (``Workcell({"puma": arm.rci, ...})``):
        ``cell.start(puma.open, microbo.open)`` calls each opener in its own thread, so in
        lockstep their first samples meet at the barrier. Any failure closes every arm and
        is raised here.
        """
        with self._primitive():
            if self.sync == "lockstep":
                if any(s.in_control for s in self.sessions.values()):
                    raise MultiError("start(): release the workcell before starting a lockstep control again")
                self._prepare_lockstep()
            self.lifecycle.reset()
            self._realtime_on()
            errors: list[BaseException] = []

            def run(f: Callable[[], Any]) -> None:
                try:
                    f()
                except BaseException as e:      # re-raised in the caller's thread
                    errors.append(e)
                    if self._barrier is not None:
                        self._barrier.abort()

            threads = [threading.Thread(target=run, args=(f,), name=f"rci-multi-start-{i}", daemon=True)
                       for i, f in enumerate(openers)]
            for t in threads:
                t.start()
            deadline = time.monotonic() + timeout
            for t in threads:
                t.join(max(0.0, deadline - time.monotonic()))
            if any(t.is_alive() for t in threads):
                errors.append(MultiError(f"start(): the openers did not return within {timeout} s"))
            if errors:
                self._close_all(power_off=False)
                raise errors[0]
            self.lifecycle.install_signals()

    def _timeout(self) -> float:
        if self.sync_timeout is not None:
            return self.sync_timeout
        if all(s.lockstep for s in self.sessions.values()):
            return 1.0      # below the 2 s a lockstep session's watchdog allows a function
        return 2.0 / min(s.rate_hz for s in self.sessions.values())

    def _wrap(self, name: str, f1, f2) -> tuple:
        """The functions given to the arm's Session: register the thread; in lockstep, the barrier."""
        session = self.sessions[name]
        self._realtime_on()            # also when a layer above starts the control (RCCL's Arm.open)
        state = {"cycle": 0, "skip": False}
        threads = self._threads

        def register() -> None:
            threads[threading.get_ident()] = name

        if self.sync == "free":
            def g1() -> None:
                if state["cycle"] == 0:
                    register()
                state["cycle"] += 1
                if f1 is not None:
                    f1()
            return g1, f2

        if self._barrier is None or name not in self._armed:
            raise MultiError(f"arm {name!r}: a lockstep workcell starts its arms together, through "
                             "cell.control(...) or cell.start(...)")
        self._armed.discard(name)
        every = self._every[name]
        rate0 = self._rates[name]
        barrier = self._barrier
        timeout = self._timeout()

        def g1() -> None:
            c = state["cycle"]
            if c == 0:
                register()
            state["cycle"] = c + 1
            if session.rate_hz != rate0:
                raise MultiError(f"lockstep: arm {name!r} changed its rate from {rate0} to {session.rate_hz} Hz; "
                                 "a lockstep workcell keeps its rates")
            if c % every == 0:
                self._arrived[name] = c // every
                try:
                    barrier.wait(timeout)
                except threading.BrokenBarrierError:
                    if self.termination is not None or session.control_task is None or session.control_task.release_requested:
                        state["skip"] = True     # another arm failed or the cell is releasing: do nothing more
                        return
                    late = [n for n, k in self._arrived.items() if k < c // every]
                    raise SyncTimeout(f"lockstep: arm {name!r} waited {timeout:.3f} s at sample {c // every} for "
                                      f"{', '.join(map(repr, late)) or 'another arm'}") from None
            if f1 is not None:
                f1()

        def g2() -> None:
            if not state["skip"] and f2 is not None:
                f2()

        return g1, g2

    # --- RCIrelease / close ----------------------------------------------------------------
    def release(self, *names: str, power_off: bool = False) -> None:
        """End control on the named arms (all arms under control if none is named)."""
        with self._primitive():
            targets = list(names) or [n for n, s in self.sessions.items() if s.in_control]
            if not targets and not names:
                raise NoControl("release(): no arm of the workcell is under control")
            for n in targets:
                self[n]
            if self.sync == "lockstep" and names and set(names) != {n for n, s in self.sessions.items()
                                                                     if s.in_control}:
                raise MultiError("release(): a lockstep workcell releases all its arms together (call release())")
            asked = {}
            for n in targets:
                task = self.sessions[n].control_task
                if task is not None and not task.ended:
                    task.request_release(power_off)       # all at once, then wait for each
                    asked[n] = task
            if self._barrier is not None:
                self._barrier.abort()
            for n, task in asked.items():                 # a task may end at once: no second check
                self.sessions[n].finish_release(task)
            self._forget_threads()
            self._flush()

    def _flush(self) -> None:
        """Once no arm is under control: make deferred writes and sends visible (nothing sent is
        lost) and give back the process-wide real-time settings."""
        if not any(s.in_control for s in self.sessions.values()):
            self.shared.commit()
            for ch in list(self.channels.values()):
                ch.commit()
            self._realtime_off()

    def _realtime_on(self) -> None:
        with self._rt_lock:
            if not self._gc_applied:
                self._realtime_apply()

    def _realtime_apply(self) -> None:
        self._gc.apply(self.rt_status)
        self._gc_applied = True
        self._saved_interval = sys.getswitchinterval()
        if self._switch_interval:
            sys.setswitchinterval(self._switch_interval)
        self.rt_status.switch_interval = sys.getswitchinterval()

    def _realtime_off(self) -> None:
        with self._rt_lock:
            if not self._gc_applied:
                return
            for s in self.sessions.values():     # let finished control threads leave first
                if s.control_task is not None:
                    s.control_task.finished.wait(0.5)
            self._gc.restore()
            self._gc_applied = False
            if self._saved_interval is not None:
                sys.setswitchinterval(self._saved_interval)
                self._saved_interval = None

    def _release_quietly(self, name: str) -> None:
        try:
            s = self.sessions[name]
            if s.in_control:
                s.release()
        except Exception:
            pass

    def _forget_threads(self) -> None:
        alive = {s.control_task.ident for s in self.sessions.values() if s.control_task is not None and s.in_control}
        for ident in list(self._threads):
            if ident not in alive:
                self._threads.pop(ident, None)

    def close(self, power_off: bool = False) -> None:
        """Release every arm (power off if asked), close every link."""
        with self._primitive():
            if not any(s.is_open for s in self.sessions.values()):
                raise NotOpen("close(): the workcell is not open")
            self._close_all(power_off)

    def _close_all(self, power_off: bool) -> None:
        for s in self.sessions.values():
            task = s.control_task
            if task is not None and not task.ended:
                task.request_release(power_off)
        if self._barrier is not None:
            self._barrier.abort()
        for s in self.sessions.values():
            s.close_quietly(power_off)
        self._flush()
        if self.rt_status.mlockall is True:
            unlock_memory()
            self.rt_status.mlockall = None
        self.lifecycle.restore_signals()

    def __enter__(self) -> "Workcell":
        if not any(s.is_open for s in self.sessions.values()):
            self.open()
        else:       # sessions opened and controlled by a layer above (RCCL arms): take over the signals
            self.lifecycle.install_signals()
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self._close_all(power_off=exc_type is not None and exc_type is not SystemExit)

    # --- data between tasks ------------------------------------------------------------------
    def channel(self, sender: str, receiver: str, capacity: int = 16, overflow: str = "drop_oldest") -> Channel:
        """The channel from ``sender`` to ``receiver`` (arm names or "planning"), made on first use."""
        for n in (sender, receiver):
            if n != PLANNING:
                self[n]
        if sender == receiver:
            raise MultiError(f"channel: {sender!r} cannot send to itself")
        key = (sender, receiver)
        with self._lock:
            ch = self.channels.get(key)
            if ch is None:
                ch = Channel(sender, receiver, capacity, overflow, deferred=self.sync == "lockstep",
                             is_control_thread=self._in_control_thread)
                self.channels[key] = ch
            elif (capacity, overflow) != (ch.capacity, ch.overflow):
                raise MultiError(f"channel {sender}->{receiver} exists with capacity {ch.capacity}, "
                                 f"overflow {ch.overflow!r}")
            return ch

    def send(self, receiver: str, message: Any, timeout: float | None = None) -> None:
        """Thesis ``send(receiver_id, buffer, size)``: from the calling task to ``receiver``."""
        sender = self.current_task()
        key = (sender, receiver)
        ch = self.channels.get(key) or self.channel(sender, receiver)
        ch.send(message, timeout, stamp=next(self._stamp))

    def receive(self, sender: str | None = None, timeout: float = 0.0) -> tuple[str, Any] | None:
        """Thesis ``receive(sender_id, ...)``: ``(sender, message)`` for the calling task, or None.

        ``sender=None`` (the thesis's 0) takes the oldest message from any sender. Never
        waits in a control task; the planning level may give a ``timeout`` (s).
        """
        me = self.current_task()
        if sender is not None and sender != PLANNING:
            self[sender]
        if timeout and self._in_control_thread():
            raise MultiError(f"receive(): arm {me!r}'s control task must not wait")
        deadline = time.monotonic() + timeout
        while True:
            chans = [c for (s, r), c in list(self.channels.items()) if r == me and (sender is None or s == sender)]
            stamped = [(c.peek_stamp(), c) for c in chans]
            stamped = [x for x in stamped if x[0] is not None]
            if stamped:
                c = min(stamped, key=lambda x: x[0])[1]
                msg = c.receive()
                if msg is not None:
                    return c.sender, msg
                continue            # taken meanwhile by another receiver of the same task: look again
            left = deadline - time.monotonic()
            if left <= 0:
                return None
            self.lifecycle.deliver_here()
            time.sleep(min(0.002, left))

    # --- planning-level wait and error delivery (rci.lifecycle) ---------------------------
    def wait(self, seconds: float | None = None, until: Callable[[], bool] | None = None,
             poll: float = 0.005) -> bool:
        """Block the planning level ``seconds`` or until ``until()``; arm errors are delivered at once."""
        return self.lifecycle.wait(seconds, until, poll)

    def _arm_terminated(self, name: str, term: codes.Termination) -> None:
        """Session listener, in the failing arm's control thread: release the others, tell the planner."""
        with self._lock:
            others = [n for n, s in self.sessions.items()
                      if n != name and s.control_task is not None and not s.control_task.ended]
            at = ArmTermination(name, self.sessions[name].robot, term, others)
            self.terminations.append(at)
            first = self.termination is None
            if first:
                self.lifecycle.termination = at     # under the lock: one first error
        for n in others:
            # stop, power kept: the other arms are healthy; their tasks send the release next cycle
            self.sessions[n].control_task.request_release(False)
        if self._barrier is not None:
            self._barrier.abort()
        if first:
            self.lifecycle.terminated(at)

    def _deliver(self) -> None:
        self.lifecycle.deliver()

    def delivery(self, t: ArmTermination) -> Delivery:
        """LifecycleHost: what the program is told about an arm's termination."""
        return Delivery(ArmTerminated(t), t.code, t.message(), t.termination.severe)

    def before_delivery(self, t: ArmTermination) -> None:
        """LifecycleHost: the sessions' own record of it is delivered too; their threads get a
        moment to finish (never waiting for a user function that does not return)."""
        for s in self.sessions.values():
            s.mark_delivered()
            task = s.control_task
            if task is not None and task is not threading.current_thread():
                task.finished.wait(min(0.2, 4 * task.period))

    def shut(self, power_off: bool) -> None:
        """LifecycleHost: release every arm (power off if asked) and close every link."""
        self._close_all(power_off=power_off)

    def _primitive(self):
        return self.lifecycle.primitive()


def open(arms: dict[str, ArmSpec], **options: Any) -> Workcell:  # noqa: A001 (thesis name)
    """Open a workcell (every arm's link); use it in a ``with`` block."""
    return Workcell(arms, **options).open()


def describe(cell: Workcell) -> Iterable[str]:
    """One line per arm: name, robot, url, rate, lockstep, in control."""
    for n, s in cell.sessions.items():
        yield f"{n}: {s.robot} at {s.url}, {s.rate_hz} Hz, {'lockstep' if s.lockstep else 'real time'}, " \
              f"{'in control' if s.in_control else 'idle'}"
