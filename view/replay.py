"""``python -m rcci.view.replay LOG.rcilog``: replay a recorded log in the 3D browser view, with a time slider and a play button.

    python -m rcci.view.replay run.rcilog                     # serves http://127.0.0.1:8080 until Ctrl-C
    python -m rcci.view.replay calib/logs/kinematics.rcilog.xz --port 0 --speed 4
    python -m rcci.view.replay run.rcilog --screenshot run.png --at 12.5   # a picture (headless Chromium), then exit

The arm is drawn at the joint angles the robot reported in each recorded cycle (``how_pos``
converted by ``rci.log_units``: the log's own robot, docs/log-format.md); the tool path
of the whole log (link 6's origin) is a grey polyline, the part already played is orange;
where every joint was commanded by position (``chg`` POS), the commanded link-6 frame is
shown as axes (the target the arm was following). ``--env`` draws simula's surfaces
(``plane:z=...``, ``box:...``). The panel has the slider (time from the first record, s), a
play/pause button, the speed and a loop switch, and the record shown in SI units: per joint the
measured and commanded position (rad, m), rate (rad/s, m/s) and torque (N m, N), and T6.
"""
from __future__ import annotations

import argparse
import sys
import threading
import time
from pathlib import Path

import numpy as np

from rci.view_link import DEFAULT_VIEW_PORT

PATH_POINTS = 1500        # the tool path is drawn through at most this many records
PLAYED_COLOR = (190, 0, 150)
PATH_COLOR = (70, 70, 76)
SPEEDS = ("0.25", "0.5", "1", "2", "4", "10")
FRAME_HZ = 30.0


class Replay:
    """A log's joint angles over time, and where link 6 was and was sent, ready to draw."""

    def __init__(self, path: str | Path) -> None:
        from rci.log_units import log_in_si
        from rci.recorder import read_log

        self.log = read_log(path)
        self.name = Path(path).name
        if len(self.log.records) == 0:
            raise ValueError(f"{path}: the log has no records")
        self.robot = self.log.meta["robot"]
        self.si = log_in_si(self.log)                  # the same SI numbers as rci.export and rci.plot
        self.t = self.si.t
        self.q = self.si.q
        # the commanded frame is drawn where every joint was commanded by position (chg POS)
        self.q_cmd = np.where(np.all(np.isfinite(self.si.q_cmd), axis=1)[:, None], self.si.q_cmd, np.nan)

    def table(self, i: int) -> str:
        """Record ``i`` in SI units as a Markdown table: a row per joint, measured and commanded."""
        si = self.si
        units = [f"{a}, {b}, {c}" for a, b, c in zip(si.unit("q"), si.unit("qd"), si.unit("tau"))]

        def cell(x: np.ndarray | None, j: int) -> str:
            return "" if x is None or not np.isfinite(x[i, j]) else f"{x[i, j]:+.4f}"
        rows = ["| joint | q | qd | tau | q cmd | tau cmd | units |", "|---|---|---|---|---|---|---|"]
        for j, name in enumerate(si.joint_names):
            rows.append(f"| {j + 1} | {cell(si.q, j)} | {cell(si.qd, j)} | {cell(si.tau, j)} | "
                        f"{cell(si.q_cmd, j)} | {cell(si.tau_cmd, j)} | {units[j]} |")
        x, y, z = si.T6[i, :3, 3]
        rows.append(f"\nT6 at ({x:+.4f}, {y:+.4f}, {z:+.4f}) m")
        return "\n".join(rows)

    @property
    def duration(self) -> float:
        return float(self.t[-1])

    def index(self, t: float) -> int:
        """The last record at or before time ``t`` (s)."""
        return int(np.clip(np.searchsorted(self.t, t, side="right") - 1, 0, len(self.t) - 1))


