"""The keypoint policy's data, training and export (`lerobot_gcs_push.pusht`): replayed frames against
gym-pusht's geometry, the saved folder's LeRobot processors against the normalisation it was trained with,
and a resumed run against an unbroken one."""

import json
from pathlib import Path

import numpy as np
import pytest
import torch

from lerobot_gcs_push.pusht import keypoint_data
from lerobot_gcs_push.pusht.keypoint_training import (
    KeypointDataConfig,
    ModelConfig,
    ScheduleConfig,
    TrainKeypointsConfig,
    normalise,
    stats_of,
    train,
)

LIST = Path(__file__).parent.parent / "experiments" / "pusht" / "demos" / "seed4800.json"
PRESET = str(Path(__file__).parent.parent / "configs" / "policy" / "diffusion_pusht_keypoints.json")


@pytest.fixture(scope="module")
def episodes():
    return keypoint_data.load([LIST], episodes=3, progress=False)


def test_replayed_frames_start_where_the_list_does_and_the_keypoints_move_rigidly(episodes):
    demos = keypoint_data.read_lists([LIST], 3)
    assert len(episodes) == 3 and episodes.frames == sum(len(d["actions"]) for d in demos)
    for start, demo in zip(episodes.starts(), demos):
        np.testing.assert_allclose(episodes.arrays["observation.state"][start], demo["pusht_state"][:2], atol=1e-3)
        np.testing.assert_array_equal(episodes.arrays["action"][start], np.float32(demo["actions"][0]))
    kp = episodes.arrays["observation.environment_state"].reshape(-1, 8, 2)
    gaps = np.linalg.norm(kp[:, :, None] - kp[:, None], axis=-1)  # a rigid body keeps its keypoints' distances
    np.testing.assert_allclose(gaps, np.broadcast_to(gaps[0], gaps.shape), atol=1e-2)
    assert np.ptp(kp[:, 0], axis=0).max() > 5.0  # and the T was moved


def test_a_list_that_does_not_replay_to_its_success_is_refused(tmp_path):
    demo = keypoint_data.read_lists([LIST], 1)[0]
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps([demo | {"actions": demo["actions"][:3]}]))
    with pytest.raises(ValueError, match="did not end at its success"):
        keypoint_data.load([bad], progress=False)
    with pytest.raises(ValueError, match="episodes asked"):
        keypoint_data.read_lists([LIST], 10**6)


def _config(tmp_path, steps, name="run", partial=None, lst=LIST, episodes=3, warmup=2, init_from=None):
    return TrainKeypointsConfig(
        data=KeypointDataConfig(lists=[str(lst)], episodes=episodes, cache_dir=str(tmp_path / "cache")),
        schedule=ScheduleConfig(steps=steps, batch_size=8, warmup_steps=warmup, save_every=2),
        preset=PRESET,
        output_dir=str(tmp_path / name),
        partial_dir=partial,
        init_from=init_from,
    )


def test_the_saved_folder_normalises_as_training_did_and_a_resumed_run_equals_an_unbroken_one(tmp_path, episodes):
    from lerobot.policies.factory import make_pre_post_processors
    from safetensors.torch import load_file

    whole = train(_config(tmp_path, 6, "whole"), progress=False)
    assert train(_config(tmp_path, 6, "broken"), progress=False, stop_after_s=0.0) is None  # a stage of 1 step
    assert [json.loads(line)["step"] for line in (tmp_path / "broken" / "log.jsonl").read_text().splitlines()] == [1]
    broken = train(_config(tmp_path, 6, "broken"), progress=False)
    a, b = load_file(whole / "model.safetensors"), load_file(broken / "model.safetensors")
    assert a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)

    pre, post = make_pre_post_processors(None, pretrained_path=str(whole))
    stats = stats_of(episodes)
    raw = {k: torch.from_numpy(episodes.arrays[k][:5]) for k in ("observation.state", "observation.environment_state")}
    out = pre(raw)
    for k, v in raw.items():
        np.testing.assert_allclose(out[k].numpy(), normalise(v.numpy(), stats[k]), atol=1e-5)
    back = post(torch.from_numpy(normalise(episodes.arrays["action"][:5], stats["action"])))
    np.testing.assert_allclose(back.numpy(), episodes.arrays["action"][:5], atol=1e-3)


