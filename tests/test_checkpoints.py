"""The shipped policy directory: half-precision export, loading as LeRobot does, no unpack step."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from lerobot_gcs_push.artifacts.checkpoints import MODEL_FILE, STEP_FILE, export_policy, is_pretrained_dir

SHIPPED = Path(__file__).resolve().parents[1] / "policies" / "diffusion_cpu"


def test_the_shipped_policy_is_a_pretrained_model_directory_in_fp16():
    from safetensors.torch import load_file

    assert is_pretrained_dir(SHIPPED)
    tensors = load_file(SHIPPED / MODEL_FILE)
    floats = [t for t in tensors.values() if t.is_floating_point()]
    assert floats and all(str(t.dtype) == "torch.float16" for t in floats)
    assert (SHIPPED / MODEL_FILE).stat().st_size < 32 * 2**20  # the repository's limit per version
    config = json.loads((SHIPPED / "config.json").read_text())
    assert config["type"] == "diffusion" and config["pretrained_path"] is None and config["use_amp"] is False


def test_export_round_trip_is_exact_and_atomic(tmp_path):
    """fp16 -> fp32 -> fp16 gives back the very same tensors (every fp16 value is an fp32 value), and a
    refused export leaves nothing behind."""
    import torch
    from safetensors.torch import load_file

    wide = export_policy(SHIPPED, tmp_path / "fp32", dtype="float32")
    narrow = export_policy(wide, tmp_path / "fp16", dtype="float16")
    a, b = load_file(SHIPPED / MODEL_FILE), load_file(narrow / MODEL_FILE)
    assert a.keys() == b.keys()
    for k in a:
        assert torch.equal(a[k], b[k]), k
    with pytest.raises(FileExistsError):
        export_policy(SHIPPED, narrow)
    with pytest.raises(FileNotFoundError, match="pretrained_model"):
        export_policy(tmp_path / "nothing", tmp_path / "out")
    with pytest.raises(ValueError, match="dtype"):
        export_policy(SHIPPED, tmp_path / "int", dtype="int8")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fp16", "fp32"]  # no staging folder left


def test_a_step_is_written_only_into_a_partial_and_never_copied_out_of_one(tmp_path):
    """A training partial records its step; a policy exported from that partial does not, so it is
    never taken for a partial to resume (training.partial_step reads the step from there)."""
    from lerobot_gcs_push.improve.training import partial_step

    partial = export_policy(SHIPPED, tmp_path / "partial", step=1500)
    assert json.loads((partial / STEP_FILE).read_text()) == {"step": 1500}
    assert partial_step(partial) == 1500
    policy = export_policy(partial, tmp_path / "policy")
    assert not (policy / STEP_FILE).exists() and partial_step(policy) == 0
    assert sorted(p.name for p in policy.iterdir()) == sorted(p.name for p in SHIPPED.iterdir())


def test_the_shipped_policy_acts_through_lerobots_factory_as_it_is():
    """Loaded by LeRobot's own factory and processors with no unpack step; its first chunk is a finger
    target inside the commandable square, and the same seed gives the same action."""
    import gymnasium as gym

    import lerobot_gcs_push  # noqa: F401
    from lerobot_gcs_push.evaluation import LearnedPolicy

    env = gym.make("GcsPushBox-v0", render_size=96).unwrapped
    obs, info = env.reset(seed=0)
    policy = LearnedPolicy(str(SHIPPED), "cpu")
    actions = []
    for _ in range(2):
        policy.reset(obs, info, seed=5)
        actions.append(policy.act(obs, info))
    np.testing.assert_array_equal(actions[0], actions[1])
    assert actions[0].shape == (2,) and np.all(np.abs(actions[0]) <= env.scene.finger_limit + 0.5)
    assert policy.chunk_steps == 8


KEYPOINTS = SHIPPED.with_name("diffusion_pusht_keypoints")


def test_the_shipped_keypoint_policy_runs_in_lerobots_own_pusht_env_as_it_is():
    """`policies/diffusion_pusht_keypoints`: fp16, no unpack step, and LeRobot's own pusht env with
    `obs_type="environment_state_agent_pos"` (its make_env and observation mapping, not this package's)
    feeds it; its actions are agent targets inside gym-pusht's 512 px arena, the same for the same seed."""
    import torch
    from lerobot.envs.configs import PushtEnv
    from lerobot.envs.utils import preprocess_observation
    from lerobot.policies.diffusion.modeling_diffusion import DiffusionPolicy
    from lerobot.policies.factory import make_pre_post_processors
    from safetensors.torch import load_file

    assert is_pretrained_dir(KEYPOINTS)
    floats = [t for t in load_file(KEYPOINTS / MODEL_FILE).values() if t.is_floating_point()]
    assert floats and all(str(t.dtype) == "torch.float16" for t in floats)
    policy = DiffusionPolicy.from_pretrained(KEYPOINTS)
    assert set(policy.config.input_features) == {"observation.state", "observation.environment_state"}
    pre, post = make_pre_post_processors(policy.config, pretrained_path=str(KEYPOINTS))
    import gym_pusht  # noqa: F401  (registers gym_pusht/PushT-v0, as LeRobot's make_env imports it)
    import gymnasium as gym

    env_cfg = PushtEnv(obs_type="environment_state_agent_pos")

    assert env_cfg.gym_kwargs["obs_type"] == "environment_state_agent_pos"
    env = gym.make(f"gym_pusht/{env_cfg.task}", **env_cfg.gym_kwargs)
    obs, _ = env.reset(seed=3)
    runs = []
    for _ in range(2):
        torch.manual_seed(7)
        policy.reset()
        batch = pre(preprocess_observation({k: v[None] for k, v in obs.items()}))
        with torch.inference_mode():
            runs.append(post(policy.select_action(batch)).numpy().reshape(-1))
    env.close()
    np.testing.assert_array_equal(runs[0], runs[1])
    assert runs[0].shape == (2,) and np.all((runs[0] > -20) & (runs[0] < 532))
