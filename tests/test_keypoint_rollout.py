"""A keypoint policy rolled out by `gcs-push evaluate` (issue 65, step 3): its env gives gym-pusht's keypoints,
its batch is what LeRobot's own `pusht` env and preprocessing give, and its records hold the slider's pose
at every step, from which the stall rule reads coverage."""

import json

import numpy as np
import pytest
import torch
from conftest import evaluate_on_pusht

from lerobot_gcs_push.evaluation import LearnedPolicy
from lerobot_gcs_push.evaluation.learned import KEYPOINTS_OBS, PIXELS_OBS, obs_type_of
from lerobot_gcs_push.pusht.env import GymPushTTarget
from lerobot_gcs_push.registration import PUSHT_ENV_ID, SCENES

STEPS = 20  # a few chunks of 8


def test_the_obs_type_is_the_policys_inputs():
    assert obs_type_of({"observation.state": 0, "observation.environment_state": 0}) == KEYPOINTS_OBS
    assert obs_type_of({"observation.state": 0, "observation.image": 0}) == PIXELS_OBS
    with pytest.raises(ValueError, match="no env obs_type gives both"):
        obs_type_of({"observation.image": 0, "observation.environment_state": 0})
    with pytest.raises(ValueError, match="neither"):
        obs_type_of({"observation.state": 0})
    assert obs_type_of({}) == PIXELS_OBS  # no features of its own: make_policy gives it the env's (images)


def _ours(path: str, seed: int):
    """Our env and LearnedPolicy: each step's batch (before the policy's processors) and action."""
    policy = LearnedPolicy(path, "cpu")
    env = GymPushTTarget(obs_type=policy.obs_type)
    policy.check_env(env)
    obs, info = env.reset(seed=seed)
    policy.reset(obs, info, seed)
    batches, actions = [], []
    for _ in range(STEPS):
        batches.append(policy.batch(obs))
        actions.append(policy.act(obs, info))
        obs, _, _, _, info = env.step(actions[-1])
    return batches, np.array(actions)


def _lerobots(path: str, seed: int, actions):
    """LeRobot's own `pusht` env (lerobot-eval's vector env) and preprocessing, the policy loaded as
    lerobot-eval loads it, stepped with `actions`: each step's batch and LeRobot's own action."""
    from lerobot.configs.policies import PreTrainedConfig
    from lerobot.envs.configs import PushtEnv
    from lerobot.envs.factory import make_env, make_env_pre_post_processors
    from lerobot.envs.utils import preprocess_observation
    from lerobot.policies.factory import make_policy, make_pre_post_processors

    env_cfg = PushtEnv(obs_type="environment_state_agent_pos")
    vec = make_env(env_cfg, n_envs=1)["pusht"][0]
    cfg = PreTrainedConfig.from_pretrained(path)
    cfg.pretrained_path = path
    policy = make_policy(cfg, env_cfg=env_cfg)
    policy.eval()
    pre, post = make_pre_post_processors(cfg, pretrained_path=path)
    env_pre, _ = make_env_pre_post_processors(env_cfg, cfg)
    obs, _ = vec.reset(seed=[seed])
    policy.reset()
    torch.manual_seed(seed)
    batches, theirs = [], []
    for action in actions:
        batch = preprocess_observation(obs)
        batches.append(batch)
        with torch.inference_mode():
            theirs.append(post(policy.select_action(pre(env_pre(batch | {"task": [""]})))).numpy().reshape(-1))
        obs, *_ = vec.step(np.asarray(action)[None])
    vec.close()
    return batches, np.array(theirs)


@pytest.mark.parametrize("seed", [5, 71])
def test_the_batch_and_actions_are_lerobots_own_for_the_same_observations(keypoint_policy, seed):
    ours, actions = _ours(keypoint_policy, seed)
    theirs, their_actions = _lerobots(keypoint_policy, seed, actions)
    for a, b in zip(ours, theirs):
        assert set(a) - {"task"} == set(b) == {"observation.state", "observation.environment_state"}
        for k in b:
            assert a[k].dtype == b[k].dtype and torch.equal(a[k], b[k]), k
    # the same noise (seeded alike) on the same batches: lerobot-eval's actions, float32 to float64
    np.testing.assert_allclose(actions, their_actions, atol=1e-4)
    assert np.ptp(actions, axis=0).max() > 1.0  # the policy did move the agent


def test_evaluate_runs_a_keypoint_policy_and_records_its_coverage_at_every_step(keypoint_policy, tmp_path):
    out = tmp_path / "eval"
    records = evaluate_on_pusht(keypoint_policy, out, 2)
    ics = json.loads((out / "settings.json").read_text())["initial_conditions"]
    scene = SCENES[PUSHT_ENV_ID]
    assert len(records) == 2
    for rec in records:
        traj = np.load(out / rec["trajectory"])
        poses = traj["slider_pose"]
        assert len(poses) == round(rec["sim_time_s"] * scene.fps) + 1 == 31  # every step and the final state
        ic = ics[rec["initial_condition_index"]]
        # the run started where gym-pusht's reset put it, and its last pose's coverage is gym-pusht's own
        start = scene.frame.state_of(poses[0], traj["finger"][0])
        np.testing.assert_allclose(start, ic["pusht_state"], atol=1e-6)
        assert scene.coverage(poses[-1]) == pytest.approx(rec["coverage"], abs=2e-3)
