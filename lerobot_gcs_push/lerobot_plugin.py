"""LeRobot env config `gcs_push`: `lerobot-train` / `lerobot-eval --env.type=gcs_push`.

LeRobot 0.6.1 finds it through the `lerobot_env_gcs_push` shim (imported for every installed
distribution named `lerobot_env_*`), which imports this module.

Importing `lerobot_gcs_push` at the top is deliberate: lerobot-eval's async vector env builds each
env in a forkserver worker that unpickles this config (and so imports this module) before calling
`gym.make`; the import registers the gym ids there too.
"""

from dataclasses import dataclass, field

from lerobot.configs import FeatureType, PolicyFeature
from lerobot.envs.configs import EnvConfig
from lerobot.utils.constants import ACTION, OBS_IMAGE, OBS_STATE

import lerobot_gcs_push  # noqa: F401  (registers GcsPushBox-v0 and gym_gcs_push/GcsPushBox-v0)


@EnvConfig.register_subclass("gcs_push")
@dataclass
class GcsPushEnvConfig(EnvConfig):
    task: str | None = "GcsPushBox-v0"
    fps: int = 10
    episode_length: int = 5000  # steps; 500 s of simulated time at 10 fps, the paper's timeout
    success_threshold: float = 0.1  # m, box centre to goal
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
        self.features["pixels"] = PolicyFeature(
            type=FeatureType.VISUAL, shape=(self.image_size, self.image_size, 3)
        )

    @property
    def package_name(self) -> str:
        return "lerobot_gcs_push"  # what create_envs imports if the gym id is not registered yet

    @property
    def gym_id(self) -> str:
        return f"gym_gcs_push/{self.task}"

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
