"""`GcsPushBox-v0`: the Gymnasium env over the Drake pushing scene.

Observation (`obs_type`):
  - "pixels_agent_pos": {"pixels": uint8 (H, W, 3) top-down image, "agent_pos": float64 (2,) finger x, y}
  - "state": float64 (4,) = [finger x, finger y, box x, box y] (the paper's state, finger first as in
    `agent_pos`).
Reward: minus the box-goal distance (m); `terminated` on success, `truncated` at `max_sim_time_s`.
Action: the absolute finger position target (x, y) in metres, held for 1/fps s of simulated time.
Targets outside the commandable square [-finger_limit, finger_limit]^2 are clipped to it; NaN or inf
raise ValueError (a silent clip would hide a broken policy).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from lerobot_gcs_push.registration import ENV_ID, register_envs  # noqa: F401  (re-exported)
from lerobot_gcs_push.scene import TASK, Disturbances, Scene, check_sampler, sample_initial_conditions
from lerobot_gcs_push.sim import PushSim

OBS_TYPES = ("pixels_agent_pos", "state")

# A force along +x pushes on the box's left (-x) face, and so on.
_DIRECTIONS = (((1.0, 0.0), "left"), ((-1.0, 0.0), "right"), ((0.0, 1.0), "bottom"), ((0.0, -1.0), "top"))


@dataclass(frozen=True)
class Disturbance:
    tick: int  # onset, in ticks since the episode start
    force: tuple[float, float]  # N, on the box centre
    face: str  # the face the force pushes on

    def to_info(self, tick_s: float) -> dict:
        return {"t": round(self.tick * tick_s, 9), "force": list(self.force), "face": self.face}


class DisturbanceSchedule:
    """The paper's random pushes on the box (section IV-A), drawn tick by tick from `rng`.

    At every tick, while fewer than `max_count` have started, a disturbance starts with probability
    `probability_per_tick`; it pushes one of the four faces, chosen uniformly, with a magnitude uniform in
    `force_range_n`, for `duration_ticks` ticks. A new one may start while another acts (the protocol
    draws at every tick); their forces add.
    """

    def __init__(self, protocol: Disturbances, rng: np.random.Generator):
        self.protocol = protocol
        self.rng = rng
        self.started: list[Disturbance] = []
        self._tick = 0

    def forces(self, n_ticks: int) -> np.ndarray | None:
        """Forces (n_ticks, 2) for the next `n_ticks` ticks, or None when none acts."""
        p = self.protocol
        start, end = self._tick, self._tick + n_ticks
        # Tick by tick, so the draws (and so the disturbances of a seed) do not depend on the env's fps.
        for tick in range(start, end):
            if len(self.started) >= p.max_count:
                break
            if self.rng.random() < p.probability_per_tick:
                magnitude = self.rng.uniform(*p.force_range_n)
                (dx, dy), face = _DIRECTIONS[self.rng.integers(len(_DIRECTIONS))]
                self.started.append(Disturbance(tick, (magnitude * dx, magnitude * dy), face))
        out = None
        for d in self.started:
            lo, hi = max(d.tick, start), min(d.tick + p.duration_ticks, end)
            if lo < hi:
                out = np.zeros((n_ticks, 2)) if out is None else out
                out[lo - start : hi - start] += d.force
        self._tick = end
        return out


class GcsPushBoxEnv(gym.Env):
    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}
    # lerobot-eval asks every sub-env for both (a missing attribute kills an AsyncVectorEnv worker).
    task = task_description = TASK

    def __init__(
        self,
        obs_type: str = "pixels_agent_pos",
        fps: float = Scene.fps,
        max_sim_time_s: float = Scene.timeout_s,
        disturbances: bool = False,
        image_size: int | tuple[int, int] = 96,
        success_threshold: float | None = None,
        goal=None,
        render_mode: str | None = "rgb_array",
        scene: Scene | None = None,
        sampler: str = "uniform",
        render_size: int | tuple[int, int] = 384,
    ):
        if obs_type not in OBS_TYPES:
            raise ValueError(f"obs_type must be one of {OBS_TYPES}, got {obs_type!r}")
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode must be 'rgb_array' or None, got {render_mode!r}")
        check_sampler(sampler)
        if not max_sim_time_s > 0:
            raise ValueError(f"max_sim_time_s must be positive, got {max_sim_time_s}")
        scene = scene if scene is not None else Scene()
        if goal is not None:
            scene = scene.with_goal(goal)
        if success_threshold is not None:
            scene = dataclasses.replace(scene, success_threshold=float(success_threshold))
        rows, cols = _size(image_size)
        scene = dataclasses.replace(scene, camera=dataclasses.replace(scene.camera, height=rows, width=cols))
        self.scene, self.obs_type, self.fps, self.sampler = scene, obs_type, fps, sampler
        self.max_sim_time_s, self.disturbances, self.render_mode = max_sim_time_s, disturbances, render_mode
        self.sim = PushSim(scene, render_size=_size(render_size))
        self._dt = 1.0 / fps
        self.sim.steps_in(self._dt)  # raises unless 1/fps is a whole number of disturbance ticks
        self._ticks_per_step = int(round(self._dt / scene.disturbances.tick_s))
        self._max_episode_steps = math.ceil(max_sim_time_s * fps - 1e-9)  # LeRobot's eval reads this
        self.metadata = {**self.metadata, "render_fps": fps}

        lim = scene.finger_limit
        self.action_space = spaces.Box(-lim, lim, shape=(2,), dtype=np.float64)
        # The finger may overshoot a command at the limit by the PID's few millimetres, and the box may be
        # pushed or knocked past its workspace: the view edge bounds the finger, nothing bounds the box.
        agent = spaces.Box(-scene.view_half_width, scene.view_half_width, shape=(2,), dtype=np.float64)
        if obs_type == "state":
            high = np.array([scene.view_half_width] * 2 + [np.inf] * 2)
            self.observation_space = spaces.Box(-high, high, dtype=np.float64)
        else:
            self.observation_space = spaces.Dict(
                {
                    "pixels": spaces.Box(0, 255, shape=(rows, cols, 3), dtype=np.uint8),
                    "agent_pos": agent,
                }
            )
        self._schedule: DisturbanceSchedule | None = None
        self._steps = 0

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        if options and ("box" in options or "finger" in options):
            box, finger = self.scene.validate_state(options.get("box"), options.get("finger"))
            if self.sim.collides(box, finger):
                raise ValueError(
                    f"initial condition: finger {finger.tolist()} overlaps the box {box.tolist()} "
                    f"(Drake's collision query)"
                )
        else:
            ic = sample_initial_conditions(
                self.scene,
                1,
                seed=int(self.np_random.integers(2**63 - 1)),
                sampler=self.sampler,
                collides=self.sim.collides,
            )[0]
            box, finger = np.array(ic.box), np.array(ic.finger)
        self.sim.reset(box, finger)
        self._steps = 0
        self._schedule = DisturbanceSchedule(self.scene.disturbances, self.np_random) if self.disturbances else None
        return self._observation(), self._info()

    def step(self, action):
        target = np.asarray(action, dtype=np.float64)
        if target.shape != (2,):
            raise ValueError(f"action must be a finger target [x, y], got shape {target.shape}")
        if not np.all(np.isfinite(target)):
            raise ValueError(f"action must be finite, got {target.tolist()} (NaN or inf)")
        lim = self.scene.finger_limit
        forces = self._schedule.forces(self._ticks_per_step) if self._schedule is not None else None
        self.sim.step(np.clip(target, -lim, lim), self._dt, forces)
        self._steps += 1
        info = self._info()
        truncated = self._steps >= self._max_episode_steps
        return self._observation(), -info["box_goal_distance"], info["is_success"], truncated, info

    def render(self):
        return self.sim.render_image()

    def _observation(self):
        finger, box = self.sim.finger_position(), self.sim.box_position()
        if self.obs_type == "state":
            return np.concatenate([finger, box])
        return {"pixels": self.sim.image(), "agent_pos": finger}

    def _info(self) -> dict:
        box = self.sim.box_position()
        distance = self.scene.box_goal_distance(box)
        tick_s = self.scene.disturbances.tick_s
        return {
            "is_success": bool(distance <= self.scene.success_threshold),
            "box_goal_distance": distance,
            "box": box,
            "finger": self.sim.finger_position(),
            "sim_time_s": self.sim.time,
            "disturbances": [d.to_info(tick_s) for d in self._schedule.started] if self._schedule else [],
            "goal": self.scene.goal_array,
        }


def _size(size) -> tuple[int, int]:
    rows, cols = (size, size) if np.isscalar(size) else size
    if int(rows) != rows or int(cols) != cols or rows < 1 or cols < 1:
        raise ValueError(f"image size must be a positive int or (rows, cols), got {size!r}")
    return int(rows), int(cols)
