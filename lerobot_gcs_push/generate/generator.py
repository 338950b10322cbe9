"""`generate`: shards run, merged with LeRobot's aggregation into a staging folder, moved into place whole;
and `merge_datasets`."""

from __future__ import annotations

import json
import os
import shutil
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lerobot_gcs_push.generate.config import (
    _IMPLICIT_SETTINGS,
    EPISODES_META,
    SETTINGS_META,
    GenerateConfig,
    dataset_root,
    lerobot_home,
    recorded_settings,
)
from lerobot_gcs_push.generate.frames import (
    _batched_image_embedding,
    read_episode_metadata,
)
from lerobot_gcs_push.generate.hub import push_to_hub
from lerobot_gcs_push.generate.replay import REPLAY_KEYS, REPLAY_META, START_KEYS, dataset_replay, write_replay
from lerobot_gcs_push.generate.shards import (
    _init_worker,
    _read_shard,
    _run_shards,
    shard_path,
)
from lerobot_gcs_push.generate.workdir import WorkDir
from lerobot_gcs_push.registration import SCENES, sample_starts
from lerobot_gcs_push.scene import (
    load_initial_conditions,
)
from lerobot_gcs_push.settings import changed, describe


@dataclass
class GenerateReport:
    root: str
    repo_id: str
    episodes: int
    frames: int
    attempts: int
    failures: int
    wall_time_s: float
    episodes_per_min: float
    shards: int = 0  # merged into the dataset
    merge_time_s: float = 0.0  # LeRobot's aggregation of the shards
    already_finished: bool = False  # --resume on a dataset that was already complete: nothing ran


def generate(cfg: GenerateConfig) -> GenerateReport:
    from lerobot.datasets.aggregate import aggregate_datasets  # noqa: F401  (imported here, not in the merge's time)

    from lerobot_gcs_push.episodes.workers import open_pool

    scene = SCENES[cfg.starts.env_id]
    root = dataset_root(cfg)
    work = WorkDir(root.with_name(root.name + ".work"))
    shards = root.with_name(root.name + ".shards")
    if cfg.output.overwrite:
        if root.exists() and not (root / "meta" / "info.json").is_file() and any(root.iterdir()):
            raise FileExistsError(
                f"--overwrite replaces a LeRobotDataset, and {root} is not one: choose another --root"
            )
        for path in (root, work.path, shards):
            shutil.rmtree(path, ignore_errors=True)
    # Where and how the jobs run may change on --resume; what they compute may not.
    settings = recorded_settings(cfg)
    if root.exists():
        return _finished(cfg, root, settings)
    if not work.path.exists():  # shards are only trusted with the settings they were made with
        shutil.rmtree(shards, ignore_errors=True)
    work.open(settings, cfg.output.resume)
    shards.mkdir(parents=True, exist_ok=True)
    for stale in shards.glob(".shard_*"):  # staging folders of jobs cut short with an interrupted run
        shutil.rmtree(stale, ignore_errors=True)

    t0 = time.perf_counter()
    if cfg.starts.initial_conditions:
        # A file's other keys (a branch state's source) stay out of the jobs.
        keys = (*START_KEYS, *REPLAY_KEYS)
        ics = [
            {k: ic[k] for k in keys if k in ic} for ic in load_initial_conditions(cfg.starts.initial_conditions, scene)
        ]
    else:
        max_attempts = int(np.ceil(cfg.episodes * cfg.max_attempts_factor)) + 10
        ics = [
            ic.to_json() for ic in sample_starts(scene, max_attempts, seed=cfg.starts.seed, sampler=cfg.starts.sampler)
        ]
    finished = {s["start"]: s for s in map(_read_shard, shards.glob("shard_*")) if s is not None}
    bar = _progress(cfg)
    failures = 0

    def progress(shard: dict) -> None:
        nonlocal failures
        ok = sum(m["success"] for m in shard["episodes"])
        failures += len(shard["episodes"]) - ok
        bar.update(ok)
        bar.set_postfix(failures=failures)

    try:
        with open_pool(
            cfg.backend,
            cfg.workers,
            _init_worker,
            (cfg, str(work.path), str(shards)),
            address=cfg.ray_address,
            hint=f"the finished shards are kept in {shards}: run again with --resume=true",
        ) as pool:
            kept = _run_shards(cfg, pool, ics, finished, shards, progress)
    finally:
        bar.close()
    metas = [m for shard in kept for m in shard["episodes"] if m["success"]]
    frames = sum(m["num_frames"] for m in metas)
    attempts = kept[-1]["stop"] if kept else 0
    enough = len(metas) == cfg.episodes or (cfg.frames is not None and frames >= cfg.frames)
    # A given list is tried once and its failures are reported, not an error.
    if not enough and not (cfg.starts.initial_conditions and metas):
        raise RuntimeError(
            f"only {len(metas)} of {cfg.episodes} episodes succeeded after {attempts} initial "
            f"conditions; their records are in {shards}"
        )
    merged = [shard_path(shards, s["start"]) for s in kept if any(m["success"] for m in s["episodes"])]
    t_merge = time.perf_counter()
    _merge(cfg, root, merged, metas, settings | {"episodes": cfg.episodes})
    merge_time = time.perf_counter() - t_merge
    shutil.rmtree(shards, ignore_errors=True)
    shutil.rmtree(work.path, ignore_errors=True)
    wall = time.perf_counter() - t0
    report = GenerateReport(
        str(root),
        cfg.output.repo_id,
        len(metas),
        frames,
        attempts,
        attempts - len(metas),
        wall,
        60.0 * len(metas) / wall if wall > 0 else float("inf"),
        len(merged),
        merge_time,
    )
    if cfg.push_to_hub:
        push_to_hub(cfg.output.repo_id, root)
    return report


