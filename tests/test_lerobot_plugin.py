"""The LeRobot plugin: `gcs_push` env config, discovery, and the real lerobot-train / lerobot-eval CLIs.

The CLI tests run LeRobot's console scripts in subprocesses from a temporary working directory, so the
env config can only come from LeRobot's own plugin discovery (the `lerobot_env_gcs_push` distribution),
never from an import in this file. One tiny dataset (2 episodes, in a temporary HF_LEROBOT_HOME) and
one 2-step checkpoint are shared by the whole session.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
REPO_ID = "local/gcs_push_box"
CPU_PRESET = REPO / "configs" / "policy" / "diffusion_cpu.json"
PAPER_PRESET = REPO / "configs" / "policy" / "diffusion_paper.json"
ENV_CONFIGS = [REPO / "configs" / "env" / "gcs_push.json", REPO / "configs" / "env" / "gcs_push_disturbances.json"]


# --- session fixtures -----------------------------------------------------------------------------------
@pytest.fixture(scope="session")
def lerobot_home(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("lerobot_home")


@pytest.fixture(scope="session")
def tiny_dataset(lerobot_home) -> Path:
    from lerobot_gcs_push.generate import GenerateConfig, generate

    root = lerobot_home / REPO_ID
    generate(GenerateConfig(episodes=2, repo_id=REPO_ID, root=str(root), workers=1, progress=False))
    return root


def _run(args: list[str], home: Path, cwd: Path, timeout: float = 600) -> subprocess.CompletedProcess:
    # One OpenMP thread: the models here are tiny, and on a small machine shared with other jobs a
    # second spinning thread per process slows everything down many times over.
    env = {
        **os.environ,
        "HF_HUB_OFFLINE": "1",
        "HF_LEROBOT_HOME": str(home),
        "MPLBACKEND": "Agg",
        "WANDB_MODE": "disabled",
        "OMP_NUM_THREADS": "1",
    }
    env.pop("PYTHONPATH", None)  # only the installed distribution may provide the plugin
    proc = subprocess.run(args, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    if proc.returncode != 0:
        pytest.fail(
            f"{' '.join(map(str, args))} failed ({proc.returncode}):\n{proc.stdout[-3000:]}\n{proc.stderr[-6000:]}"
        )
    return proc


@pytest.fixture(scope="session")
def checkpoint(tiny_dataset, lerobot_home, tmp_path_factory) -> Path:
    """A 2-step run of the CPU preset with a tiny U-Net, through the real lerobot-train."""
    work = tmp_path_factory.mktemp("train")
    out = work / "run"
    _run(
        [
            str(BIN / "lerobot-train"),
            f"--config_path={CPU_PRESET}",
            f"--dataset.repo_id={REPO_ID}",
            "--steps=2",
            "--batch_size=2",
            "--num_workers=0",
            "--policy.down_dims=[32,64]",
            "--env_eval_freq=0",
            "--save_freq=2",
            "--log_freq=1",
            f"--output_dir={out}",
        ],
        home=lerobot_home,
        cwd=work,
    )
    return out / "checkpoints" / "last" / "pretrained_model"


def _eval_info(out: Path) -> dict:
    return json.loads((out / "eval_info.json").read_text())["overall"]


# --- the config itself ----------------------------------------------------------------------------------
def test_env_config_kwargs_and_env():
    import gymnasium as gym
    import numpy as np
    from lerobot.envs import make_env, make_env_config
    from lerobot.envs.utils import env_to_policy_features

    import lerobot_gcs_push.lerobot_plugin  # noqa: F401

    cfg = make_env_config("gcs_push", episode_length=7, disturbances=True, success_threshold=0.05)
    assert cfg.type == "gcs_push"
    assert cfg.gym_kwargs["max_episode_steps"] == 7
    assert cfg.gym_kwargs["max_sim_time_s"] == pytest.approx(0.7)
    assert cfg.gym_kwargs["disturbances"] is True
    assert env_to_policy_features(cfg) == {
        "action": cfg.features["action"],
        "observation.state": cfg.features["agent_pos"],
        "observation.image": type(cfg.features["pixels"])(type=cfg.features["pixels"].type, shape=(3, 96, 96)),
    }
    assert make_env_config("gcs_push").episode_length == 5000  # the paper's 500 s timeout at 10 fps

    vec = make_env(cfg, n_envs=1)["gcs_push"][0]
    try:
        obs, _ = vec.reset(seed=0)
        assert obs["pixels"].shape == (1, 96, 96, 3) and obs["pixels"].dtype == np.uint8
        assert obs["agent_pos"].shape == (1, 2)
        assert vec.call("_max_episode_steps") == (7,)
        assert vec.call("task_description")[0] == vec.call("task")[0] != ""
        env = vec.envs[0].unwrapped
        assert env.disturbances and env.scene.success_threshold == 0.05 and env.max_sim_time_s == pytest.approx(0.7)
        for step in range(1, 8):
            *_, terminated, truncated, _ = vec.step(obs["agent_pos"])
            if terminated[0]:
                break
            assert truncated[0] == (step == 7)
    finally:
        vec.close()
    assert isinstance(vec, gym.vector.SyncVectorEnv)

    with pytest.raises(ValueError, match="pixels_agent_pos"):
        make_env_config("gcs_push", obs_type="state")


@pytest.mark.parametrize("path", ENV_CONFIGS, ids=lambda p: p.stem)
def test_env_config_files_decode(path):
    import draccus
    from lerobot.envs.configs import EnvConfig

    import lerobot_gcs_push.lerobot_plugin  # noqa: F401

    cfg = draccus.decode(EnvConfig, json.loads(path.read_text())["env"])
    assert cfg.type == "gcs_push" and cfg.episode_length == 5000
    assert cfg.disturbances == ("disturbances" in path.stem)


@pytest.mark.parametrize("path", [CPU_PRESET, PAPER_PRESET], ids=lambda p: p.stem)
def test_policy_presets(path):
    import draccus
    import lerobot.policies  # noqa: F401
    from lerobot.configs.policies import PreTrainedConfig
    from lerobot.envs.configs import EnvConfig

    import lerobot_gcs_push.lerobot_plugin  # noqa: F401

    raw = json.loads(path.read_text())
    policy = draccus.decode(PreTrainedConfig, raw["policy"])
    assert (policy.n_obs_steps, policy.horizon, policy.n_action_steps) == (1, 16, 8)
    assert policy.drop_n_last_frames == policy.horizon - policy.n_action_steps - policy.n_obs_steps + 1
    # The paper crops 84x84 at random; the CPU preset sees the whole fixed view (see configs/README.md).
    assert policy.crop_shape == ((84, 84) if path == PAPER_PRESET else None)
    assert policy.pretrained_backbone_weights is None
    assert not policy.push_to_hub and policy.use_group_norm and policy.device == "cpu"
    # The env has no box position, so the policy must not take observation.environment_state.
    assert set(policy.input_features) == {"observation.image", "observation.state"}
    assert raw["dataset"] == {"repo_id": REPO_ID, "video_backend": "pyav"}
    assert draccus.decode(EnvConfig, raw["env"]).type == "gcs_push"
    assert raw["wandb"]["enable"] is False and raw["output_dir"].startswith("outputs/train/")


# --- LeRobot's discovery and CLIs ----------------------------------------------------------------------
def test_discovered_by_lerobot(tmp_path):
    code = (
        "from lerobot.utils.import_utils import register_third_party_plugins\n"
        "register_third_party_plugins()\n"
        "from lerobot.envs.configs import EnvConfig\n"
        "assert 'gcs_push' in EnvConfig.get_known_choices(), EnvConfig.get_known_choices()\n"
    )
    _run([sys.executable, "-c", code], home=tmp_path, cwd=tmp_path)


def test_dataset_through_lerobot_factory(tiny_dataset):
    import draccus
    import lerobot.policies  # noqa: F401
    import torch
    from lerobot.configs.default import DatasetConfig
    from lerobot.configs.policies import PreTrainedConfig
    from lerobot.configs.train import TrainPipelineConfig
    from lerobot.datasets.factory import make_dataset

    policy = draccus.decode(PreTrainedConfig, json.loads(CPU_PRESET.read_text())["policy"])
    cfg = TrainPipelineConfig(
        dataset=DatasetConfig(repo_id=REPO_ID, root=str(tiny_dataset), video_backend="pyav"), policy=policy
    )
    dataset = make_dataset(cfg)
    assert dataset.num_episodes == 2 and dataset.fps == 10
    item = dataset[0]
    assert item["action"].shape == (16, 2) and item["action"].dtype == torch.float32
    assert item["observation.image"].shape == (1, 3, 96, 96)
    assert item["observation.state"].shape == (1, 2)
    assert item["action_is_pad"].shape == (16,) and not item["action_is_pad"].any()
    last = dataset[dataset.meta.episodes["dataset_to_index"][0] - 1]  # padded past the episode end
    assert last["action_is_pad"][1:].all()


@pytest.mark.slow
def test_lerobot_train_cli(checkpoint):
    assert (checkpoint / "model.safetensors").is_file()
    cfg = json.loads((checkpoint / "config.json").read_text())
    assert cfg["type"] == "diffusion" and cfg["down_dims"] == [32, 64] and cfg["noise_scheduler_type"] == "DDIM"
    train_cfg = json.loads((checkpoint / "train_config.json").read_text())
    assert train_cfg["env"]["type"] == "gcs_push" and train_cfg["steps"] == 2


def _check_success_matches_reward(out):
    """LeRobot's success (the env's is_success) agrees with its reward (minus the box-goal distance):
    an episode succeeded exactly when its best reward reached -0.1 m."""
    metrics = json.loads((out / "eval_info.json").read_text())["per_task"][0]["metrics"]
    successes, best = metrics["successes"], metrics["max_rewards"]
    assert successes and len(successes) == len(best)
    for ok, reward in zip(successes, best):
        assert ok == (reward >= -0.1), (ok, reward)
    assert _eval_info(out)["pc_success"] == pytest.approx(100.0 * sum(successes) / len(successes))


@pytest.mark.slow
def test_lerobot_eval_cli(checkpoint, lerobot_home, tmp_path):
    out = tmp_path / "eval"
    _run(
        [
            str(BIN / "lerobot-eval"),
            f"--policy.path={checkpoint}",
            f"--config_path={ENV_CONFIGS[0]}",
            "--env.episode_length=30",
            "--eval.n_episodes=1",
            "--eval.batch_size=1",
            "--eval.use_async_envs=false",
            "--policy.device=cpu",
            f"--output_dir={out}",
        ],
        home=lerobot_home,
        cwd=tmp_path,
    )
    overall = _eval_info(out)
    assert overall["n_episodes"] == 1
    _check_success_matches_reward(out)


@pytest.mark.slow
def test_lerobot_eval_cli_async_disturbances(checkpoint, lerobot_home, tmp_path):
    """lerobot-eval's default AsyncVectorEnv: each env is built in a forkserver worker."""
    out = tmp_path / "eval"
    _run(
        [
            str(BIN / "lerobot-eval"),
            f"--policy.path={checkpoint}",
            "--env.type=gcs_push",
            "--env.disturbances=true",
            "--env.episode_length=10",
            "--eval.n_episodes=2",
            "--eval.batch_size=2",
            "--policy.device=cpu",
            f"--output_dir={out}",
        ],
        home=lerobot_home,
        cwd=tmp_path,
    )
    overall = _eval_info(out)
    assert overall["n_episodes"] == 2
    _check_success_matches_reward(out)


