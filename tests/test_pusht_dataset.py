"""Issue 47, item 3: `gcs-push generate --env_id=gym_pusht/PushT-v0` writes lerobot/pusht's format.

The slow tests share one generate of 2 episodes (the expert plans through contact: a first compile of the
relaxation and up to a minute an episode) from starts a few px and degrees off gym-pusht's goal. They check
the written dataset against lerobot/pusht's features and, as independent evidence, replay its actions in a
fresh gym-pusht env, which must report the same agent positions, rewards and success at the same frame.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from lerobot_gcs_push.pusht.dataset import PUSHT_FEATURE_KEYS, PushTFrames, pusht_features
from lerobot_gcs_push.registration import PUSHT_ENV_ID

BIN = Path(sys.executable).parent
REPO_ID = "local/gcs_pusht"
# gym-pusht's state [agent u, v, block u, v, angle] (px, rad): blocks a few px and degrees off the goal
# (256, 256, pi / 4), from which the closed-loop expert succeeds within a few seconds.
STARTS = [[256.0, 400.0, 256.0, 262.0, 0.785], [150.0, 150.0, 262.0, 258.0, 0.85]]
# lerobot/pusht's features, beside LeRobot's own bookkeeping columns: (dtype, shape).
PUSHT = {
    "observation.image": ("video", (96, 96, 3)),
    "observation.state": ("float32", (2,)),
    "action": ("float32", (2,)),
    "next.reward": ("float32", (1,)),
    "next.done": ("bool", (1,)),
    "next.success": ("bool", (1,)),
}


# --- fast: the feature list and the frame recorder -------------------------------------------------------
def test_features_are_lerobot_pushts_and_what_its_pusht_env_gives():
    from lerobot.envs.configs import PushtEnv

    feats = pusht_features(96)
    assert {k: (v["dtype"], tuple(v["shape"])) for k, v in feats.items()} == PUSHT
    assert tuple(feats) == PUSHT_FEATURE_KEYS
    assert "observation.environment_state" not in feats
    # LeRobot's --env.type=pusht (pixels_agent_pos) gives exactly the observations the dataset holds.
    env = PushtEnv()
    assert env.obs_type == "pixels_agent_pos" and env.fps == 10
    given = {env.features_map[k] for k in env.features if k != "action"}
    assert given == {k for k in feats if k.startswith("observation.")}


def test_frames_hold_what_each_step_returned():
    """A hand policy that never moves the block: the episode runs out (3 steps), each frame holds the
    observation its action was chosen from and the reward and success of the step that followed."""
    from lerobot_gcs_push.episodes.rollout import rollout
    from lerobot_gcs_push.registration import make_env

    env = make_env(PUSHT_ENV_ID, max_sim_time_s=0.3)

    class Hold:
        def reset(self, obs, info, seed):
            self.seen = []

        def act(self, obs, info):
            self.seen.append(np.array(obs["agent_pos"], np.float32))
            return np.array([600.0, 20.5])  # outside the arena: clipped, and recorded as run

    frames, policy = PushTFrames(env), Hold()
    result = rollout(frames.env, policy, pusht_state=[100.0, 100.0, 300.0, 300.0, 0.0])
    env.close()
    a = frames.arrays()
    assert len(frames) == 3 and not result["success"]
    assert {k: (str(v.dtype) if k != "observation.image" else "video", v.shape[1:]) for k, v in a.items()} == {
        k: (dtype if k != "observation.image" else "video", shape) for k, (dtype, shape) in PUSHT.items()
    }
    assert a["observation.image"].dtype == np.uint8
    np.testing.assert_array_equal(a["observation.state"], np.stack(policy.seen))
    np.testing.assert_array_equal(a["observation.state"][0], [100.0, 100.0])
    np.testing.assert_array_equal(a["action"], np.tile(np.float32([512.0, 20.5]), (3, 1)))
    assert a["next.done"][:, 0].tolist() == [False, False, True]
    assert not a["next.success"].any()
    assert np.all((a["next.reward"] >= 0) & (a["next.reward"] < 1))


# --- slow: one generate, read back and replayed --------------------------------------------------------
@pytest.fixture(scope="module")
def pusht_dataset(tmp_path_factory):
    from lerobot_gcs_push.generate import GenerateConfig, generate

    home = tmp_path_factory.mktemp("lerobot_home")
    starts = home / "starts.json"
    starts.write_text(json.dumps([{"pusht_state": s} for s in STARTS]))
    root = home / REPO_ID
    cfg = GenerateConfig(
        env_id=PUSHT_ENV_ID,
        episodes=2,
        repo_id=REPO_ID,
        root=str(root),
        initial_conditions=str(starts),
        workers=1,
        progress=False,
    )
    assert cfg.expert.mode == "closed-loop" and cfg.max_sim_time_s == 30.0  # gym-pusht's own 300 steps
    report = generate(cfg)
    assert (report.episodes, report.failures) == (2, 0), report
    return home, root, report


def _episodes(root: Path) -> list[dict]:
    """Each episode's non-video columns as numpy arrays, in order."""
    import pyarrow.parquet as pq

    table = pq.read_table(sorted((root / "data").rglob("*.parquet"))).to_pandas()
    out = []
    for _, rows in table.groupby("episode_index", sort=True):
        rows = rows.sort_values("frame_index")
        # Shape-(1,) features are stored as scalars: (frames, 1) here, as the features say.
        out.append({k: np.stack(rows[k].to_numpy()).reshape(len(rows), -1) for k in PUSHT if k != "observation.image"})
    return out


