"""`GcsPushBox-v0`, `GcsPushBoxSE2-v0` and `GcsPushT-v0`: one Gymnasium env class over the Drake pushing
scene; the ids differ only in their `Scene` (registration.py). See `GcsPushEnv` for the spaces."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import gymnasium as gym
import numpy as np

from lerobot_gcs_push.registration import ENV_ID, SE2_ENV_ID, TEE_ENV_ID, register_envs  # noqa: F401  (re-exported)
from lerobot_gcs_push.scene import (
    HARD_SAMPLERS,
    TASK,
    Disturbances,
    Scene,
    check_sampler,
    sample_initial_conditions,
    wrap_angle,
)
from lerobot_gcs_push.shapes import SliderShape
from lerobot_gcs_push.sim import PushSim
from lerobot_gcs_push.sim.spaces import action_space, observation_space

OBS_TYPES = ("pixels_agent_pos", "environment_state_agent_pos", "state")

# A force along +x pushes on the box's left (-x) face, and so on.
_DIRECTIONS = (((1.0, 0.0), "left"), ((-1.0, 0.0), "right"), ((0.0, 1.0), "bottom"), ((0.0, -1.0), "top"))


@dataclass(frozen=True)
class Disturbance:
    tick: int  # onset, in ticks since the episode start
    force: tuple[float, float]  # N, on the box centre
    face: str  # the face the force pushes on (for a rotating slider: the side of it that faces -force)
    point: tuple[float, float] | None = None  # a rotating slider's: where the force acts, in its own frame
    torque: float | None = None  # ... and the torque about its centroid (N*m), fixed at the onset

    def to_info(self, tick_s: float) -> dict:
        out = {"t": round(self.tick * tick_s, 9), "force": list(self.force), "face": self.face}
        if self.point is not None:
            out |= {"point": list(self.point), "torque": self.torque}
        return out

    @property
    def wrench(self) -> tuple[float, ...]:
        return self.force if self.torque is None else (*self.force, self.torque)


class DisturbanceSchedule:
    """The paper's random pushes on the box (section IV-A), drawn tick by tick from `rng`.

    At every tick, while fewer than `max_count` have started, a disturbance starts with probability
    `probability_per_tick`; it pushes one of the four faces, chosen uniformly, with a magnitude uniform in
    `force_range_n`, for `duration_ticks` ticks. A new one may start while another acts (the protocol
    draws at every tick); their forces add.

    With a rotating slider's `shape`, the force also twists: it acts at a point drawn uniformly (by
    length) on the faces it pushes into (those whose outward normal opposes it) at the slider's heading
    when drawn, and the disturbance is the constant wrench (force, torque about the centroid) it gives
    then. The box's draws are unchanged, so are its disturbances for a seed.
    """

    def __init__(self, protocol: Disturbances, rng: np.random.Generator, shape: SliderShape | None = None):
        self.protocol = protocol
        self.rng = rng
        self.shape = shape
        self.started: list[Disturbance] = []
        self._tick = 0

    def forces(self, n_ticks: int, heading: float = 0.0) -> np.ndarray | None:
        """Forces (n_ticks, 2) for the next `n_ticks` ticks, or None when none acts; with a shape, wrenches
        (n_ticks, 3) = (fx, fy, torque), those starting now placed on the slider at `heading`."""
        p = self.protocol
        start, end = self._tick, self._tick + n_ticks
        # Tick by tick, so the draws (and so the disturbances of a seed) do not depend on the env's fps.
        for tick in range(start, end):
            if len(self.started) >= p.max_count:
                break
            if self.rng.random() < p.probability_per_tick:
                magnitude = self.rng.uniform(*p.force_range_n)
                (dx, dy), face = _DIRECTIONS[self.rng.integers(len(_DIRECTIONS))]
                force = (magnitude * dx, magnitude * dy)
                if self.shape is None:
                    self.started.append(Disturbance(tick, force, face))
                else:
                    point = self._point_pushed(np.array([dx, dy]), heading)
                    c, s = math.cos(heading), math.sin(heading)
                    r = (c * point[0] - s * point[1], s * point[0] + c * point[1])
                    torque = r[0] * force[1] - r[1] * force[0]
                    self.started.append(Disturbance(tick, force, face, point, float(torque)))
        width = 2 if self.shape is None else 3
        out = None
        for d in self.started:
            lo, hi = max(d.tick, start), min(d.tick + p.duration_ticks, end)
            if lo < hi:
                out = np.zeros((n_ticks, width)) if out is None else out
                out[lo - start : hi - start] += d.wrench
        self._tick = end
        return out

    def _point_pushed(self, direction: np.ndarray, heading: float) -> tuple[float, float]:
        """A point, uniform by length, on the faces that `direction` (world) pushes into, in the slider's
        frame."""
        local = np.array(
            [
                math.cos(heading) * direction[0] + math.sin(heading) * direction[1],
                -math.sin(heading) * direction[0] + math.cos(heading) * direction[1],
            ]
        )
        faces = [(a, b) for a, b, normal in self.shape.faces() if normal @ local < -1e-9]
        lengths = np.array([np.linalg.norm(b - a) for a, b in faces])
        u = self.rng.uniform(0.0, lengths.sum())
        i = min(int(np.searchsorted(np.cumsum(lengths), u)), len(faces) - 1)
        a, b = faces[i]
        t = np.clip((u - lengths[:i].sum()) / lengths[i], 0.0, 1.0)  # rounding may put u a hair past a face
        return tuple(float(v) for v in a + t * (b - a))


class GcsPushEnv(gym.Env):
    """A finger pushes a slider on a plane, in Drake, to a goal: the paper's box that cannot turn
    (`GcsPushBox-v0`), a box that turns (`GcsPushBoxSE2-v0`) or gym-pusht's T (`GcsPushT-v0`).

    ## Description
    A sphere finger under a PID controller pushes a slider resting on damped joints (quasi-static ground
    friction: pushed, it moves; released, it stops). The registered ids differ only in their `Scene`
    (its slider, that slider's kind, `goal_heading`); every dimension, gain and rule comes from it.

    ## Action Space
    `Box(-finger_limit, finger_limit, (2,), float64)`: the absolute finger target (x, y) in metres, held
    for 1/fps s of simulated time. Targets outside the box are clipped to it; NaN or inf raise ValueError
    (a silent clip would hide a broken policy).

    ## Observation Space (`obs_type`)
    - "pixels_agent_pos" (default): {"pixels": uint8 (H, W, 3) top-down image with the goal drawn (a
      filled square for the box that cannot turn, the goal pose's outline for a rotating slider),
      "agent_pos": float64 (2,) finger x, y}.
    - "environment_state_agent_pos": {"environment_state": float64 (3,) slider [x, y, heading] (heading
      in [-pi, pi), 0 for the box that cannot turn), "agent_pos"}.
    - "state": float64 (4,) [finger x, finger y, box x, box y] (the paper's state); for a rotating slider
      (5,) [finger x, finger y, slider x, slider y, heading].

    ## Rewards
    The box that cannot turn: minus the box-goal distance (m). A rotating slider: gym-pusht's
    min(coverage / success_coverage, 1), coverage being the share of the goal outline's area it covers.

    ## Success Criteria
    `info["is_success"]`: the box centre within `success_threshold` m of the goal; a rotating slider
    covers at least `success_coverage` (0.95, gym-pusht's rule) of the goal outline's area.

    ## Starting State
    Sampled by `scene.sample_initial_conditions` with `sampler` from the env's seed: the slider's centre
    uniform over [-box_init_half_width, box_init_half_width]^2, the finger's over
    [-finger_init_half_width, finger_init_half_width]^2, a rotating slider's heading uniform in [-pi, pi),
    redrawn until finger and slider do not overlap (Drake's query). `reset(options={"box": [x, y],
    "finger": [x, y], "heading": radians})` sets it instead (heading defaults to 0).

    ## Episode End
    `terminated` on success, `truncated` after `max_sim_time_s` of simulated time.

    ## Info
    Always: `is_success`, `box_goal_distance` (m), `box` (slider x, y), `finger`, `sim_time_s`,
    `disturbances`, `goal` (x, y). A rotating slider adds `coverage`, `position_error` (m, = the
    distance), `heading_error` (radians, wrapped to [-pi, pi)), `heading`, `slider_pose` (x, y, heading)
    and `goal_pose`.

    ## Arguments
    `obs_type`, `fps` (env steps per simulated second), `max_sim_time_s`, `disturbances` (the paper's
    random pushes; a rotating slider's also twist it, see `DisturbanceSchedule`), `image_size`,
    `success_threshold` (m), `success_coverage`, `goal` ((x, y), or (x, y, heading) for a rotating
    slider), `render_mode` ("rgb_array"), `scene` (default: the registered id's), `sampler` ("uniform",
    "sobol", "hard" and "hard_v2": the box only), `render_size` (of `render()`).

    ## Version History
    - v0: the paper's box; the SE(2) box and the T added with rotation (issue 32).
    """

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
        success_coverage: float | None = None,
    ):
        if obs_type not in OBS_TYPES:
            raise ValueError(f"obs_type must be one of {OBS_TYPES}, got {obs_type!r}")
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode must be 'rgb_array' or None, got {render_mode!r}")
        check_sampler(sampler)
        if not max_sim_time_s > 0:
            raise ValueError(f"max_sim_time_s must be positive, got {max_sim_time_s}")
        scene = scene if scene is not None else Scene()
        if sampler in HARD_SAMPLERS and not scene.kind.hard_starts:
            raise ValueError(f"sampler {sampler!r} is for the box that cannot rotate: choose 'uniform' or 'sobol'")
        if goal is not None:
            scene = scene.with_goal(goal)
        if success_threshold is not None:
            scene = dataclasses.replace(scene, success_threshold=float(success_threshold))
        if success_coverage is not None:
            scene = dataclasses.replace(scene, success_coverage=float(success_coverage))
        rows, cols = _size(image_size)
        scene = dataclasses.replace(scene, camera=dataclasses.replace(scene.camera, height=rows, width=cols))
        self.scene, self.obs_type, self.fps, self.sampler = scene, obs_type, fps, sampler
        self.max_sim_time_s, self.disturbances, self.render_mode = max_sim_time_s, disturbances, render_mode
        self.task = self.task_description = scene.task
        self.sim = PushSim(scene, render_size=_size(render_size))
        self._dt = 1.0 / fps
        self.sim.steps_in(self._dt)  # raises unless 1/fps is a whole number of disturbance ticks
        self._ticks_per_step = int(round(self._dt / scene.disturbances.tick_s))
        self._max_episode_steps = math.ceil(max_sim_time_s * fps - 1e-9)  # LeRobot's eval reads this
        self.metadata = {**self.metadata, "render_fps": fps}

        self.action_space = action_space(scene)
        self.observation_space = observation_space(scene, obs_type)
        self._schedule: DisturbanceSchedule | None = None
        self._steps = 0

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        if options and ("box" in options or "finger" in options or "heading" in options):
            heading = options.get("heading", 0.0)
            box, finger = self.scene.validate_state(options.get("box"), options.get("finger"), heading=heading)
            heading = float(heading)
            if self.sim.collides(box, finger, heading):
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
            box, finger, heading = np.array(ic.box), np.array(ic.finger), ic.heading or 0.0
        self.sim.reset(box, finger, heading)
        self._steps = 0
        twist = self.scene.kind.twist(self.scene)
        self._schedule = (
            DisturbanceSchedule(self.scene.disturbances, self.np_random, twist) if self.disturbances else None
        )
        return self._observation(), self._info()

    def step(self, action):
        target = np.asarray(action, dtype=np.float64)
        if target.shape != (2,):
            raise ValueError(f"action must be a finger target [x, y], got shape {target.shape}")
        if not np.all(np.isfinite(target)):
            raise ValueError(f"action must be finite, got {target.tolist()} (NaN or inf)")
        lim = self.scene.finger_limit
        forces = None
        if self._schedule is not None:
            forces = self._schedule.forces(self._ticks_per_step, self.sim.box_heading())
        self.sim.step(np.clip(target, -lim, lim), self._dt, forces)
        self._steps += 1
        info = self._info()
        truncated = self._steps >= self._max_episode_steps
        reward = self.scene.kind.reward(self.scene, info)
        return self._observation(), reward, info["is_success"], truncated, info

    def render(self):
        return self.sim.render_image()

    def _slider_pose(self) -> np.ndarray:
        """[x, y, heading], the heading wrapped to [-pi, pi)."""
        return np.array([*self.sim.box_position(), wrap_angle(self.sim.box_heading())])

    def _observation(self):
        finger = self.sim.finger_position()
        if self.obs_type == "state":
            return np.concatenate([finger, self.scene.kind.state(self._slider_pose())])
        if self.obs_type == "environment_state_agent_pos":
            return {"environment_state": self._slider_pose(), "agent_pos": finger}
        return {"pixels": self.sim.image(), "agent_pos": finger}

    def _info(self) -> dict:
        box = self.sim.box_position()
        distance = self.scene.box_goal_distance(box)
        tick_s = self.scene.disturbances.tick_s
        judged = self.scene.kind.judge(self.scene, self._slider_pose(), distance)  # success and the pose's keys
        return {
            "is_success": judged.pop("is_success"),
            "box_goal_distance": distance,
            "box": box,
            "finger": self.sim.finger_position(),
            "sim_time_s": self.sim.time,
            "disturbances": [d.to_info(tick_s) for d in self._schedule.started] if self._schedule else [],
            "goal": self.scene.goal_array,
        } | judged


def _size(size) -> tuple[int, int]:
    rows, cols = (size, size) if np.isscalar(size) else size
    if int(rows) != rows or int(cols) != cols or rows < 1 or cols < 1:
        raise ValueError(f"image size must be a positive int or (rows, cols), got {size!r}")
    return int(rows), int(cols)
