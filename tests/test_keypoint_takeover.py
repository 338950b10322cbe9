"""Expert takeover for a keypoint policy (issue 65, step 3): `gcs-push collect` on a keypoint policy's
rollouts labels its stall states with the closed-loop GCS expert, recorded with gym-pusht's keypoints, and
the replay list it writes starts each demonstration where the policy was (checked against the policy run
again to that step) and replays to success in `keypoint_data`."""

import json

import numpy as np
import pytest
from conftest import evaluate_on_pusht

from lerobot_gcs_push.evaluation import LearnedPolicy
from lerobot_gcs_push.generate.replay import REPLAY_META
from lerobot_gcs_push.improve.collect import CollectConfig, collect, rollouts_obs_type
from lerobot_gcs_push.pusht import keypoint_data
from lerobot_gcs_push.pusht.env import GymPushTTarget


def _policy_obs_at(path: str, ic: dict, seed: int, step: int) -> dict:
    """The keypoint observation the policy met at `step` of its run: the run made again, as evaluate made it."""
    policy = LearnedPolicy(path, "cpu")
    env = GymPushTTarget(obs_type=policy.obs_type)
    obs, info = env.reset(seed=seed, options={"pusht_state": ic["pusht_state"]})
    policy.reset(obs, info, seed)
    for _ in range(step):
        obs, *_, info = env.step(policy.act(obs, info))
    return obs


def test_collect_on_keypoint_rollouts_writes_keypoint_demonstrations_from_the_policys_states(keypoint_policy, tmp_path):
    rollouts = tmp_path / "rollouts"
    records = evaluate_on_pusht(keypoint_policy, rollouts, 1)
    assert rollouts_obs_type(records) == "environment_state_agent_pos"
    root = tmp_path / "takeover"
    # two states of the run, its first and last startable chunk starts: two expert episodes, under a minute
    report, states = collect(CollectConfig(rollouts=[str(rollouts)], max_per_run=2, root=str(root), workers=1))
    assert len(states) == 2 and max(s["source"]["step"] for s in states) > 0

    features = json.loads((root / "meta" / "info.json").read_text())["features"]
    assert "observation.environment_state" in features and "observation.image" not in features
    replay = json.loads((root / REPLAY_META).read_text())
    assert replay and [e["pusht_state"] for e in replay] == [s["pusht_state"] for s in states][: len(replay)]

    # each demonstration replays to its success, and starts at what the policy saw at its branch step
    episodes = keypoint_data.load([root / REPLAY_META], progress=False)
    ics = json.loads((rollouts / "settings.json").read_text())["initial_conditions"]
    rec = records[0]
    for start, state in zip(episodes.starts(), states):
        seen = _policy_obs_at(
            keypoint_policy, ics[rec["initial_condition_index"]], rec["seed"], state["source"]["step"]
        )
        np.testing.assert_allclose(episodes.arrays["observation.state"][start], seen["agent_pos"], atol=1e-3)
        np.testing.assert_allclose(
            episodes.arrays["observation.environment_state"][start], seen["environment_state"], atol=1e-3
        )


def test_rollouts_of_policies_that_saw_different_observations_are_collected_apart():
    recs = [{"policy": "a", "obs_type": "environment_state_agent_pos"}, {"policy": "b"}]
    with pytest.raises(ValueError, match="collect one at a time"):
        rollouts_obs_type(recs)
    assert rollouts_obs_type(recs[1:] + [{"policy": "gcs-closed-loop", "obs_type": "x"}]) == "pixels_agent_pos"
