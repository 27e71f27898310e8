"""An RCCL program's arm, planned path and target shown live in a web browser (``rcci.view.plan.show(arm)``).

    with rccl.open(url, robot="puma260") as arm:
        view = rcci.view.plan.show(arm, env=["plane:z=-0.2"])    # prints the address
        arm.move(p1); arm.move(p2); arm.waitfor(p2.end)

``show`` starts the 3D view of ``rcci.view.scene`` in a child process (``rci.view_link``) and a
thread that, 30 times a second, reads the arm through its public state and sends:

* the arm at the joint angles the robot reports (``arm.measured_q()``), so the view shows
  the real arm on a robot and the simulated one on simula;
* the planned path: the tool point along each request's checked plan (``request.profile``,
  made by ``move()`` at the planning level: a straight line in Cartesian mode, the image
  of a straight joint-space line in joint mode), one polyline per request, coloured by
  its status: grey done, magenta running, blue queued, red failed;
* the current target: the tool frame the running request goes to (its position equation
  solved now, so a moving target moves), as axes;
* a status line: the trajectory's clock, the request running, how many wait.

The requests are found without changing the arm: the latest ``move()`` (``arm.last``) and
the running request are read each time, and a listener on the generator's public
``on_transition`` notes each request as it starts (a cheap append in the control task),
so a request queued and started between two looks is still drawn. A request queued and
still waiting behind a later one when the view looks appears when it starts.

Nothing here runs in the control task except that append: the sampling thread reads, the
child process draws (see rci/view_link.py). ``env`` takes simula's ``--env`` words to
draw the same surfaces; the view does not ask simula for them.
"""
from __future__ import annotations

import collections
import sys
from typing import Sequence

import numpy as np

from rci.view_link import DEFAULT_HZ, DEFAULT_VIEW_PORT, ViewFeed

from rccl.drive import drive_coefficients, drive_basis
from rccl.exceptions import NotRunning
from rccl.transform import T6

PATH_POINTS = 32          # points per request's polyline
KEEP_REQUESTS = 50        # requests remembered for the path (the oldest done ones are dropped)
COLORS = {"done": (70, 70, 76), "running": (190, 0, 150), "queued": (0, 70, 215), "failed": (215, 0, 0)}


def _running_request(gen):
    """The request the generator is running (quartic: ``seg.req``; Ruckig: ``move.req``), or None."""
    for attr in ("seg", "move"):
        part = getattr(gen, attr, None)
        if part is not None:
            return part.req
    return None


def _tool(req) -> np.ndarray:
    pos = req.position
    return np.eye(4) if pos.tool is T6 else pos.tool_from_t6(req.snap)


def request_path(kin, req, n: int = PATH_POINTS) -> np.ndarray | None:
    """The tool point (n, 3), m, along a request's checked plan from start to destination; None without a plan."""
    plan = req.profile
    if plan is None or not hasattr(plan, "q_dest"):
        return None
    lams = np.linspace(1.0, 0.0, n)          # lam runs from 1 (start) to 0 (destination)
    if plan.mode == "joint":
        q = plan.q_dest[None, :] + lams[:, None] * plan.dq[None, :]
        x = kin.fk(q) @ plan.tool
    else:
        drives = (drive_coefficients(plan.theta, lams) @ drive_basis(plan.d, plan.k)).reshape(n, 4, 4)
        x = plan.x_c @ drives
    return np.asarray(x)[:, :3, 3]


