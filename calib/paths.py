"""Joint paths for the measurement programs: constant-speed sweeps with turns outside
the observation window (thesis 4.5.1), and point-to-point moves for the random halts.

A path is a list of segments, each a straight line in joint space from one pose to the
next with a trapezoidal speed profile (accelerate, cruise, decelerate); ``sample``
evaluates it at the controller's cycle times.  The cruise of a sweep covers its whole
observation window because the ramps fit in the margin beyond each end.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PathSegment:
    """A move from ``start`` to ``end`` (rad, (n_joints,)) with cruise speed ``speed`` (rad/s,
    along the largest joint change), acceleration ``accel`` (rad/s^2), then ``dwell`` s
    standing still at ``end``."""

    start: np.ndarray
    end: np.ndarray
    speed: float
    accel: float
    dwell: float = 0.0

    @property
    def distance(self) -> float:
        return float(np.max(np.abs(self.end - self.start)))

    def _profile(self) -> tuple[float, float, float]:
        """(ramp time, cruise time, peak speed) of the trapezoid (a triangle if short)."""
        d, v, a = self.distance, self.speed, self.accel
        if d == 0.0:
            return 0.0, 0.0, 0.0
        t_ramp = v / a
        if a * t_ramp**2 >= d:          # never reaches cruise speed: triangle
            t_ramp = float(np.sqrt(d / a))
            return t_ramp, 0.0, a * t_ramp
        return t_ramp, (d - a * t_ramp**2) / v, v

    @property
    def duration(self) -> float:
        t_ramp, t_cruise, _ = self._profile()
        return 2 * t_ramp + t_cruise + self.dwell

    def at(self, t: np.ndarray) -> np.ndarray:
        """Poses (N, n_joints) at times ``t`` (s) from the segment's start."""
        t = np.clip(np.asarray(t, dtype=float), 0.0, None)
        t_ramp, t_cruise, v = self._profile()
        d = self.distance
        if d == 0.0:
            return np.tile(self.start, (t.size, 1))
        a = self.accel
        s = np.where(t < t_ramp, 0.5 * a * t**2,
                     np.where(t < t_ramp + t_cruise, 0.5 * a * t_ramp**2 + v * (t - t_ramp),
                              d - 0.5 * a * np.clip(2 * t_ramp + t_cruise - t, 0, None) ** 2))
        frac = np.clip(s / d, 0.0, 1.0)
        return self.start + frac[:, None] * (self.end - self.start)


@dataclass(frozen=True)
class Path:
    """Segments one after another; ``sample(rate)`` gives the setpoint of every cycle."""

    segments: tuple[PathSegment, ...]

    @property
    def duration(self) -> float:
        return float(sum(s.duration for s in self.segments))

    def within(self, vmax, share: float = 0.8) -> "Path":
        """The same path with each segment's speed lowered where needed so that every joint moves
        at most ``share`` of its velocity limit ``vmax`` ((n_joints,) rad/s, m/s on a slide):
        a segment's speed is along its largest joint change, which on an arm with a slide (metres)
        or slow joints need not be the joint nearest its limit."""
        lim = share * np.asarray(vmax, dtype=float)
        out = []
        for seg in self.segments:
            d = np.abs(seg.end - seg.start)
            big = float(d.max()) if d.size else 0.0
            moving = d > 1e-12
            speed = seg.speed
            if big > 0 and np.any(moving):
                speed = float(min(speed, np.min(lim[moving] * big / d[moving])))
            out.append(PathSegment(seg.start, seg.end, speed, seg.accel, seg.dwell))
        return Path(tuple(out))

    def sample(self, rate_hz: float) -> np.ndarray:
        """Setpoints (N, n_joints) rad at t = k / rate_hz until the path ends."""
        n = int(np.ceil(self.duration * rate_hz)) + 1
        t = np.arange(n) / rate_hz
        out = np.empty((n, len(self.segments[-1].end)))
        t0 = 0.0
        for seg in self.segments:
            sel = (t >= t0) & (t < t0 + seg.duration)
            out[sel] = seg.at(t[sel] - t0)
            t0 += seg.duration
        out[t >= t0] = self.segments[-1].end
        return out


def sweep_path(q: np.ndarray, joint: int, lo: float, hi: float, speeds: list[float],
               trips: int, accel: float, start: np.ndarray | None = None,
               dwell: float = 0.1) -> Path:
    """Back-and-forth passes of ``joint`` (0-based) through [lo, hi] rad at each speed,
    ``trips`` round trips per speed, turning beyond the window where the ramps fit and
    standing ``dwell`` s at each turn; the other joints held at ``q``.  Begins with a
    move from ``start`` (if given)."""
    segs: list[PathSegment] = []
    here = np.asarray(q, dtype=float).copy()
    for v in speeds:
        margin = v * v / (2 * accel) + 2 * np.pi / 180
        low, high = here.copy(), here.copy()
        low[joint], high[joint] = lo - margin, hi + margin
        if start is not None or segs:
            segs.append(PathSegment(start if not segs else segs[-1].end, low, max(v, 0.3), accel, 0.3))
        else:
            segs.append(PathSegment(low, low, 1.0, accel, 0.3))
        for _ in range(trips):
            segs.append(PathSegment(low, high, v, accel, dwell))
            segs.append(PathSegment(high, low, v, accel, dwell))
    return Path(tuple(segs))


def approach_path(here: np.ndarray, via, first: np.ndarray, accel: float, speed: float = 0.6) -> Path:
    """From ``here`` through the poses ``via`` to ``first`` (rad): straight joint moves at
    ``speed`` rad/s with ``accel`` rad/s^2, half a second's halt at each pose."""
    poses = [np.asarray(here, float), *[np.asarray(v, float) for v in via], np.asarray(first, float)]
    return Path(tuple(PathSegment(a, b, speed, accel, 0.5) for a, b in zip(poses, poses[1:])))
