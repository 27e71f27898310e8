"""The motion layer's extension points: Request.on_finish and MotionQueue's QueuePolicy (used by rccl.events)."""
from __future__ import annotations

import threading

from rccl.motion import MotionParams, Request
from rccl.queue import HOLD, TAKE, MotionQueue, QueuePolicy


class _End:
    def __init__(self) -> None:
        self.count = 0

    def signal(self) -> None:
        self.count += 1


class _Pos:
    def __init__(self, name: str) -> None:
        self.name = name
        self.end = _End()


def _req(name: str = "p") -> Request:
    return Request(_Pos(name), None, MotionParams())


def test_on_finish_fires_once_with_the_request():
    r = _req()
    seen = []
    r.on_finish(seen.append)
    assert seen == []
    r.finish()
    r.finish()                      # a second finish does not call it again
    assert seen == [r] and r.status == "done" and r.wait(0)


def test_on_finish_registered_after_finish_fires_at_once():
    r = _req()
    r.finish(ValueError("x"))
    seen = []
    r.on_finish(seen.append)
    assert seen == [r] and r.status == "failed"


def test_on_finish_from_another_thread():
    r = _req()
    seen = []
    r.on_finish(lambda q: seen.append(threading.current_thread().name))
    t = threading.Thread(target=r.finish, name="trajectory")
    t.start()
    t.join()
    assert seen == ["trajectory"]


class _Gate(QueuePolicy):
    def __init__(self) -> None:
        self.open: set[str] = set()
        self.stopped: set[str] = set()
        self.log: list[tuple[str, str]] = []

    def queued(self, item) -> None:
        self.log.append(("queued", item.position.name))

    def admit(self, head):
        name = head.position.name
        if name in self.stopped:
            return RuntimeError(f"{name}: deleted")
        return TAKE if name in self.open else HOLD

    def taken(self, item) -> None:
        self.log.append(("taken", item.position.name))

    def cleared(self, items) -> None:
        self.log.append(("cleared", ",".join(i.position.name for i in items)))


def test_the_gate_holds_and_releases_the_head():
    gate = _Gate()
    q = MotionQueue()
    a, b = _req("a"), _req("b")
    q.put(a)                         # queued before the policy is set: it is gated too
    q.set_policy(gate)
    q.put(b)
    assert q.get() is None and len(q) == 2     # a is held; b stays behind it
    gate.open.add("b")
    assert q.get() is None                      # b is open but queued behind the held a
    gate.open.add("a")
    assert q.get() is a and q.get() is b and q.get() is None
    assert gate.log == [("queued", "b"), ("taken", "a"), ("taken", "b")]


def test_the_gate_deletes_a_stopped_request_before_it_starts():
    gate = _Gate()
    q = MotionQueue(gate)
    a, b = _req("a"), _req("b")
    q.put(a)
    q.put(b)
    gate.stopped.add("a")
    gate.open.add("b")
    assert q.get() is b                          # a deleted, b handed out in the same call
    assert a.status == "failed" and str(a.error) == "a: deleted" and a.position.end.count == 1
    assert b.status == "queued" and len(q) == 0


def test_clear_tells_the_policy():
    gate = _Gate()
    q = MotionQueue(gate)
    q.put(_req("a"))
    q.put(_req("b"))
    assert [r.position.name for r in q.clear()] == ["a", "b"]
    assert gate.log[-1] == ("cleared", "a,b")


def test_default_policy_is_a_plain_fifo():
    q = MotionQueue()
    a, b = _req("a"), _req("b")
    q.put(a)
    q.put(b)
    assert q.get() is a and q.get() is b and q.get() is None
