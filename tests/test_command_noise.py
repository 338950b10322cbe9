"""DART's command noise on gym-pusht (issue 65): the env runs each target plus a seeded Gaussian draw, the
dataset records the target, and the replay list holds both, so the episode replays exactly.

The evidence is gym-pusht itself: what a fresh env does with the list's "actions" must be what was
recorded, and what it does with the labels alone must not be."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from lerobot_gcs_push.pusht.dataset import CommandNoise, PushTFrames
from lerobot_gcs_push.registration import PUSHT_ENV_ID

START = [100.0, 100.0, 300.0, 300.0, 0.0]  # agent far from the T: a hand policy moves it in free space


# --- fast ---------------------------------------------------------------------------------------------
def test_draws_are_one_stream_whatever_is_drawn_at_once():
    noise = CommandNoise(7.5, 12345)
    bulk = noise.draws(300)
    rng = np.random.RandomState(12345)
    one_by_one = np.stack([rng.normal(0.0, 7.5, 2) for _ in range(300)])
    np.testing.assert_array_equal(bulk, one_by_one)
    np.testing.assert_array_equal(noise.draws(17), bulk[:17])
    # Gaussian of the stated std (20,000 values: the std's standard error is 0.5 %).
    many = CommandNoise(7.5, 1).draws(10_000).ravel()
    assert abs(many.mean()) < 0.2 and abs(many.std() / 7.5 - 1) < 0.02
    assert not np.array_equal(CommandNoise(7.5, 2).draws(5), noise.draws(5))


def test_commands_run_are_label_plus_draw_clipped_to_the_arena():
    labels = np.array([[256.0, 256.0], [0.5, 511.5], [100.25, 3.0]], np.float32)
    run = CommandNoise(50.0, 3).commands_run(labels)
    draws = np.random.RandomState(3).normal(0.0, 50.0, (3, 2))
    assert run.dtype == np.float32
    for label, d, r in zip(labels, draws, run):
        for c in range(2):
            assert r[c] == np.float32(min(max(float(label[c]) + d[c], 0.0), 512.0))
    assert np.array_equal(CommandNoise(0.0, 3).commands_run(labels), labels)


@pytest.mark.parametrize("spec", [{"std_px": -1, "seed": 0}, {"std_px": float("nan"), "seed": 0},
                                  {"std_px": 1.0, "seed": 2**32}, {"std_px": 1.0}, None])  # fmt: skip
def test_bad_noise_specs_are_refused(spec):
    with pytest.raises(ValueError, match="command noise|command_noise"):
        CommandNoise.of(spec)


def _hand_episode(noise, expected_run=None, steps=12):
    """A hand policy's targets (a slow sweep in free space) recorded under `noise`."""
    from lerobot_gcs_push.episodes.rollout import rollout
    from lerobot_gcs_push.registration import make_env

    env = make_env(PUSHT_ENV_ID, max_sim_time_s=steps / 10, obs_type="environment_state_agent_pos")

    class Sweep:
        def reset(self, obs, info, seed):
            self.k = 0

        def act(self, obs, info):
            self.k += 1
            return np.array([100.0 + 6.0 * self.k, 100.0 + 3.0 * self.k])

    frames = PushTFrames(env, "environment_state_agent_pos", noise, expected_run)
    rollout(frames.env, Sweep(), pusht_state=START)
    env.close()
    return frames.arrays()


def _raw_replay(actions) -> np.ndarray:
    """gym-pusht itself, not this package: the agent positions it reports before each of `actions`."""
    import gym_pusht  # noqa: F401
    import gymnasium as gym

    from lerobot_gcs_push.pusht.frame import reset_to_state

    env = gym.make("gym_pusht/PushT-v0", obs_type="environment_state_agent_pos")
    obs, _ = env.reset(options={"reset_to_state": reset_to_state(START)})
    seen = []
    for a in actions:
        seen.append(np.asarray(obs["agent_pos"], np.float32))
        obs, *_ = env.step(np.asarray(a, np.float64))
    env.close()
    return np.stack(seen)


def test_the_env_runs_label_plus_noise_and_the_frames_hold_the_label():
    noise = CommandNoise(8.0, 99)
    a = _hand_episode(noise)
    labels = a["action"]
    np.testing.assert_array_equal(labels[:3], np.float32([[106, 103], [112, 106], [118, 109]]))
    run = noise.commands_run(labels)
    np.testing.assert_array_equal(_raw_replay(run), a["observation.state"])
    # The noise moved the agent: the labels alone lead elsewhere.
    assert np.abs(_raw_replay(labels) - a["observation.state"]).max() > 1.0
    # Without noise the frames are the plain recorder's.
    plain = _hand_episode(None)
    np.testing.assert_array_equal(plain["action"], labels)
    np.testing.assert_array_equal(_raw_replay(labels), plain["observation.state"])