def test_the_models_size_is_what_model_down_dims_asks_and_what_the_folder_loads(tmp_path):
    from lerobot.policies.diffusion.modeling_diffusion import DiffusionPolicy

    cfg = _config(tmp_path, 2, "small")
    cfg.model = ModelConfig(down_dims=[16, 32])
    folder = train(cfg, progress=False)
    assert json.loads((folder / "config.json").read_text())["down_dims"] == [16, 32]
    unet = DiffusionPolicy.from_pretrained(folder).diffusion.unet
    assert [block[0].out_channels for block in unet.down_modules] == [16, 32]  # the blocks, as asked
    with pytest.raises(ValueError, match="positive channel counts"):
        TrainKeypointsConfig(data=cfg.data, model=ModelConfig(down_dims=[16, 0]))
    with pytest.raises(ValueError, match="keeps its base's model"):
        TrainKeypointsConfig(data=cfg.data, model=ModelConfig(down_dims=[16, 32]), init_from=str(folder))


def test_a_run_goes_on_from_the_small_partial_on_another_machine(tmp_path):
    partial = str(tmp_path / "partial")
    assert train(_config(tmp_path, 6, "here", partial), progress=False, stop_after_s=0.0) is None
    # a fresh machine: no local checkpoint, only the committed partial
    folder = train(_config(tmp_path, 6, "there", partial), progress=False)
    log = (tmp_path / "there" / "log.jsonl").read_text().splitlines()
    assert folder.is_dir() and [json.loads(line)["step"] for line in log] == [2, 4, 6]  # went on from step 1


def test_gcs_push_train_reads_its_config_and_names_what_is_missing(capsys, tmp_path):
    """`gcs-push train`: no lists is a one-line error; the committed config's lists and preset are there."""
    import draccus

    from lerobot_gcs_push.cli import main

    assert main(["train"]) == 2
    assert "data.lists is empty" in capsys.readouterr().err
    root = Path(__file__).parent.parent
    cfg = draccus.parse(
        TrainKeypointsConfig, config_path=str(root / "configs" / "train" / "pusht_keypoints.json"), args=[]
    )
    assert cfg.data.episodes == 1000 and all((root / p).is_file() for p in cfg.data.lists[:3])
    assert (cfg.schedule.steps, cfg.schedule.batch_size) == (20000, 64) and (root / cfg.preset).is_file()
    assert main(["train", "--data.lists=[nowhere.json]", f"--output_dir={tmp_path / 'out'}"]) == 2
    assert "no replay list at nowhere.json" in capsys.readouterr().err and not (tmp_path / "out").exists()


def test_training_windows_are_what_lerobot_dataset_gives_the_diffusion_policy(tmp_path):
    """The oracle is LeRobot itself: a LeRobotDataset of the same frames, queried with the diffusion
    policy's own delta indices, gives each sample's observations, actions and padding; the trainer's windows
    must be the same (the action chunk starts at the first observed frame, t - 1, not at t)."""
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    from lerobot_gcs_push.pusht.keypoint_training import Windows, policy_config

    pcfg, _ = policy_config(PRESET)
    rng = np.random.default_rng(0)
    lengths = [13, 9]  # the second shorter than the horizon: padding at both ends
    arrays = {k: rng.normal(size=(sum(lengths), d)).astype(np.float32) for k, d in
              (("observation.state", 2), ("observation.environment_state", 16), ("action", 2))}  # fmt: skip
    data = keypoint_data.Episodes(arrays, np.cumsum(lengths))
    unit = {k: {"min": np.full(v.shape[1], -1.0), "max": np.full(v.shape[1], 1.0)} for k, v in arrays.items()}
    feats = {k: {"dtype": "float32", "shape": (v.shape[1],), "names": None} for k, v in arrays.items()}
    ds = LeRobotDataset.create("local/windows", fps=10, root=tmp_path / "ds", features=feats, use_videos=False)
    for s, e in zip(data.starts(), data.ends):
        for t in range(s, e):
            ds.add_frame({k: v[t] for k, v in arrays.items()} | {"task": "push"})
        ds.save_episode()
    ds.finalize()
    deltas = {
        k: [d / 10 for d in pcfg.observation_delta_indices]
        for k in ("observation.state", "observation.environment_state")
    }
    deltas["action"] = [d / 10 for d in pcfg.action_delta_indices]
    lerobot = LeRobotDataset("local/windows", root=tmp_path / "ds", delta_timestamps=deltas)
    windows = Windows(data, unit, pcfg.n_obs_steps, pcfg.horizon, pcfg.drop_n_last_frames)
    # MIN_MAX over [-1, 1] leaves values as they are (to float32 rounding).
    assert len(windows) == sum(max(n - pcfg.drop_n_last_frames, 1) for n in lengths)
    batch = windows.batch(np.arange(len(windows)))
    for row, t in enumerate(windows.t):
        item = lerobot[int(t)]
        for key in ("observation.state", "observation.environment_state", "action"):
            np.testing.assert_allclose(batch[key][row].numpy(), item[key].numpy(), atol=1e-6, err_msg=f"{key} at {t}")
        assert batch["action_is_pad"][row].tolist() == item["action_is_pad"].tolist(), t
    assert batch["action_is_pad"][:, 0].any() and batch["action_is_pad"][:, -1].any()


