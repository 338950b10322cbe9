"""A LeRobot checkpoint as a `rollout.Policy`, and the env observation type its inputs need."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from lerobot_gcs_push.scene import TASK

# LeRobot's feature keys and the env observations its `preprocess_observation` maps to them: an image policy
# reads the env's pixels, a keypoint policy its environment_state (gym-pusht's 8 keypoints of the T).
IMAGE, ENV_STATE = "observation.image", "observation.environment_state"
PIXELS_OBS, KEYPOINTS_OBS = "pixels_agent_pos", "environment_state_agent_pos"


def obs_type_of(input_features) -> str:
    """The env `obs_type` whose observations hold what a policy with these input features reads (LeRobot's
    `--env.obs_type`). Chosen from the policy's own config, so a keypoint policy needs no flag of its own."""
    keys = set(input_features)
    if not keys:  # LeRobot's make_policy gives such a config the env's features: pixels and agent_pos
        return PIXELS_OBS
    if ENV_STATE in keys and IMAGE in keys:
        raise ValueError(f"a policy reading both {IMAGE} and {ENV_STATE}: no env obs_type gives both")
    if ENV_STATE in keys:
        return KEYPOINTS_OBS
    if IMAGE in keys:
        return PIXELS_OBS
    raise ValueError(f"the policy reads {sorted(keys)}: neither {IMAGE} nor {ENV_STATE}, which the envs give")


def policy_obs_type(path: str) -> str:
    """`obs_type_of` a pretrained_model folder's config.json (read as JSON: neither the weights nor LeRobot's
    policy registry are loaded, so an evaluation's settings are checked in a moment)."""
    return obs_type_of(json.loads((Path(path) / "config.json").read_text()).get("input_features", {}))


class LearnedPolicy:
    """A LeRobot checkpoint as a `rollout.Policy`, run the way lerobot-eval runs it (processors, action
    queue: a chunk is predicted every `chunk_steps` steps). Its env must be made with `obs_type`."""

    def __init__(self, path: str, device: str, task: str = TASK):
        import torch
        from lerobot.configs.policies import PreTrainedConfig
        from lerobot.envs.utils import preprocess_observation
        from lerobot.policies.factory import make_policy, make_pre_post_processors

        from lerobot_gcs_push.lerobot_plugin import GcsPushEnvConfig

        cfg = PreTrainedConfig.from_pretrained(path)
        cfg.pretrained_path = path
        cfg.device = device
        self.obs_type = obs_type_of(cfg.input_features)
        self.input_shapes = {k: tuple(f.shape) for k, f in cfg.input_features.items()}
        # The env config only fills features a config lacks; a saved policy has its own.
        self.policy = make_policy(cfg, env_cfg=GcsPushEnvConfig())
        self.policy.eval()
        self.pre, self.post = make_pre_post_processors(
            cfg, pretrained_path=path, preprocessor_overrides={"device_processor": {"device": device}}
        )
        self.torch, self._preprocess = torch, preprocess_observation  # resolved once, not at every step
        self.task = task  # the env's language instruction, as lerobot-eval passes it
        self.chunk_steps = int(cfg.n_action_steps)  # actions executed per predicted chunk

    def check_env(self, env) -> None:
        """Refuse an env whose observations the policy cannot read (another obs_type, or a Drake scene's
        3-value slider pose where the policy learned gym-pusht's 16 keypoint coordinates)."""
        if getattr(env, "obs_type", self.obs_type) != self.obs_type:
            raise ValueError(f"the policy reads obs_type {self.obs_type}, the env gives {env.obs_type}")
        space = getattr(env.observation_space, "spaces", {})
        if ENV_STATE in self.input_shapes and "environment_state" in space:
            have, want = tuple(space["environment_state"].shape), self.input_shapes[ENV_STATE]
            if have != want:
                raise ValueError(f"the policy reads {want} values of environment_state, this env gives {have}")

    def reset(self, obs, info: dict, seed: int | None) -> None:
        # The diffusion sampler's noise comes from torch's global generator: seeded per episode, a run
        # is reproducible whatever ran before it in this process.
        if seed is not None:
            self.torch.manual_seed(seed)
        self.policy.reset()

    def batch(self, obs) -> dict:
        """One env observation as lerobot-eval hands it to the policy's processors: a batch of one, mapped by
        LeRobot's own `preprocess_observation` (pixels or environment_state, and agent_pos), with the task."""
        batch = self._preprocess({k: np.asarray(v)[None] for k, v in obs.items()})
        batch["task"] = [self.task]
        return batch

    def act(self, obs, info: dict) -> np.ndarray:
        with self.torch.inference_mode():
            action = self.post(self.policy.select_action(self.pre(self.batch(obs))))
        return action.reshape(-1)[:2].cpu().numpy().astype(np.float64)
