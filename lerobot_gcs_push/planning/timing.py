"""When the finger is where along a plan's knots: each segment at its kind's speed, either at once (the speed
jumps at every knot) or, with an acceleration bound, along a velocity profile that starts and ends at rest,
slows for corners and never exceeds a segment's speed (`Speeds.accel`).

A policy imitates a position path best when the path is smooth: with jumps, every corner is a kick the
imitator must time to the frame (experiments/pusht/README.md, "Imitable commands").
"""

from __future__ import annotations

import numpy as np

# A corner's change of velocity is allowed what the acceleration bound gives in this time (s): gym-pusht's
# action period, the time over which a command holds.
CORNER_S = 0.1


class Timing:
    """Knot times for a path of K + 1 knots: segment i (knot i to i + 1) runs at most `vmax[i]` (m/s), or holds
    for `hold[i]` s where it has no length (a dwell: the finger at rest at both its knots). `accel` (m/s^2)
    bounds the speed's change along the path and, over CORNER_S, at a corner; 0: no bound (the speed jumps)."""

    def __init__(self, path: np.ndarray, vmax: np.ndarray, hold: np.ndarray, accel: float = 0.0):
        path = np.asarray(path, float)
        self.lengths = np.linalg.norm(np.diff(path, axis=0), axis=1)
        vmax, hold = np.asarray(vmax, float), np.asarray(hold, float)
        self.accel = float(accel)
        moving = self.lengths > 1e-12
        if self.accel > 0:
            knot_v = _knot_speeds(path, self.lengths, vmax, hold, self.accel)
            v_in, v_out = knot_v[:-1], knot_v[1:]
            peak = np.minimum(vmax, np.sqrt(np.maximum(self.accel * self.lengths + (v_in**2 + v_out**2) / 2, 0.0)))
            peak = np.where(moving, np.maximum(peak, np.maximum(v_in, v_out)), 0.0)
            t_up = np.where(moving, (peak - v_in) / self.accel, 0.0)
            t_down = np.where(moving, (peak - v_out) / self.accel, 0.0)
            d_up = np.where(moving, (peak**2 - v_in**2) / (2 * self.accel), 0.0)
            d_down = np.where(moving, (peak**2 - v_out**2) / (2 * self.accel), 0.0)
            cruise = np.maximum(self.lengths - d_up - d_down, 0.0)
            t_cruise = np.divide(cruise, peak, out=np.zeros_like(peak), where=peak > 0)
        else:  # the speed jumps to each segment's own at its first knot
            peak = np.where(moving, vmax, 0.0)
            v_in = peak
            t_up = t_down = np.zeros_like(peak)
            t_cruise = np.divide(self.lengths, peak, out=np.zeros_like(peak), where=peak > 0)
        durations = np.where(moving, t_up + t_cruise + t_down, hold)
        self.times = np.concatenate([[0.0], np.cumsum(durations)])
        self._v_in, self._peak, self._t_up, self._t_cruise = v_in, peak, t_up, t_cruise

    @property
    def duration(self) -> float:
        return float(self.times[-1])

    def where(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(segment, share of its length) at each time t (clipped to the path's span). At a knot's time the
        segment that starts there, past any that take no time: the last knot of that instant, as linear
        interpolation in time gives it."""
        t = np.clip(np.asarray(t, float), 0.0, self.duration)
        n = len(self.lengths)
        if n == 0:
            return np.zeros(len(t), int), np.ones(len(t))
        seg = np.clip(np.searchsorted(self.times, t, side="right") - 1, 0, n - 1)
        tau = t - self.times[seg]
        a = self.accel if self.accel > 0 else 0.0
        v0, vp, t1, t2 = self._v_in[seg], self._peak[seg], self._t_up[seg], self._t_cruise[seg]
        up = np.minimum(tau, t1)
        cruise = np.clip(tau - t1, 0.0, t2)
        down = np.maximum(tau - t1 - t2, 0.0)
        s = v0 * up + a * up**2 / 2 + vp * cruise + (vp * down - a * down**2 / 2)
        length = self.lengths[seg]
        span = self.times[seg + 1] - self.times[seg]
        share = np.where(
            length > 1e-12,
            np.divide(s, length, out=np.ones_like(s), where=length > 1e-12),
            np.divide(tau, span, out=np.ones_like(tau), where=span > 0),
        )
        return seg, np.clip(share, 0.0, 1.0)


def _knot_speeds(path, lengths, vmax, hold, accel) -> np.ndarray:
    """The fastest speed at each knot: at rest at both ends and at a dwell's knots, no faster than either
    segment that meets there, through a corner no faster than turns its velocity by accel x CORNER_S, and
    reachable from the knots on both sides within the bound (a forward and a backward pass)."""
    k = len(lengths)
    moving = lengths > 1e-12
    direction = np.zeros((k, 2))
    direction[moving] = np.diff(path, axis=0)[moving] / lengths[moving, None]
    v = np.full(k + 1, np.inf)
    v[0] = v[-1] = 0.0
    for j in range(1, k):
        v[j] = min(vmax[j - 1], vmax[j])
        before, after = _moving_neighbour(moving, hold, j - 1, -1), _moving_neighbour(moving, hold, j, 1)
        if before is None or after is None:  # a dwell (or the path's end) lies between: at rest
            v[j] = 0.0
            continue
        turn = float(np.linalg.norm(direction[after] - direction[before]))
        if turn > 1e-9:
            v[j] = min(v[j], accel * CORNER_S / turn)
    for j in range(k):  # forward: no faster than the bound allows from the knot before
        v[j + 1] = min(v[j + 1], np.sqrt(v[j] ** 2 + 2 * accel * lengths[j]))
    for j in range(k - 1, -1, -1):  # backward: slow enough to stop for what follows
        v[j] = min(v[j], np.sqrt(v[j + 1] ** 2 + 2 * accel * lengths[j]))
    return v


def _moving_neighbour(moving, hold, i, step) -> int | None:
    """The first segment from i, stepping by `step`, that has length; None where a dwell or the end comes first."""
    while 0 <= i < len(moving):
        if moving[i]:
            return i
        if hold[i] > 0:
            return None
        i += step
    return None