LIST2 = LIST.with_name("seed4801.json")


def _fine_tune(tmp_path, base, steps, name):
    return _config(tmp_path, steps, name, lst=LIST2, episodes=2, warmup=1, init_from=base)


def _actions(folder, seed=7, steps=12):
    """A policy's actions in gym-pusht from a reset, through LeRobot's loading and processors."""
    from lerobot_gcs_push.evaluation import LearnedPolicy
    from lerobot_gcs_push.pusht.env import GymPushTTarget

    policy = LearnedPolicy(str(folder), "cpu")
    env = GymPushTTarget(obs_type=policy.obs_type)
    obs, info = env.reset(seed=seed)
    policy.reset(obs, info, seed)
    out = []
    for _ in range(steps):
        out.append(policy.act(obs, info))
        obs, *_, info = env.step(out[-1])
    return np.array(out)


def test_a_fine_tune_starts_from_its_bases_weights_and_statistics(tmp_path, keypoint_policy, episodes):
    """The base (conftest) learned on LIST's first 3 episodes; the fine-tune's data is another list's."""
    from lerobot_gcs_push.pusht.keypoint_training import export, prepare

    run = prepare(_fine_tune(tmp_path, keypoint_policy, 4, "ft"), progress=False)
    base_data, new_data = stats_of(episodes), stats_of(run.data)
    for k in ("observation.state", "observation.environment_state", "action"):
        for s in ("min", "max", "mean", "std"):
            np.testing.assert_allclose(run.stats[k][s], base_data[k][s], rtol=1e-6, atol=1e-6)
    assert not np.allclose(new_data["action"]["min"], base_data["action"]["min"])  # recomputed would differ
    # before any step the weights and their EMA are the base's: its very predictions, once saved as it was
    a, b = run.policy.state_dict(), run.ema.state_dict()
    assert all(torch.equal(a[k], b[k]) for k in a)
    start = export(run.ema, run.pcfg, run.stats, tmp_path / "start")
    base_actions = _actions(keypoint_policy)
    np.testing.assert_array_equal(_actions(start), base_actions)
    assert np.ptp(base_actions, axis=0).max() > 1.0


def test_a_fine_tune_resumes_from_its_checkpoint_not_from_its_base(tmp_path, keypoint_policy):
    from lerobot.policies.factory import make_pre_post_processors
    from lerobot.processor import NormalizerProcessorStep
    from safetensors.torch import load_file

    whole = train(_fine_tune(tmp_path, keypoint_policy, 4, "whole"), progress=False)
    assert train(_fine_tune(tmp_path, keypoint_policy, 4, "broken"), progress=False, stop_after_s=0.0) is None
    broken = train(_fine_tune(tmp_path, keypoint_policy, 4, "broken"), progress=False)
    log = (tmp_path / "broken" / "log.jsonl").read_text().splitlines()
    assert [json.loads(line)["step"] for line in log] == [1, 2, 4]
    a, b, base = (load_file(Path(f) / "model.safetensors") for f in (whole, broken, keypoint_policy))
    assert all(torch.equal(a[k], b[k]) for k in a)  # went on from step 1's checkpoint, as an unbroken run
    assert any(not torch.equal(a[k], base[k]) for k in a)  # and it did train

    # the saved fine-tune normalises as its base: lerobot-eval feeds it inputs on the base's scale
    def saved_stats(folder):
        pre, _ = make_pre_post_processors(None, pretrained_path=str(folder))
        return next(s for s in pre.steps if isinstance(s, NormalizerProcessorStep)).stats

    stats = [saved_stats(f) for f in (whole, keypoint_policy)]
    for k in stats[1]:
        for s in stats[1][k]:
            np.testing.assert_array_equal(np.asarray(stats[0][k][s]), np.asarray(stats[1][k][s]))
    resolved = json.loads((tmp_path / "whole" / "train_config.json").read_text())["resolved"]
    assert resolved["stats_from"] == keypoint_policy and set(resolved["outside_stats_range"]) == {
        "observation.state",
        "observation.environment_state",
        "action",
    }


