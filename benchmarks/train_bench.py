"""Training throughput and inference latency of the DiffusionPolicy presets on CPU.

`run()` returns a flat dict and prints nothing. For each preset in `configs/policy/` it builds what
`lerobot-train` builds, with LeRobot's own pieces: `make_dataset` (the preset's delta timestamps),
`EpisodeAwareSampler` + `DataLoader` (the preset's `batch_size` / `num_workers`, spawn workers),
`make_policy`, `make_pre_post_processors` and the preset's optimizer; then it times a few optimisation
steps after warm-up:
  - `<preset>_train_samples_per_s`: batch_size / mean step time (wall clock, batch wait included);
  - `<preset>_dataloader_share`: time waiting for the next batch (plus preprocessing, as lerobot-train
    counts it) over the total step time;
  - `<preset>_train_cpu_s_per_step`: this process's CPU time per step, all its threads (OpenMP's
    default active waiting counts as CPU time);
  - `<preset>_inference_s_per_chunk`: `select_action` with an empty action queue, i.e. one full
    denoising of `horizon` actions (median), at batch size 1.
The dataset is a tiny one generated in a temporary HF_LEROBOT_HOME (or `dataset_root`, if given).

On a 2-core machine shared with other jobs, PyTorch's OpenMP threads spin while they wait and every
step gets several times slower; set OMP_WAIT_POLICY=PASSIVE (or OMP_NUM_THREADS=1) before starting
Python there. `omp_wait_policy` and the load averages are returned so a number can be judged.
"""

from __future__ import annotations

import json
import os
import statistics
import tempfile
import time
import warnings
from pathlib import Path

CONFIGS = Path(__file__).resolve().parents[1] / "configs" / "policy"
PRESETS = {"cpu": "diffusion_cpu.json", "paper": "diffusion_paper.json"}
REPO_ID = "local/gcs_push_box"


def _policy_config(preset: str):
    import draccus
    import lerobot.policies  # noqa: F401  (registers the policy types)
    from lerobot.configs.policies import PreTrainedConfig

    raw = json.loads((CONFIGS / PRESETS[preset]).read_text())
    return draccus.decode(PreTrainedConfig, raw["policy"]), raw


def _dataset(policy_cfg, root: Path):
    from lerobot.configs.default import DatasetConfig
    from lerobot.configs.train import TrainPipelineConfig
    from lerobot.datasets.factory import make_dataset

    cfg = TrainPipelineConfig(
        dataset=DatasetConfig(repo_id=REPO_ID, root=str(root), video_backend="pyav"), policy=policy_cfg
    )
    return make_dataset(cfg)


def _dataloader(dataset, policy_cfg, batch_size: int, num_workers: int, seed: int = 0):
    import torch
    from lerobot.datasets.sampler import EpisodeAwareSampler

    sampler = EpisodeAwareSampler(
        dataset.meta.episodes["dataset_from_index"],
        dataset.meta.episodes["dataset_to_index"],
        episode_indices_to_use=dataset.episodes,
        drop_n_last_frames=policy_cfg.drop_n_last_frames,
        shuffle=True,
        seed=seed,
        absolute_to_relative_idx=dataset.absolute_to_relative_idx,
    )
    workers = {"prefetch_factor": 4, "persistent_workers": True, "multiprocessing_context": "spawn"}
    return torch.utils.data.DataLoader(
        dataset,
        batch_size=batch_size,
        sampler=sampler,
        drop_last=False,
        num_workers=num_workers,
        **(workers if num_workers > 0 else {}),
    )


def _cycle(loader):
    while True:
        yield from loader