class ReplayView:
    """An ``ArmView`` driven by a ``Replay``: ``show(t)``, the panel's controls, a player thread."""

    def __init__(self, replay: Replay, *, env=(), host: str = "127.0.0.1", port: int = DEFAULT_VIEW_PORT,
                 collision: bool = False) -> None:
        from .scene import ArmView

        self.replay = replay
        self.view = ArmView(replay.robot, env=env, host=host, port=port, title=f"replay {replay.name}",
                            q=replay.q[0], collision=collision)
        tree = self.view.tree
        self._tip = tree.joints[-1].child if tree.joints else tree.root     # link 6 (the last link)
        step = max(1, len(replay.q) // PATH_POINTS)
        self._path_idx = np.arange(0, len(replay.q), step)
        self._path = np.array([tree.link_poses(q)[self._tip][:3, 3] for q in replay.q[self._path_idx]])
        gui = self.view.server.gui
        rate = float(self.replay.log.meta.get("rate_hz") or 36)
        self.slider = gui.add_slider("time (s)", min=0.0, max=max(replay.duration, 1.0 / rate),
                                     step=1.0 / rate, initial_value=0.0)
        self.play = gui.add_button("play")
        self.speed = gui.add_dropdown("speed", SPEEDS, initial_value="1")
        self.loop = gui.add_checkbox("loop", initial_value=False)
        self._playing = threading.Event()
        self._stop = threading.Event()
        self.slider.on_update(lambda _: self.show(self.slider.value))
        self.play.on_click(lambda _: self.toggle())
        self.show(0.0)
        self._thread = threading.Thread(target=self._player, name="replay", daemon=True)
        self._thread.start()

    @property
    def url(self) -> str:
        return self.view.url

    def show(self, t: float) -> None:
        """Draw the arm as recorded at time ``t`` (s from the first record)."""
        r = self.replay
        i = r.index(t)
        v = self.view
        v.set_q(r.q[i])
        k = int(np.searchsorted(self._path_idx, i, side="right"))
        played = np.vstack([self._path[:k], v.tree.link_poses(r.q[i])[self._tip][:3, 3]])
        v.set_path("recorded", [(self._path, PATH_COLOR), (played, PLAYED_COLOR)])
        cmd = r.q_cmd[i]
        v.set_target(None if np.isnan(cmd).any() else v.tree.link_poses(cmd)[self._tip])
        v.set_status(f"**{r.name}** ({r.robot}), record {i + 1} of {len(r.q)}, t = {r.t[i]:.2f} s\n\n{r.table(i)}")

    def toggle(self) -> None:
        if self._playing.is_set():
            self._playing.clear()
            self.play.label = "play"
        else:
            if self.slider.value >= self.replay.duration:
                self.slider.value = 0.0
            self._playing.set()
            self.play.label = "pause"

    def _player(self) -> None:
        last = time.monotonic()
        while not self._stop.wait(1.0 / FRAME_HZ):
            now = time.monotonic()
            dt, last = now - last, now
            if not self._playing.is_set():
                continue
            t = self.slider.value + dt * float(self.speed.value)
            if t > self.replay.duration:
                if self.loop.value:
                    t = 0.0
                else:
                    t = self.replay.duration
                    self._playing.clear()
                    self.play.label = "play"
            self.slider.value = t             # its on_update draws the frame

    def close(self) -> None:
        self._stop.set()
        self._thread.join(2.0)
        self.view.close()


def _size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(x) for x in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not WIDTHxHEIGHT (e.g. 1200x800)") from None
    return w, h


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m rcci.view.replay",
        description="Replay a recorded .rcilog in the 3D browser view (the arm, its tool path, the commanded "
                    "frame), with a time slider and a play button (docs/viewer.md). Needs pip install 'rcci[view]'.")
    p.add_argument("log", help="the log (.rcilog, or .rcilog.xz / .gz as in calib/logs/)")
    p.add_argument("--host", default="127.0.0.1", help="address the view listens on (default loopback)")
    p.add_argument("--port", type=int, default=DEFAULT_VIEW_PORT,
                   help=f"HTTP port (default {DEFAULT_VIEW_PORT}; 0: any free one; a busy one: the next free)")
    p.add_argument("--env", action="append", default=[], metavar="SPEC",
                   help="environment surface to draw (repeatable), simula's --env words: plane:z=..., box:...")
    p.add_argument("--collision", action="store_true",
                   help="also draw the arm's collision shapes (models/collision/ROBOT.toml; docs/collision.md)")
    p.add_argument("--play", action="store_true", help="start playing at once")
    p.add_argument("--speed", choices=SPEEDS, default="1", help="playing speed (default 1: real time)")
    p.add_argument("--screenshot", metavar="PNG",
                   help="write a picture of the view (headless Chromium) and exit instead of serving")
    p.add_argument("--at", type=float, default=None, metavar="SECONDS",
                   help="with --screenshot: the moment shown, s from the first record (default: the end)")
    p.add_argument("--size", type=_size, default=(1200, 800), metavar="WxH",
                   help="with --screenshot: picture size in pixels (default 1200x800)")
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        replay = Replay(args.log)
        rv = ReplayView(replay, env=args.env, host=args.host, port=args.port, collision=args.collision)
    except ImportError as exc:
        print(f"rcci.view.replay: {exc}", file=sys.stderr)
        return 2
    except Exception as exc:  # noqa: BLE001 - a bad log, robot or environment word: say so, exit 2
        print(f"rcci.view.replay: {exc}", file=sys.stderr)
        return 2
    rv.speed.value = args.speed
    try:
        if args.screenshot:
            from .screenshot import BrowserError, screenshot
            at = replay.duration if args.at is None else args.at
            rv.slider.value = min(max(at, 0.0), replay.duration)
            rv.show(rv.slider.value)
            try:
                screenshot(rv.url, args.screenshot, size=args.size)
            except BrowserError as exc:
                print(f"rcci.view.replay: {exc}", file=sys.stderr)
                return 1
            print(f"wrote {args.screenshot} ({replay.name} at t = {rv.slider.value:.2f} s)")
            return 0
        print(f"view {rv.url}  ({replay.name}: {len(replay.q)} records, {replay.duration:.1f} s; Ctrl-C ends)",
              flush=True)
        if args.play:
            rv.toggle()
        try:
            while True:
                time.sleep(3600)
        except KeyboardInterrupt:
            pass
        return 0
    finally:
        rv.close()


if __name__ == "__main__":
    sys.exit(main())
