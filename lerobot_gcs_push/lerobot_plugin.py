"""LeRobot env configs: `lerobot-train` / `lerobot-eval --env.type=gcs_push` (the box, `GcsPushBox-v0`),
`gcs_push_se2` (the rotating box, `GcsPushBoxSE2-v0`) and `gcs_push_t` (the T, `GcsPushT-v0`).

LeRobot 0.6.1 finds them through the `lerobot_env_gcs_push` shim (imported for every installed
distribution named `lerobot_env_*`), which imports this module.

Each config names one of the package's gym ids: lerobot-eval's async vector env builds each env in a
forkserver worker that unpickles the config, which imports the package and so registers the ids.
"""

from dataclasses import dataclass, field

from lerobot.configs import FeatureType, PolicyFeature
from lerobot.envs.configs import EnvConfig
from lerobot.utils.constants import ACTION, OBS_IMAGE, OBS_STATE

from lerobot_gcs_push.registration import ENV_ID, SE2_ENV_ID, TEE_ENV_ID
from lerobot_gcs_push.scene import Scene


@EnvConfig.register_subclass("gcs_push")
@dataclass
class GcsPushEnvConfig(EnvConfig):
    task: str | None = ENV_ID
    fps: int = Scene.fps
    episode_length: int = round(Scene.timeout_s * Scene.fps)  # steps: the paper's 500 s timeout
    success_threshold: float = Scene.success_threshold  # m, box centre to goal
    disturbances: bool = False  # the paper's random pushes on the box
    image_size: int = 96
    obs_type: str = "pixels_agent_pos"
    render_mode: str = "rgb_array"
    features: dict[str, PolicyFeature] = field(
        default_factory=lambda: {
            ACTION: PolicyFeature(type=FeatureType.ACTION, shape=(2,)),
            "agent_pos": PolicyFeature(type=FeatureType.STATE, shape=(2,)),
        }
    )
    features_map: dict[str, str] = field(
        default_factory=lambda: {ACTION: ACTION, "agent_pos": OBS_STATE, "pixels": OBS_IMAGE}
    )

    def __post_init__(self):
        if self.obs_type != "pixels_agent_pos":
            # LeRobot's preprocess_observation only understands dict observations.
            raise ValueError(f"gcs_push supports obs_type='pixels_agent_pos' only, got {self.obs_type!r}")
        self.features["pixels"] = PolicyFeature(type=FeatureType.VISUAL, shape=(self.image_size, self.image_size, 3))

    @property
    def package_name(self) -> str:
        return "lerobot_gcs_push"  # what create_envs imports if the gym id is not registered yet

    @property
    def gym_id(self) -> str:
        return self.task

    @property
    def gym_kwargs(self) -> dict:
        return {
            "obs_type": self.obs_type,
            "render_mode": self.render_mode,
            "fps": self.fps,
            "image_size": self.image_size,
            "success_threshold": self.success_threshold,
            "disturbances": self.disturbances,
            "max_sim_time_s": self.episode_length / self.fps,
            "max_episode_steps": self.episode_length,
        }


@dataclass
class _RotatingSliderConfig(GcsPushEnvConfig):
    """A rotating slider succeeds by coverage of the goal outline, not by a distance: the env gets
    `success_coverage` and keeps its scene's distance threshold (which it does not use)."""

    success_coverage: float = Scene.success_coverage  # share of the goal outline's area covered

    @property
    def gym_kwargs(self) -> dict:
        kwargs = {k: v for k, v in super().gym_kwargs.items() if k != "success_threshold"}
        return {**kwargs, "success_coverage": self.success_coverage}


@EnvConfig.register_subclass("gcs_push_se2")
@dataclass
class GcsPushSE2EnvConfig(_RotatingSliderConfig):
    task: str | None = SE2_ENV_ID


@EnvConfig.register_subclass("gcs_push_t")
@dataclass
class GcsPushTEnvConfig(_RotatingSliderConfig):
    task: str | None = TEE_ENV_ID