def bench_preset(
    preset: str,
    root: Path,
    warmup: int = 1,
    steps: int = 3,
    inference_reps: int = 3,
    batch_size: int | None = None,
    num_workers: int | None = None,
    amp: bool = False,
    **policy_overrides,
) -> dict:
    """amp=True measures what `lerobot-train --policy.use_amp=true` does on CPU (bf16 autocast of the
    forward pass, fp32 weights); its keys are prefixed `<preset>_bf16_`."""
    import torch
    from lerobot.policies.factory import make_policy, make_pre_post_processors

    policy_cfg, raw = _policy_config(preset)
    for key, value in policy_overrides.items():
        setattr(policy_cfg, key, value)
    policy_cfg.__post_init__()
    policy_cfg.device = "cpu"
    batch_size = raw["batch_size"] if batch_size is None else batch_size
    num_workers = raw["num_workers"] if num_workers is None else num_workers

    torch.manual_seed(0)
    dataset = _dataset(policy_cfg, root)
    policy = make_policy(policy_cfg, ds_meta=dataset.meta)
    pre, _post = make_pre_post_processors(policy_cfg, dataset_stats=dataset.meta.stats)
    optimizer = policy_cfg.get_optimizer_preset().build(policy.get_optim_params())
    clip = policy_cfg.get_optimizer_preset().grad_clip_norm
    batches = _cycle(_dataloader(dataset, policy_cfg, batch_size, num_workers))
    camera_keys = dataset.meta.camera_keys

    policy.train()
    wait, total, cpu = [], [], []
    for i in range(warmup + steps):
        t0, c0 = time.perf_counter(), time.process_time()
        batch = next(batches)
        for key in camera_keys:
            if key in batch and batch[key].dtype == torch.uint8:
                batch[key] = batch[key].to(torch.float32) / 255.0
        batch = pre(batch)
        t1 = time.perf_counter()
        with torch.autocast("cpu", dtype=torch.bfloat16, enabled=amp):
            loss, _ = policy.forward(batch)
        loss.backward()
        torch.nn.utils.clip_grad_norm_(policy.parameters(), clip)
        optimizer.step()
        optimizer.zero_grad()
        t2, c2 = time.perf_counter(), time.process_time()
        if i >= warmup:
            wait.append(t1 - t0)
            total.append(t2 - t0)
            cpu.append(c2 - c0)

    # One full denoising per call: reset() empties the action queue.
    policy.eval()
    frame = dataset[0]
    obs = {k: frame[k][-1:].clone() for k in policy_cfg.input_features}  # the latest frame, batch of 1
    obs = pre(obs)
    latencies = []
    with torch.inference_mode():
        for i in range(inference_reps + 1):
            policy.reset()
            t0 = time.perf_counter()
            policy.select_action(obs)
            if i > 0:  # the first call warms up
                latencies.append(time.perf_counter() - t0)

    step_s = statistics.fmean(total)
    preset = f"{preset}_bf16" if amp else preset
    return {
        f"{preset}_batch_size": batch_size,
        f"{preset}_num_workers": num_workers,
        f"{preset}_params_m": sum(p.numel() for p in policy.parameters()) / 1e6,
        f"{preset}_train_step_s": step_s,
        f"{preset}_train_samples_per_s": batch_size / step_s,
        f"{preset}_train_cpu_s_per_step": statistics.fmean(cpu),
        f"{preset}_dataloader_share": sum(wait) / sum(total),
        f"{preset}_inference_s_per_chunk": statistics.median(latencies),
        f"{preset}_denoising_steps": policy_cfg.num_inference_steps or policy_cfg.num_train_timesteps,
    }


def _tiny_dataset(home: Path, episodes: int) -> Path:
    from lerobot_gcs_push.generate import GenerateConfig, generate

    root = home / REPO_ID
    generate(GenerateConfig(episodes=episodes, repo_id=REPO_ID, root=str(root), workers=1, progress=False))
    return root


def run(presets=("cpu", "paper"), dataset_root: str | None = None, episodes: int = 2, **kwargs) -> dict:
    os.environ.setdefault("HF_HUB_OFFLINE", "1")
    from datasets.utils.logging import disable_progress_bar

    disable_progress_bar()
    out = {
        "torch_threads": __import__("torch").get_num_threads(),
        "cpu_count": os.cpu_count(),
        "omp_wait_policy": os.environ.get("OMP_WAIT_POLICY", ""),
        "load_avg_1min": os.getloadavg()[0],
    }
    with tempfile.TemporaryDirectory(prefix="gcs_push_train_bench_") as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore")  # e.g. the DataLoader's "more workers than cores" for the paper preset
        root = Path(dataset_root) if dataset_root else _tiny_dataset(Path(tmp), episodes)
        for preset in presets:
            out.update(bench_preset(preset, root, **kwargs))
    out["load_avg_1min_after"] = os.getloadavg()[0]
    return out