def test_init_from_must_be_a_keypoint_policy(tmp_path):
    with pytest.raises(FileNotFoundError, match="no pretrained_model folder"):
        _fine_tune(tmp_path, str(tmp_path), 2, "x")
    folder = tmp_path / "image_policy"
    folder.mkdir()
    (folder / "model.safetensors").write_bytes(b"")
    (folder / "config.json").write_text(json.dumps({"type": "diffusion", "input_features": {"observation.image": {}}}))
    with pytest.raises(ValueError, match="not a keypoint diffusion policy"):
        _fine_tune(tmp_path, str(folder), 2, "x")


def test_labels_taken_later_stay_within_their_episode():
    """Hand-computed: episodes of 3 and 2 frames, actions 0..4; two frames later, each episode's last
    action repeats past its end, and the observations are untouched."""
    arrays = {"observation.state": np.arange(10, dtype=np.float32).reshape(5, 2),
              "observation.environment_state": np.zeros((5, 16), np.float32),
              "action": np.repeat(np.arange(5, dtype=np.float32)[:, None], 2, axis=1)}  # fmt: skip
    data = keypoint_data.Episodes(arrays, np.array([3, 5]))
    assert data.labels_ahead(0) is data
    ahead = data.labels_ahead(2)
    assert ahead.arrays["action"][:, 0].tolist() == [2, 2, 2, 4, 4]
    assert ahead.arrays["action"][:, 1].tolist() == [2, 2, 2, 4, 4]
    assert data.labels_ahead(1).arrays["action"][:, 0].tolist() == [1, 2, 2, 4, 4]
    np.testing.assert_array_equal(ahead.arrays["observation.state"], arrays["observation.state"])
    with pytest.raises(ValueError, match="later, not earlier"):
        data.labels_ahead(-1)


def test_held_frames_after_success_bring_the_agent_to_rest_where_it_was():
    """Replayed with frames held after success, each episode is longer by exactly those frames, their
    command is the agent's position at the success, and in gym-pusht's own physics (critically damped PD)
    the agent comes to rest there within the second held."""
    demos = keypoint_data.read_lists([LIST], 2)
    plain = keypoint_data.replay(demos, progress=False)
    held = keypoint_data.replay(demos, progress=False, hold_frames=10)
    assert np.diff(np.concatenate([[0], held.ends])).tolist() == [
        e + 10 for e in np.diff(np.concatenate([[0], plain.ends]))
    ]
    for s_plain, e_plain, e_held in zip(plain.starts(), plain.ends, held.ends):
        s_held = e_held - (e_plain - s_plain) - 10
        for key in keypoint_data.KEYS:  # the demonstration itself is unchanged
            np.testing.assert_array_equal(
                held.arrays[key][s_held : s_held + e_plain - s_plain], plain.arrays[key][s_plain:e_plain]
            )
        tail_action = held.arrays["action"][e_held - 10 : e_held]
        agent = held.arrays["observation.state"][e_held - 10 : e_held]
        np.testing.assert_array_equal(tail_action, np.repeat(agent[:1], 10, axis=0))  # held where it was
        assert np.linalg.norm(agent[-1] - agent[0]) < 1.0 and np.linalg.norm(agent[-1] - agent[-2]) < 0.1
    with pytest.raises(ValueError, match="hold_frames must be >= 0"):
        keypoint_data.load([LIST], 2, None, False, hold_frames=-1)