def _finished(cfg: GenerateConfig, root: Path, settings: dict) -> GenerateReport:
    """An existing dataset: its report if --resume asks for exactly what it holds, else a named refusal.

    A finished run leaves no work folder, so its settings are kept in the dataset itself: a script that
    re-runs every step after a kill can pass --resume=true to a step that already finished.
    """
    hint = "pass --overwrite=true to replace it (or choose another --repo_id / --root)"
    if not cfg.output.resume:
        raise FileExistsError(f"a dataset already exists at {root}: {hint}")
    wanted = settings | {"episodes": cfg.episodes}
    file = root / SETTINGS_META
    if not file.exists():
        raise FileExistsError(f"a dataset already exists at {root}, made before its settings were recorded: {hint}")
    diff = changed(json.loads(file.read_text()), _IMPLICIT_SETTINGS | wanted, _IMPLICIT_SETTINGS)
    if diff:
        raise FileExistsError(f"the finished dataset at {root} was made with other settings ({describe(diff)}): {hint}")
    metas = read_episode_metadata(root)
    return GenerateReport(
        str(root),
        cfg.output.repo_id,
        episodes=len(metas),
        frames=sum(m["num_frames"] for m in metas),
        attempts=0,
        failures=0,
        wall_time_s=0.0,
        episodes_per_min=0.0,
        already_finished=True,
    )


def _merge(cfg: GenerateConfig, root: Path, shard_roots: list[Path], metas: list[dict], settings: dict) -> None:
    """LeRobot's aggregation of the shards, in index order, into a staging folder moved into place once whole."""
    from lerobot.datasets.aggregate import aggregate_datasets

    staging = root.with_name(root.name + ".staging")
    shutil.rmtree(staging, ignore_errors=True)
    with _batched_image_embedding():
        aggregate_datasets(
            [cfg.output.repo_id] * len(shard_roots), cfg.output.repo_id, roots=shard_roots, aggr_root=staging
        )
    (staging / EPISODES_META).write_text(
        "".join(json.dumps({"episode_index": i, **meta}) + "\n" for i, meta in enumerate(metas))
    )
    (staging / SETTINGS_META).write_text(json.dumps(settings, indent=1))
    write_replay(staging / REPLAY_META, dataset_replay(staging, metas))
    root.parent.mkdir(parents=True, exist_ok=True)
    os.replace(staging, root)


def merge_datasets(repo_ids: list[str], repo_id: str, desc: str = "merge") -> Path:
    """LeRobot's aggregation of whole datasets from the cache into `repo_id` there, which appears whole or
    not at all (a killed merge leaves only a staging folder, removed by the next try)."""
    from lerobot.datasets.aggregate import aggregate_datasets
    from tqdm.auto import tqdm

    home = lerobot_home()
    root = home / repo_id
    if (root / "meta" / "info.json").is_file():
        return root
    for r in repo_ids:
        if not (home / r / "meta" / "info.json").is_file():
            raise FileNotFoundError(f"cannot merge {r}: no LeRobotDataset at {home / r}")
    staging = root.with_name(root.name + ".staging")
    shutil.rmtree(staging, ignore_errors=True)
    with tqdm(total=1, desc=desc, unit="merge", dynamic_ncols=True) as bar, _batched_image_embedding():
        aggregate_datasets(repo_ids, repo_id, roots=[home / r for r in repo_ids], aggr_root=staging)
        bar.update(1)
    os.replace(staging, root)
    return root


def _progress(cfg: GenerateConfig):
    from tqdm.auto import tqdm

    return tqdm(total=cfg.episodes, desc="demonstrations", unit="ep", disable=not cfg.progress, dynamic_ncols=True)