@pytest.mark.slow
def test_gcs_push_evaluate_runs_a_lerobot_checkpoint(checkpoint, tmp_path):
    """Issue 6: a LeRobot checkpoint evaluates end to end through `gcs-push evaluate` (LeRobot's factory
    and processors); whatever its success rate, its records must be complete and consistent."""
    import numpy as np

    from lerobot_gcs_push.evaluation import EvaluateConfig, evaluate, read_runs

    out = tmp_path / "eval"
    summary = evaluate(
        EvaluateConfig(
            policies=[str(checkpoint)],
            num_initial_conditions=2,
            runs=1,
            disturbances=True,
            timeout_s=3.0,
            output_dir=str(out),
            videos=0,
        )
    )
    recs = read_runs(out / "runs.jsonl")
    assert len(recs) == 4  # 2 ICs x (without, with disturbances)
    assert {r["disturbances"] for r in recs} == {False, True}
    for r in recs:
        assert r["plan_time_s"] == 0.0 and r["run_time_s"] > 0
        traj = np.load(out / r["trajectory"])
        assert r["sim_time_s"] == pytest.approx((len(traj["finger"]) - 1) / 10, abs=1e-6)
        np.testing.assert_allclose(traj["finger"][0], r["finger_initial"], atol=1e-6)
        # The recorded final distance is the trajectory's last box position, measured independently.
        assert r["final_distance"] == pytest.approx(np.linalg.norm(traj["box"][-1]), abs=1e-9)
        assert r["success"] == (r["final_distance"] <= 0.1)
        assert r["success"] or r["sim_time_s"] == pytest.approx(3.0)
    assert sum(v["runs"] for v in summary["variants"].values()) == 4


