"""The view's own process: an ``ArmView`` served by viser, updated from JSON lines on stdin.

``rci.view_link.ViewFeed`` starts it (``python -m rcci.view.process``) for ``simula --view`` and
``rcci.view.plan.show``; it prints ``view URL`` when the scene is up and ends when its stdin
closes. The message format is ``rci.view_link``'s (what it says, one JSON object a line).
A view slower than its feed skips to the newest state instead of lagging behind (``serve``).
"""
from __future__ import annotations

import argparse
import json
import os
import select
import sys

from rci.view_link import DEFAULT_VIEW_PORT, not_realtime


def apply(view, msg: dict) -> None:
    """Apply one feed message to an ``ArmView``."""
    if "q" in msg:
        view.set_q(msg["q"])
    if "status" in msg:
        view.set_status(str(msg["status"]))
    for name, polylines in (msg.get("paths") or {}).items():
        view.set_path(name, [(pts, color) for pts, color in polylines])
    if "target" in msg:
        view.set_target(msg["target"])


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m rcci.view.process",
        description="Serve the 3D view of an arm and update it from JSON lines on stdin (started by "
                    "rci.view_link.ViewFeed for simula --view and rcci.view.plan.show; prints 'view URL' "
                    "when ready and exits when stdin closes).")
    p.add_argument("--robot", default="puma260", help="robot model (models/ROBOT.toml and its URDF)")
    p.add_argument("--host", default="127.0.0.1", help="address the view listens on (default loopback)")
    p.add_argument("--port", type=int, default=DEFAULT_VIEW_PORT,
                   help=f"HTTP/websocket port (default {DEFAULT_VIEW_PORT}; 0: any free port; a busy one: the next)")
    p.add_argument("--env", action="append", default=[], metavar="SPEC",
                   help="environment surface to draw (repeatable), simula's --env words: plane:z=..., box:...")
    p.add_argument("--title", default="", help="the panel's title")
    p.add_argument("--collision", action="store_true",
                   help="also draw the arm's collision shapes (models/collision/ROBOT.toml; docs/collision.md)")
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    not_realtime()
    from .scene import ArmView
    try:
        view = ArmView(args.robot, env=args.env, host=args.host, port=args.port, title=args.title,
                       collision=args.collision)
    except (ImportError, ValueError, OSError) as exc:
        print(f"view: {exc}", file=sys.stderr)
        return 2
    except Exception as exc:  # a bad robot name is a ModelError
        print(f"view: {exc}", file=sys.stderr)
        return 2
    print(f"view {view.url}", flush=True)
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 1)                                      # nobody reads stdout from here on
    sys.stdout = open(1, "w", closefd=False)
    try:
        serve(view, sys.stdin.fileno())
    except KeyboardInterrupt:
        pass
    finally:
        view.close()
    return 0


def merge(pending: dict, msg: dict) -> None:
    """Fold ``msg`` into ``pending``: the newest value of each key, paths by name."""
    for key, value in msg.items():
        if key == "paths":
            pending.setdefault("paths", {}).update(value or {})
        else:
            pending[key] = value


def serve(view, fd: int) -> None:
    """Apply the messages arriving on ``fd`` until end of file; what queued up meanwhile is merged
    first, so a view slower than its feed skips to the newest state instead of lagging behind."""
    buf = b""
    while True:
        select.select([fd], [], [])
        data = os.read(fd, 1 << 16)
        if not data:
            return
        buf += data
        while select.select([fd], [], [], 0)[0]:            # everything already there
            more = os.read(fd, 1 << 16)
            if not more:
                break
            buf += more
        *lines, buf = buf.split(b"\n")
        pending: dict = {}
        for line in lines:
            try:
                msg = json.loads(line)
                if not isinstance(msg, dict):
                    raise ValueError("not a JSON object")
                merge(pending, msg)
            except ValueError as exc:
                print(f"view: bad message dropped ({exc})", file=sys.stderr)
        if pending:
            try:
                apply(view, pending)
            except (ValueError, TypeError, KeyError) as exc:
                print(f"view: bad message dropped ({exc})", file=sys.stderr)


if __name__ == "__main__":
    sys.exit(main())