class PlanReader:
    """What the view shows of one RCCL arm, read through its public state: ``sample()`` gives one message.

    Attaches one listener to the generator's ``on_transition`` (``detach()`` removes it).
    ``sample`` is called from one thread (the feed's), never from the control task.
    """

    def __init__(self, arm) -> None:
        if getattr(arm, "gen", None) is None:
            raise NotRunning("rcci.view.plan: the arm is not running; call it inside `with rccl.open(...) as arm:`")
        self.arm = arm
        self.gen = arm.gen
        self._requests: collections.OrderedDict = collections.OrderedDict()   # serial -> Request
        self._started: collections.deque = collections.deque(maxlen=KEEP_REQUESTS)
        self._drawn: tuple | None = None
        self._listening = hasattr(self.gen, "on_transition")
        if self._listening:
            self.gen.on_transition.append(self._on_transition)

    def _on_transition(self, event) -> None:  # noqa: ARG002 - the event names positions; the request is the generator's
        """Control task, as a transition starts: note the request now running (one append, never raises)."""
        try:
            self._started.append(_running_request(self.gen))
        except Exception:  # noqa: BLE001 - a listener must not raise into the trajectory generator
            pass

    def _note(self, req) -> None:
        if req is None or req.repeat or req.serial <= 0 or req.serial in self._requests:
            return
        self._requests[req.serial] = req
        while len(self._requests) > KEEP_REQUESTS:
            self._requests.popitem(last=False)

    def requests(self) -> list:
        """The requests seen so far (the latest KEEP_REQUESTS), oldest first."""
        while self._started:
            self._note(self._started.popleft())
        self._note(_running_request(self.gen))
        snapshot = getattr(self.gen.queue, "snapshot", None)
        for req in (snapshot() if snapshot is not None else ()):
            self._note(req)
        self._note(getattr(self.arm, "last", None))
        return sorted(self._requests.values(), key=lambda r: r.serial)

    def sample(self) -> dict:
        """One message for the view: ``q``, ``status``, ``target``, and ``paths`` when a request came or changed status."""
        arm, gen = self.arm, self.gen
        running = _running_request(gen)
        reqs = self.requests()
        msg: dict = {"q": [float(x) for x in arm.measured_q()]}
        drawn = tuple((r.serial, r.status) for r in reqs)
        if drawn != self._drawn:
            lines = []
            for r in reqs:
                pts = request_path(gen.kin, r)
                if pts is not None:
                    lines.append([np.round(pts, 5).tolist(), list(COLORS.get(r.status, COLORS["queued"]))])
            msg["paths"] = {"planned": lines}
            self._drawn = drawn
        if running is not None:
            target = running.position.solve(running.snap) @ _tool(running)
            msg["target"] = np.round(target, 6).tolist()
            if running.repeat or running.serial <= 0 or getattr(running.profile, "stationary", False):
                what = "at"                   # holding, or a stop(): a move to where the arm already is
            else:
                what = "moving to"
            state = f"{what} {running.position.name} ({running.mode})"
        else:
            state = "holding"
        waiting = len(gen.queue)
        msg["status"] = (f"**RCCL** {arm.robot}, t = {gen.t:.1f} s, {state}"
                         + (f", {waiting} queued" if waiting else ""))
        return msg

    def detach(self) -> None:
        if self._listening:
            try:
                self.gen.on_transition.remove(self._on_transition)
            except ValueError:
                pass
            self._listening = False


class ArmWatch:
    """The live view of one RCCL arm: ``url``, ``close()``; made by :func:`show`."""

    def __init__(self, arm, *, env: Sequence[str] = (), host: str = "127.0.0.1", port: int = DEFAULT_VIEW_PORT,
                 hz: float = DEFAULT_HZ, collision: bool = False) -> None:
        self.reader = PlanReader(arm)
        try:
            self.feed = ViewFeed(arm.robot, env=env, host=host, port=port, title=f"RCCL {arm.robot}",
                                 collision=collision)
        except BaseException:
            self.reader.detach()
            raise
        self.url = self.feed.url
        self.feed.follow(self.reader.sample, hz)

    def close(self) -> None:
        """Stop the view (its process ends) and detach from the generator."""
        self.reader.detach()
        self.feed.close()

    def __enter__(self) -> "ArmWatch":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def show(arm, *, env: Sequence[str] = (), host: str = "127.0.0.1", port: int = DEFAULT_VIEW_PORT,
         hz: float = DEFAULT_HZ, quiet: bool = False, collision: bool = False) -> ArmWatch:
    """Show ``arm`` (an open RCCL arm) live in a browser; prints the address (stderr) unless ``quiet``.

    ``env``: simula's ``--env`` words (``plane:z=...``, ``box:...``) to draw those surfaces;
    ``port``: the view's HTTP port (0: any free one); ``hz``: updates per second; ``collision``:
    also draw the arm's collision shapes (what ``arm.collisions(...)`` checks against). The view
    lives until ``close()`` or the end of the program. Needs ``pip install 'rcci[view]'``.
    """
    watch = ArmWatch(arm, env=env, host=host, port=port, hz=hz, collision=collision)
    if not quiet:
        print(f"rcci.view.plan: {arm.robot} shown at {watch.url}", file=sys.stderr, flush=True)
    return watch