# --- the T: the expert's demonstrations through LeRobot's own tools ------------------------------------------
TEE_REPO_ID = "local/gcs_push_t"


@pytest.fixture(scope="session")
def tee_dataset(lerobot_home, tmp_path_factory) -> Path:
    """One closed-loop demonstration of the T, from the first start of its uniform set (the README's GIF)."""
    from lerobot_gcs_push.generate import GenerateConfig, generate
    from lerobot_gcs_push.registration import SCENES, TEE_ENV_ID
    from lerobot_gcs_push.scene import sample_initial_conditions

    (ic,) = sample_initial_conditions(SCENES[TEE_ENV_ID], 1, seed=1000, sampler="uniform")
    ics = tmp_path_factory.mktemp("tee_ics") / "ics.json"
    ics.write_text(json.dumps([ic.to_json()]))
    root = lerobot_home / TEE_REPO_ID
    cfg = GenerateConfig(env_id=TEE_ENV_ID, initial_conditions=str(ics), repo_id=TEE_REPO_ID, root=str(root),
                         workers=1, max_sim_time_s=60, progress=False)  # fmt: skip
    report = generate(cfg)
    assert report.episodes == 1, "the closed-loop expert should push this T to coverage"
    return root


@pytest.mark.slow
def test_lerobot_train_and_eval_on_the_tee(tee_dataset, lerobot_home, tmp_path):
    """lerobot-train 2 steps on the T's demonstrations with --env.type=gcs_push_t, then lerobot-eval an
    episode of the checkpoint in the T env: the T's dataset and env config fit LeRobot's own CLIs."""
    out = tmp_path / "train"
    common = ["--policy.down_dims=[32,64]", "--env.type=gcs_push_t"]
    _run(
        [str(BIN / "lerobot-train"), f"--config_path={CPU_PRESET}", f"--dataset.repo_id={TEE_REPO_ID}", "--steps=2",
         "--batch_size=2", "--num_workers=0", "--env_eval_freq=0", "--save_freq=2", f"--output_dir={out}", *common],
        home=lerobot_home,
        cwd=tmp_path,
    )  # fmt: skip
    ckpt = out / "checkpoints" / "last" / "pretrained_model"
    train_cfg = json.loads((ckpt / "train_config.json").read_text())
    assert train_cfg["env"]["type"] == "gcs_push_t" and train_cfg["dataset"]["repo_id"] == TEE_REPO_ID
    ev = tmp_path / "eval"
    _run(
        [str(BIN / "lerobot-eval"), f"--policy.path={ckpt}", "--env.type=gcs_push_t", "--env.episode_length=20",
         "--eval.n_episodes=1", "--eval.batch_size=1", "--eval.use_async_envs=false", "--policy.device=cpu",
         f"--output_dir={ev}"],
        home=lerobot_home,
        cwd=tmp_path,
    )  # fmt: skip
    assert _eval_info(ev)["n_episodes"] == 1