@pytest.mark.slow
def test_generate_writes_lerobot_pushts_features(pusht_dataset):
    from lerobot.datasets.lerobot_dataset import LeRobotDataset
    from lerobot.utils.constants import DEFAULT_FEATURES

    from lerobot_gcs_push.generate import read_episode_metadata

    _, root, report = pusht_dataset
    ds = LeRobotDataset(REPO_ID, root=root, video_backend="pyav")
    written = {k: (v["dtype"], tuple(v["shape"])) for k, v in ds.meta.features.items() if k not in DEFAULT_FEATURES}
    assert written == PUSHT
    assert ds.meta.video_keys == ["observation.image"] and ds.meta.camera_keys == ["observation.image"]
    assert ds.fps == 10 and ds.num_episodes == 2
    metas = read_episode_metadata(root)
    assert [m["pusht_state_initial"] for m in metas] == STARTS
    assert all(m["success"] for m in metas)
    assert ds.num_frames == report.frames == sum(m["num_frames"] for m in metas)
    item = ds[0]
    assert tuple(item["observation.image"].shape) == (3, 96, 96)
    assert tuple(item["observation.state"].shape) == (2,) and tuple(item["action"].shape) == (2,)


@pytest.mark.slow
def test_generated_episodes_replay_in_a_fresh_gym_pusht(pusht_dataset):
    """Independent of the writer: gym-pusht itself, reset to each start and fed the stored actions, reports
    the stored agent positions, rewards and images, and succeeds (terminates) at the stored last frame."""
    import gym_pusht  # noqa: F401
    import gymnasium as gym
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    from lerobot_gcs_push.generate import read_episode_metadata
    from lerobot_gcs_push.pusht.frame import reset_to_state

    _, root, _ = pusht_dataset
    ds = LeRobotDataset(REPO_ID, root=root, video_backend="pyav")
    metas = read_episode_metadata(root)
    start_index = 0
    for meta, ep in zip(metas, _episodes(root), strict=True):
        n = len(ep["action"])
        assert n == meta["num_frames"] > 1
        assert np.all((ep["action"] >= 0) & (ep["action"] <= 512))
        assert ep["next.done"][:, 0].tolist() == [False] * (n - 1) + [True]
        assert ep["next.success"][-1, 0] and not ep["next.success"][:-1].any()  # ends at its first success
        options = {"reset_to_state": reset_to_state(meta["pusht_state_initial"])}
        state_env = gym.make("gym_pusht/PushT-v0", obs_type="state")
        pixel_env = gym.make("gym_pusht/PushT-v0", obs_type="pixels_agent_pos")
        state, _ = state_env.reset(options=options)
        pixels, _ = pixel_env.reset(options=options)
        np.testing.assert_allclose(state, meta["pusht_state_initial"], atol=1e-6)
        for t in range(n):
            assert np.array_equal(ep["observation.state"][t], np.float32(state[:2])), t
            if t in (0, n // 2, n - 1):  # gym-pusht's own render, through the video codec
                image = ds[start_index + t]["observation.image"].numpy().transpose(1, 2, 0)
                assert np.abs(image - pixels["pixels"] / 255.0).mean() < 0.01, t  # codec error: ~0.004
            state, reward, terminated, truncated, info = state_env.step(ep["action"][t])
            pixels, *_ = pixel_env.step(ep["action"][t])
            assert np.float32(reward) == ep["next.reward"][t, 0], t
            assert info["is_success"] == ep["next.success"][t, 0], t
            assert terminated == (t == n - 1) and not truncated, t
        assert info["is_success"]
        state_env.close()
        pixel_env.close()
        start_index += n


def _replayed(pusht_dataset, name: str, **kwargs):
    """(folder, config) of a dataset rebuilt from the module's dataset's replay list, beside it."""
    from lerobot_gcs_push.generate import GenerateConfig
    from lerobot_gcs_push.generate.replay import REPLAY_META

    home, root, _ = pusht_dataset
    folder = home / "local" / name
    cfg = GenerateConfig(
        env_id=PUSHT_ENV_ID,
        repo_id=f"local/{name}",
        root=str(folder),
        initial_conditions=str(root / REPLAY_META),
        workers=1,
        progress=False,
        **kwargs,
    )
    return folder, cfg


@pytest.mark.slow
def test_its_replay_list_rebuilds_it_value_for_value(pusht_dataset):
    """`meta/gcs_push_replay.json` (starts and actions) replayed with no planning: every stored value and
    every video frame as the expert's run wrote them (gym-pusht runs the stored float32 actions)."""
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    from lerobot_gcs_push.generate import generate

    home, root, report = pusht_dataset
    copy, cfg = _replayed(pusht_dataset, "gcs_pusht_replayed")
    assert cfg.expert.mode == "replay"
    assert generate(cfg).frames == report.frames
    for a, b in zip(_episodes(root), _episodes(copy), strict=True):
        for key in a:
            assert np.array_equal(a[key], b[key]), key
    source = LeRobotDataset(REPO_ID, root=root, video_backend="pyav")
    rebuilt = LeRobotDataset("local/gcs_pusht_replayed", root=copy, video_backend="pyav")
    for t in (0, report.frames // 2, report.frames - 1):  # decoded frames: the same encoder on the same images
        assert np.array_equal(source[t]["observation.image"].numpy(), rebuilt[t]["observation.image"].numpy()), t


@pytest.mark.slow
def test_its_keypoint_twin_holds_what_lerobots_pusht_env_gives_with_environment_state(pusht_dataset):
    """The same replay list written with `obs_type="environment_state_agent_pos"`: the image's place taken by
    `observation.environment_state` (16 float32), every other value the pixel dataset's; and each episode's
    first keypoints are what LeRobot's own observation mapping makes of gym-pusht's reset to that start."""
    import gymnasium as gym
    from lerobot.envs.utils import preprocess_observation

    from lerobot_gcs_push.generate import GenerateConfig, generate
    from lerobot_gcs_push.generate.replay import REPLAY_META
    from lerobot_gcs_push.pusht.frame import reset_to_state

    home, root, report = pusht_dataset
    twin, cfg = _replayed(pusht_dataset, "gcs_pusht_keypoints", obs_type="environment_state_agent_pos")
    assert generate(cfg).frames == report.frames
    info = json.loads((twin / "meta" / "info.json").read_text())
    assert "observation.image" not in info["features"]
    assert info["features"]["observation.environment_state"]["shape"] == [16]
    import pyarrow.parquet as pq

    table = pq.read_table(sorted((twin / "data").rglob("*.parquet"))).to_pandas()
    starts = json.loads((root / REPLAY_META).read_text())
    env = gym.make("gym_pusht/PushT-v0", obs_type="environment_state_agent_pos")
    for (_, rows), pixel, start in zip(table.groupby("episode_index", sort=True), _episodes(root), starts, strict=True):
        rows = rows.sort_values("frame_index")
        for key in ("observation.state", "action"):
            assert np.array_equal(np.stack(rows[key].to_numpy()), pixel[key]), key
        obs, _ = env.reset(options={"reset_to_state": reset_to_state(start["pusht_state"])})
        mapped = preprocess_observation({k: v[None] for k, v in obs.items()})
        kp = np.stack(rows["observation.environment_state"].to_numpy())
        np.testing.assert_allclose(kp[0], mapped["observation.environment_state"][0].numpy(), atol=1e-4)
        assert np.ptp(kp, axis=0).max() > 1.0  # the T moved
    with pytest.raises(ValueError, match="obs_type"):
        GenerateConfig(env_id=PUSHT_ENV_ID, repo_id="local/x", obs_type="state")


def _lerobot(args: list[str], home: Path, cwd: Path) -> None:
    """One of LeRobot's console scripts, offline, on the datasets in `home` (as tests/test_lerobot_plugin.py)."""
    env = {
        **os.environ,
        "HF_HUB_OFFLINE": "1",
        "HF_LEROBOT_HOME": str(home),
        "MPLBACKEND": "Agg",
        "WANDB_MODE": "disabled",
        "OMP_NUM_THREADS": "1",
    }
    env.pop("PYTHONPATH", None)
    proc = subprocess.run(args, cwd=cwd, env=env, capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, f"{' '.join(args)}:\n{proc.stdout[-3000:]}\n{proc.stderr[-6000:]}"


@pytest.fixture(scope="module")
def pusht_checkpoint(pusht_dataset, tmp_path_factory) -> Path:
    """LeRobot's own lerobot-train: --env.type=pusht, a (tiny) diffusion policy, 2 steps."""
    home, _, _ = pusht_dataset
    work = tmp_path_factory.mktemp("train")
    out = work / "run"
    _lerobot(
        [
            str(BIN / "lerobot-train"),
            f"--dataset.repo_id={REPO_ID}",
            "--dataset.video_backend=pyav",
            "--env.type=pusht",
            "--policy.type=diffusion",
            "--policy.device=cpu",
            "--policy.push_to_hub=false",
            "--policy.down_dims=[32,64]",
            "--policy.pretrained_backbone_weights=null",  # offline: no torchvision download
            "--policy.use_group_norm=true",
            "--steps=2",
            "--batch_size=2",
            "--num_workers=0",
            "--env_eval_freq=0",
            "--save_freq=2",
            "--log_freq=1",
            "--wandb.enable=false",
            f"--output_dir={out}",
        ],
        home,
        work,
    )
    return out / "checkpoints" / "last" / "pretrained_model"


@pytest.mark.slow
def test_lerobot_train_accepts_it_with_the_pusht_env(pusht_checkpoint):
    config = json.loads((pusht_checkpoint / "config.json").read_text())
    assert set(config["input_features"]) == {"observation.image", "observation.state"}
    assert config["input_features"]["observation.image"]["shape"] == [3, 96, 96]
    assert set(config["output_features"]) == {"action"}


@pytest.mark.slow
def test_lerobot_eval_runs_it_in_the_pusht_env(pusht_dataset, pusht_checkpoint, tmp_path):
    """LeRobot's lerobot-eval in gym-pusht (--env.type=pusht), its images at the dataset's 96 px (LeRobot's
    pusht config renders 384 px unless told), one short episode."""
    home, _, _ = pusht_dataset
    out = tmp_path / "eval"
    _lerobot(
        [
            str(BIN / "lerobot-eval"),
            f"--policy.path={pusht_checkpoint}",
            "--env.type=pusht",
            "--env.observation_height=96",
            "--env.observation_width=96",
            "--env.episode_length=10",
            "--eval.n_episodes=1",
            "--eval.batch_size=1",
            "--eval.use_async_envs=false",
            "--policy.device=cpu",
            f"--output_dir={out}",
        ],
        home,
        tmp_path,
    )
    overall = json.loads((out / "eval_info.json").read_text())["overall"]
    assert overall["n_episodes"] == 1 and 0.0 <= overall["avg_max_reward"] <= 1.0
