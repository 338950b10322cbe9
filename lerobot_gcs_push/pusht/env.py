"""gym-pusht's own `gym_pusht/PushT-v0` as a target of `generate` and `evaluate`, through the same rollout
and expert seams as the Drake envs (see `GymPushTTarget`)."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np

from lerobot_gcs_push.pusht.frame import (
    ARENA_PX,
    BAR_PX,
    COG_PX,
    GOAL_STATE,
    PX_PER_M,
    PixelFrame,
    check_pusht_state,
    reset_to_state,
)
from lerobot_gcs_push.scene import InitialCondition, Scene, episode_seed

GYM_PUSHT_ID = "gym_pusht/PushT-v0"
GYM_PUSHT_FPS = 10  # gym-pusht's control rate: 10 physics substeps of 0.01 s per action
GYM_PUSHT_STEPS = 300  # its registered episode length (30 s)


class GymPushTTarget(gym.Env):
    """gym-pusht's PushT (huggingface/gym-pusht) with this project's state beside its own.

    ## Description
    The env is gym-pusht's, unchanged: its physics (pymunk), its observations, its reward and success rule
    (coverage > 0.95), its renders. This wrapper only adds, in `info`, the state in this project's metres
    (`scene.frame`: 60 px to the metre, y up), so that the planner's experts and the evaluation's records
    read it as they read the Drake envs'.

    ## Action Space
    gym-pusht's: the agent's target (u, v) in px, `Box(0, 512, (2,))`; targets outside are clipped to it,
    NaN or inf raise ValueError.

    ## Observation Space
    gym-pusht's for `obs_type` ("pixels_agent_pos" by default, as LeRobot's `pusht` env: a 96 x 96 image and
    the agent's position in px; "state": [agent u, v, block u, v, angle]).

    ## Rewards and Success Criteria
    gym-pusht's: clip(coverage / 0.95, 0, 1); `info["is_success"]` when coverage > 0.95.

    ## Starting State
    With no options, gym-pusht's own reset from `seed`. `reset(options={"pusht_state": [ax, ay, bx, by,
    angle]})` starts from a state exactly as `obs_type="state"` reports it (px, radians): the env then reports
    that same state (gym-pusht's `reset_to_state` would move the block; `frame.reset_to_state` passes
    what lands on it). `{"box": [x, y], "finger": [x, y], "heading": h}` does the same in metres (the slider's
    centre of gravity). Agent and block may overlap, as in gym-pusht's own resets.

    ## Episode End
    `terminated` on success, `truncated` after `max_sim_time_s` (30 s, gym-pusht's 300 steps).

    ## Info
    gym-pusht's keys, and in metres: `box` (the T's centre of gravity), `finger`, `slider_pose` (x, y,
    heading), `heading`, `coverage`, `position_error` (= `box_goal_distance`), `heading_error`, `goal`,
    `goal_pose`, `sim_time_s`, `disturbances` (always empty), `pusht_state` (gym-pusht's state vector).

    ## Arguments
    `obs_type`, `fps` (10 only), `max_sim_time_s`, `disturbances` (False only: gym-pusht has none),
    `image_size` (its observation size), `render_size` (its visualization size), `scene` (the registered
    id's), `success_threshold` and `success_coverage` (accepted for the Drake envs' callers; gym-pusht's rule
    decides).
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": GYM_PUSHT_FPS}

    def __init__(
        self,
        obs_type: str = "pixels_agent_pos",
        fps: float = GYM_PUSHT_FPS,
        max_sim_time_s: float = GYM_PUSHT_STEPS / GYM_PUSHT_FPS,
        disturbances: bool = False,
        image_size: int = 96,
        render_size: int = 384,
        scene: Scene | None = None,
        success_threshold: float | None = None,
        success_coverage: float | None = None,
        render_mode: str | None = "rgb_array",
    ):
        import gym_pusht  # noqa: F401  (registers gym_pusht/PushT-v0)

        if fps != GYM_PUSHT_FPS:
            raise ValueError(f"fps: gym-pusht runs at {GYM_PUSHT_FPS} actions a second, got {fps}")
        if disturbances:
            raise ValueError("disturbances: gym-pusht has none; run it without (--disturbances=false)")
        if not max_sim_time_s > 0:
            raise ValueError(f"max_sim_time_s must be positive, got {max_sim_time_s}")
        if success_coverage not in (None, 0.95):
            raise ValueError(f"success_coverage: gym-pusht's rule is coverage > 0.95, got {success_coverage}")
        self.scene = scene if scene is not None else pusht_scene()
        self.frame = self.scene.frame
        self.fps, self.obs_type, self.render_mode = GYM_PUSHT_FPS, obs_type, render_mode
        self._max_episode_steps = math.ceil(max_sim_time_s * self.fps - 1e-9)  # LeRobot's eval reads this
        self.env = gym.make(
            GYM_PUSHT_ID,
            obs_type=obs_type,
            render_mode="rgb_array",
            observation_width=int(image_size),
            observation_height=int(image_size),
            visualization_width=int(render_size),
            visualization_height=int(render_size),
            max_episode_steps=self._max_episode_steps,
            disable_env_checker=True,
        )
        self.action_space = self.env.action_space
        self.observation_space = self.env.observation_space
        self.task = self.task_description = self.scene.task
        self._steps = 0

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        options = dict(options or {})
        state = None
        if "pusht_state" in options:
            state = check_pusht_state(options.pop("pusht_state"))
        elif any(k in options for k in ("box", "finger", "heading")):
            box, finger = self.scene.validate_state(
                options.get("box"), options.get("finger"), heading=options.get("heading", 0.0), allow_overlap=True
            )
            state = self.frame.state_of([*box, float(options.get("heading", 0.0))], finger)
        reset_options = None if state is None else {"reset_to_state": reset_to_state(state)}
        # gym-pusht draws its reset from the seed alone (a RandomState of its own): None would be a fresh draw.
        if seed is None and state is None:
            seed = int(self.np_random.integers(2**31 - 1))
        obs, info = self.env.reset(seed=seed, options=reset_options)
        self._steps = 0
        return obs, self._info(info)

    def step(self, action):
        target = np.asarray(action, dtype=np.float64)
        if target.shape != (2,):
            raise ValueError(f"action must be an agent target [u, v] in px, got shape {target.shape}")
        if not np.all(np.isfinite(target)):
            raise ValueError(f"action must be finite, got {target.tolist()} (NaN or inf)")
        obs, reward, terminated, truncated, info = self.env.step(np.clip(target, 0.0, ARENA_PX))
        self._steps += 1
        return obs, float(reward), bool(terminated), bool(truncated), self._info(info)

    def render(self):
        return self.env.render()

    def close(self):
        self.env.close()

    def _info(self, raw: dict) -> dict:
        scene, frame = self.scene, self.frame
        block = np.asarray(raw["block_pose"], float)
        pose = frame.pose_of_block(block)
        finger = frame.to_m(raw["pos_agent"])
        # gym-pusht reports coverage after a step only; at a reset the shape's own (exact) clipping gives it.
        coverage = float(raw["coverage"]) if "coverage" in raw else scene.coverage(pose)
        distance = scene.box_goal_distance(pose[:2])
        return {
            **raw,
            "is_success": bool(raw.get("is_success", False)),
            "coverage": coverage,
            "box": pose[:2],
            "finger": finger,
            "slider_pose": pose,
            "heading": float(pose[2]),
            "box_goal_distance": distance,
            "position_error": distance,
            "heading_error": scene.heading_error(pose[2]),
            "goal": scene.goal_array,
            "goal_pose": scene.goal_pose,
            "sim_time_s": self._steps / self.fps,
            "disturbances": [],
            "pusht_state": np.array([*np.asarray(raw["pos_agent"], float), *block[:2], block[2] % (2 * math.pi)]),
        }


def reset_states(scene: Scene, n: int, seed: int) -> list:
    """The first `n` of gym-pusht's own resets from seeds of `seed` (`scene.episode_seed`), as initial
    conditions: the start in metres and gym-pusht's state vector, which a reset lands on exactly."""
    env = GymPushTTarget(obs_type="state", scene=scene)
    out = []
    for i in range(n):
        state, info = env.reset(seed=episode_seed(seed, i))
        out.append(
            InitialCondition(
                tuple(map(float, info["box"])),
                tuple(map(float, info["finger"])),
                heading=float(info["heading"]),
                pusht_state=tuple(map(float, state)),
            )
        )
    env.close()
    return out


def pusht_scene() -> Scene:
    """gym-pusht's facts in metres (../shared/design/pusht-notes.md has them measured): its T about its
    centre of gravity, a first-order block under frictionless contact (the limit surface of its mass
    matrix, sqrt(I / m) = sqrt(3000) px), the agent's 15 px radius and its PD lag (kv / kp = 0.2 s, as
    push_lag_s = box_damping / (finger_mass kp)), the goal, starts anywhere gym-pusht's resets put them
    (centres of gravity u in [100, 400), v in [145, 445) px; agents in [50, 450) px) and its 30 s."""
    frame = PixelFrame()
    goal = frame.pose_of_block(GOAL_STATE)
    return Scene(
        slider="tee",
        rotates=True,
        tee_bar_length=BAR_PX / PX_PER_M,
        slider_pivot="parts",
        limit_surface_radius=math.sqrt(3000.0) / PX_PER_M,
        finger_radius=15.0 / PX_PER_M,
        finger_box_friction=0.0,
        box_damping=20.0,
        kp=100.0,
        kd=20.0,
        goal=(float(goal[0]), float(goal[1])),
        goal_heading=float(goal[2]),
        box_init_half_width=(400.0 + COG_PX[1] - 256.0) / PX_PER_M,
        finger_init_half_width=200.0 / PX_PER_M,
        timeout_s=GYM_PUSHT_STEPS / GYM_PUSHT_FPS,
        frame=frame,
    )
