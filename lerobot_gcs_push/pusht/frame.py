"""gym-pusht's frame and state against this project's: pixels (y down) and its T's body origin on one side,
metres (y up) and the T's centre of gravity on the other.

gym-pusht (huggingface/gym-pusht, `gym_pusht/envs/pusht.py`) places its T by the body origin, the middle of
the bar's outer edge, with the bar at local y in [0, 30] px and the stem below it to y = 120; the body's
centre of gravity is (0, 45) px, the plain mean of the two boxes' centroids, and pymunk turns the body about
it. A point (u, v) on its 512 px screen is (x, y) = ((u - u0) / s, -(v - v0) / s) here, s px to the metre:
a reflection, so its angle a is heading -a here, and its local (lx, ly) is (lx, 45 - ly) / s in the frame
of `shapes.tee(bar_length=120 / s, pivot="parts")`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

# gym-pusht's T: bar 120 x 30 px, stem 30 x 90 px; 60 px to the metre makes it this project's 2 m T exactly.
PX_PER_M = 60.0
BAR_PX = 120.0
COG_PX = (0.0, 45.0)  # the body's centre of gravity, in its local frame (px)
ARENA_PX = 512.0
GOAL_STATE = (256.0, 256.0, math.pi / 4)  # the goal's body origin and angle, gym-pusht's `goal_pose`


@dataclass(frozen=True)
class PixelFrame:
    """Where this project's metres sit on gym-pusht's screen: `origin` (px) is (0, 0), y flips."""

    px_per_m: float = PX_PER_M
    origin: tuple[float, float] = (ARENA_PX / 2, ARENA_PX / 2)

    def to_px(self, xy) -> np.ndarray:
        """Points (..., 2) in metres to pixels."""
        xy, (u0, v0), s = np.asarray(xy, float), self.origin, self.px_per_m
        return np.stack([u0 + s * xy[..., 0], v0 - s * xy[..., 1]], -1)

    def to_m(self, uv) -> np.ndarray:
        """Points (..., 2) in pixels to metres."""
        uv, (u0, v0), s = np.asarray(uv, float), self.origin, self.px_per_m
        return np.stack([(uv[..., 0] - u0) / s, -(uv[..., 1] - v0) / s], -1)

    def pose_of_block(self, block) -> np.ndarray:
        """gym-pusht's block (origin u, v in px, angle) as this project's slider pose (x, y of the centre of
        gravity in metres, heading in [-pi, pi])."""
        u, v, a = (float(b) for b in block)
        cog = np.array([u, v]) + _rot(a) @ COG_PX
        return np.array([*self.to_m(cog), math.remainder(-a, 2 * math.pi)])

    def block_of_pose(self, pose) -> np.ndarray:
        """The inverse of `pose_of_block`: (u, v, angle) with the angle in [0, 2 pi), as gym-pusht reports it."""
        x, y, heading = (float(p) for p in pose)
        a = (-heading) % (2 * math.pi)
        origin = self.to_px([x, y]) - _rot(a) @ COG_PX
        return np.array([*origin, a])

    def state_of(self, pose, finger) -> np.ndarray:
        """gym-pusht's `obs_type="state"` vector [agent u, v, block u, v, angle] of a pose and finger (m)."""
        return np.concatenate([self.to_px(finger), self.block_of_pose(pose)])

    def pose_finger_of(self, state) -> tuple[np.ndarray, np.ndarray]:
        """(slider pose, finger) in metres of gym-pusht's state vector."""
        state = np.asarray(state, float)
        return self.pose_of_block(state[2:5]), self.to_m(state[:2])


def reset_to_state(state) -> list[float]:
    """What to pass as gym-pusht's `options["reset_to_state"]` for its env to report `state` after the reset:
    it places the body's origin and then turns the body about its centre of gravity, which moves the origin
    by (I - R(angle)) (0, 45) px; this passes the origin that turn lands on `state`'s."""
    state = np.asarray(state, float)
    a = float(state[4])
    placed = state[2:4] - np.asarray(COG_PX) + _rot(a) @ COG_PX
    return [float(state[0]), float(state[1]), float(placed[0]), float(placed[1]), a]


def _rot(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s], [s, c]])


def check_pusht_state(state) -> np.ndarray:
    """gym-pusht's state [agent u, v, block u, v, angle] as floats, or a ValueError naming the field."""
    try:
        arr = np.asarray(state, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"pusht_state must be [agent_x, agent_y, block_x, block_y, angle], got {state!r}") from None
    if arr.shape != (5,):
        raise ValueError(f"pusht_state must be [agent_x, agent_y, block_x, block_y, angle], got {state!r}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"pusht_state must be finite, got {arr.tolist()}")
    # The block's origin lies on its outline, which gym-pusht's walls keep inside the arena. (The agent passes
    # through walls; its bound is the planner's workspace, checked in px by `Scene.validate_start`.)
    u, v = arr[2:4]
    if not (0 <= u <= ARENA_PX and 0 <= v <= ARENA_PX):
        raise ValueError(f"pusht_state's block ({u:g}, {v:g}) px lies outside gym-pusht's arena [0, {ARENA_PX:g}] px")
    return arr