def test_a_replay_whose_actions_differ_from_its_labels_and_noise_is_refused():
    noise = CommandNoise(8.0, 99)
    labels = _hand_episode(noise)["action"]
    run = noise.commands_run(labels)
    _hand_episode(noise, expected_run=run)  # as recorded: runs through
    bad = run.copy()
    bad[5, 0] += np.float32(0.5)
    with pytest.raises(ValueError, match="step 5"):
        _hand_episode(noise, expected_run=bad)


def test_generate_refuses_noise_where_it_has_no_meaning(tmp_path):
    from lerobot_gcs_push.generate import GenerateConfig

    with pytest.raises(ValueError, match="gym-pusht"):
        GenerateConfig(repo_id="local/x", command_noise_px=3.0)  # the Drake box: metres, not px
    with pytest.raises(ValueError, match="command_noise_px"):
        GenerateConfig(env_id=PUSHT_ENV_ID, repo_id="local/x", command_noise_px=-1.0)
    listed = tmp_path / "list.json"
    listed.write_text(json.dumps([{"pusht_state": START, "actions": [[1.0, 2.0]]}]))
    with pytest.raises(ValueError, match="drop --command_noise_px"):
        GenerateConfig(env_id=PUSHT_ENV_ID, repo_id="local/x", initial_conditions=str(listed), command_noise_px=3.0)
    listed.write_text(
        json.dumps([{"pusht_state": START, "actions": [[1.0, 2.0]], "command_noise": {"std_px": 1, "seed": 1}}])
    )
    with pytest.raises(ValueError, match='no "labels"'):
        GenerateConfig(env_id=PUSHT_ENV_ID, repo_id="local/x", initial_conditions=str(listed))


# --- slow: one DART episode generated, its list replayed two ways ---------------------------------------
@pytest.mark.slow
def test_a_dart_dataset_replays_exactly_and_teaches_its_labels(tmp_path):
    import pyarrow.parquet as pq

    from lerobot_gcs_push.generate import GenerateConfig, generate, read_episode_metadata
    from lerobot_gcs_push.generate.replay import REPLAY_META
    from lerobot_gcs_push.pusht import keypoint_data

    starts = tmp_path / "starts.json"
    # A few px and degrees off gym-pusht's goal: the closed-loop expert succeeds within seconds.
    starts.write_text(json.dumps([{"pusht_state": [256.0, 400.0, 256.0, 262.0, 0.785]}]))
    common = dict(env_id=PUSHT_ENV_ID, repo_id="local/dart", obs_type="environment_state_agent_pos", workers=1,
                  progress=False)  # fmt: skip
    cfg = GenerateConfig(**common, root=str(tmp_path / "src"), initial_conditions=str(starts), command_noise_px=4.0)
    report = generate(cfg)
    assert report.episodes == 1
    root = Path(cfg.output.root)
    (meta,) = read_episode_metadata(root)
    (entry,) = json.loads((root / REPLAY_META).read_text())
    table = pq.read_table(sorted((root / "data").rglob("*.parquet"))).to_pandas().sort_values("frame_index")
    stored = np.stack(table["action"].to_numpy()).astype(np.float32)
    assert meta["command_noise"]["std_px"] == 4.0 and entry["command_noise"] == meta["command_noise"]
    np.testing.assert_array_equal(np.float32(entry["labels"]), stored)
    draws = np.random.RandomState(meta["command_noise"]["seed"]).normal(0.0, 4.0, stored.shape)
    np.testing.assert_array_equal(np.float32(entry["actions"]), np.clip(stored + draws, 0, 512).astype(np.float32))
    assert np.abs(np.float32(entry["actions"]) - stored).max() > 1.0
    # gym-pusht itself, running the list's actions, passes through the recorded states and succeeds last.
    data = keypoint_data.replay([entry], progress=False)
    np.testing.assert_array_equal(data.arrays["action"], stored)
    np.testing.assert_array_equal(data.arrays["observation.state"], np.stack(table["observation.state"].to_numpy()))
    # `generate --expert=replay` rebuilds it value for value (and checks every step's run command).
    copy = GenerateConfig(**common, root=str(tmp_path / "copy"), initial_conditions=str(root / REPLAY_META))
    assert copy.expert.mode == "replay" and generate(copy).frames == report.frames
    again = (
        pq.read_table(sorted((tmp_path / "copy" / "data").rglob("*.parquet"))).to_pandas().sort_values("frame_index")
    )
    for key in ("action", "observation.state", "observation.environment_state", "next.reward"):
        assert np.array_equal(np.stack(again[key].to_numpy()), np.stack(table[key].to_numpy())), key
    assert json.loads((tmp_path / "copy" / REPLAY_META).read_text()) == [entry]
