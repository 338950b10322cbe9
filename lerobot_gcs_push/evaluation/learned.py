"""A LeRobot checkpoint as a `rollout.Policy`."""

from __future__ import annotations

import numpy as np

from lerobot_gcs_push.scene import TASK


class LearnedPolicy:
    """A LeRobot checkpoint as a `rollout.Policy`, run the way lerobot-eval runs it (processors, action
    queue: a chunk is predicted every `chunk_steps` steps)."""

    def __init__(self, path: str, device: str, task: str = TASK):
        import torch
        from lerobot.configs.policies import PreTrainedConfig
        from lerobot.envs.utils import preprocess_observation
        from lerobot.policies.factory import make_policy, make_pre_post_processors

        from lerobot_gcs_push.lerobot_plugin import GcsPushEnvConfig

        cfg = PreTrainedConfig.from_pretrained(path)
        cfg.pretrained_path = path
        cfg.device = device
        self.policy = make_policy(cfg, env_cfg=GcsPushEnvConfig())
        self.policy.eval()
        self.pre, self.post = make_pre_post_processors(
            cfg, pretrained_path=path, preprocessor_overrides={"device_processor": {"device": device}}
        )
        self.torch, self._preprocess = torch, preprocess_observation  # resolved once, not at every step
        self.task = task  # the env's language instruction, as lerobot-eval passes it
        self.chunk_steps = int(cfg.n_action_steps)  # actions executed per predicted chunk

    def reset(self, obs, info: dict, seed: int | None) -> None:
        # The diffusion sampler's noise comes from torch's global generator: seeded per episode, a run
        # is reproducible whatever ran before it in this process.
        if seed is not None:
            self.torch.manual_seed(seed)
        self.policy.reset()

    def act(self, obs, info: dict) -> np.ndarray:
        batch = self._preprocess({"pixels": obs["pixels"][None], "agent_pos": obs["agent_pos"][None]})
        batch["task"] = [self.task]
        with self.torch.inference_mode():
            action = self.post(self.policy.select_action(self.pre(batch)))
        return action.reshape(-1)[:2].cpu().numpy().astype(np.float64)
