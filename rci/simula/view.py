"""``simula --view``: the simulated arm shown live in a browser (rcci.view.scene), sampled without touching the loop.

``start_view(arm, robot, env, port)`` starts the view in a child process (``rci.view_link``)
and a thread that, 30 times a second, copies the arm's joint angles, its clock and its
power into one message for it. The thread only reads: ``arm.q`` is replaced by a fresh
array at every physics substep (never written in place), so the reference it takes is a
consistent snapshot of one instant; simula's loop neither waits for the view nor knows
it is there (the thread's scheduling: rci/view_link.py). The environment's surfaces (``--env``) are drawn as they were given.
"""
from __future__ import annotations

from typing import Sequence

from ..view_link import DEFAULT_HZ, ViewFeed


def start_view(arm, robot: str, env: Sequence[str] = (), *, host: str = "127.0.0.1", port: int = 8080,
               hz: float = DEFAULT_HZ) -> ViewFeed:
    """The view of ``arm`` (a SimulatedArm), following it ``hz`` times a second; ``.url``, ``.close()``."""
    feed = ViewFeed(robot, env=env, host=host, port=port, title=f"simula {robot}")

    def sample() -> dict:
        q = arm.q                    # one reference: the array of one substep (see the module docstring)
        power = "on" if arm.power else "off"
        return {"q": [float(x) for x in q],
                "status": f"**simula** {robot}, t = {arm.t:.1f} s, power {power}"}

    feed.follow(sample, hz)
    return feed
