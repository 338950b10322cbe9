"""Shards of episodes: one contiguous range of initial conditions a job, run on a worker (a local process or
a Ray actor), written as a LeRobotDataset of its own; and the driver's side, which hands them out."""

from __future__ import annotations

import json
import math
import os
import shutil
import time
import uuid
from pathlib import Path

from lerobot_gcs_push.generate.config import (
    GenerateConfig,
)
from lerobot_gcs_push.generate.frames import (
    EpisodeFrames,
    _Writer,
)
from lerobot_gcs_push.generate.replay import ReplayActions
from lerobot_gcs_push.generate.workdir import WorkDir
from lerobot_gcs_push.pusht.dataset import CommandNoise, PushTFrames
from lerobot_gcs_push.pusht.finish import Finish
from lerobot_gcs_push.scene import (
    episode_seed,
)

_WORKER: dict = {}
SHARD_FILE = "gcs_push_shard.json"  # in a shard: its range and the metadata of every rollout in it, failures too
CRASH_ENV = "GCS_PUSH_TEST_CRASH_DIR"  # tests: a file `episode_<i>` there kills the worker once, before episode i


def _init_worker(cfg: GenerateConfig, work_path: str, shards_path: str) -> None:
    import lerobot_gcs_push  # noqa: F401  (registers the env)
    from lerobot_gcs_push.planning.factory import REPLAY, make_expert
    from lerobot_gcs_push.registration import make_env

    env = make_env(
        cfg.starts.env_id,
        fps=cfg.fps,
        image_size=cfg.image_size,
        disturbances=cfg.starts.disturbances,
        max_sim_time_s=cfg.max_sim_time_s,
        obs_type=cfg.obs_type,
    )
    _WORKER.update(
        cfg=cfg,
        env=env,
        work=WorkDir(Path(work_path)),
        shards=Path(shards_path),
        expert=ReplayActions() if cfg.expert.mode == REPLAY else make_expert(env.scene, cfg.fps, cfg.expert),
    )


def shard_path(shards: Path, start: int) -> Path:
    return shards / f"shard_{start:06d}"


def _run_shard(job: tuple[int, int, list[dict]]) -> dict:
    """Rolls out initial conditions [start, stop) and writes their successes as the shard `shard_<start>`."""
    start, stop, ics = job
    cfg, work, shards = _WORKER["cfg"], _WORKER["work"], _WORKER["shards"]
    final = shard_path(shards, start)
    if (final / SHARD_FILE).exists():  # an earlier attempt of this job got as far as the rename
        return json.loads((final / SHARD_FILE).read_text())
    metas = []
    for index, ic in zip(range(start, stop), ics, strict=True):
        _crash_hook(index)
        metas.append(work.meta(index) if work.episode_file(index).exists() else _run_episode((index, ic)))
    # A private staging name: a second attempt of the job (a worker presumed dead that was not) cannot mix in.
    staging = shards / f".{final.name}.{uuid.uuid4().hex}"
    good = [m for m in metas if m["success"]]
    if good:
        writer = _Writer(cfg, staging)
        for meta in good:
            writer.add(work.load_arrays(meta["index"]))
        writer.finish()
    else:
        staging.mkdir(parents=True)
    summary = {"start": start, "stop": stop, "episodes": metas}
    (staging / SHARD_FILE).write_text(json.dumps(summary))
    try:
        os.rename(staging, final)
    except OSError:  # another attempt's shard is already in place; the two are the same
        shutil.rmtree(staging, ignore_errors=True)
        if not (final / SHARD_FILE).exists():
            raise
    for index in range(start, stop):
        work.episode_file(index).unlink(missing_ok=True)
    return summary


def _crash_hook(index: int) -> None:
    triggers = os.environ.get(CRASH_ENV)
    if not triggers:
        return
    try:
        (Path(triggers) / f"episode_{index}").unlink()  # whoever removes the trigger dies; the retry goes on
    except FileNotFoundError:
        return
    os._exit(1)


def _run_episode(job: tuple[int, dict]) -> dict:
    from lerobot_gcs_push.episodes.rollout import rollout

    index, ic = job
    env, expert, cfg = _WORKER["env"], _WORKER["expert"], _WORKER["cfg"]
    pusht = env.scene.kind.lerobot_pusht_data  # lerobot/pusht's frames, recorded from the env's own steps
    seed = episode_seed(cfg.starts.seed, index)
    noise, expected_run = None, None
    if cfg.expert.mode == "replay" and "command_noise" in ic:  # a DART list: its labels again, its noise again
        noise, expected_run = CommandNoise.of(ic["command_noise"]), ic["actions"]
        expert.load(ic["labels"])
    elif cfg.expert.mode == "replay":
        expert.load(ic["actions"])
    elif cfg.command_noise_px > 0:
        noise = CommandNoise(cfg.command_noise_px, seed)
    finish = None
    if cfg.expert.mode == "replay" and "finish" in ic:  # the entry ended where its own setting said
        finish = Finish.of(ic["finish"])
    elif cfg.finish_coverage is not None:
        finish = Finish(cfg.finish_coverage, cfg.finish_frames)
    run_env = env if finish is None else finish.wrap(env)
    frames = PushTFrames(run_env, cfg.obs_type, noise, expected_run) if pusht else EpisodeFrames(env.scene)
    t0 = time.perf_counter()
    result = rollout(
        frames.env if pusht else env,
        expert,
        ic["box"],
        ic["finger"],
        seed=seed,
        on_step=None if pusht else frames,
        heading=ic.get("heading"),
        pusht_state=ic.get("pusht_state"),
    )
    plan = result["plan"]
    meta = {
        "index": index,
        "box_initial": ic["box"],
        "finger_initial": ic["finger"],
        "success": result["success"],
        "final_distance": result["final_distance"],
        "sim_time_s": result["sim_time_s"],
        "plan_time_s": result["plan_time_s"],
        "plan_cost": plan.cost if plan else None,  # None: the expert found no plan from this state
        "plan_lower_bound": plan.lower_bound if plan else None,
        "modes": plan.modes if plan else [],
        "replans": result["replans"],
        "num_frames": len(frames),
        "wall_time_s": time.perf_counter() - t0,
        "disturbances": result["disturbances"],
    }
    if env.scene.kind.records_coverage:  # a rotating slider: where it started and how much of the goal it covers
        meta |= {"heading_initial": ic.get("heading", 0.0), "coverage": result["coverage"]}
    if ic.get("pusht_state") is not None:  # gym-pusht's start, as its obs_type="state" reports it
        meta["pusht_state_initial"] = [float(v) for v in ic["pusht_state"]]
    if noise is not None:
        meta["command_noise"] = noise.spec()
    if finish is not None:
        meta["finish"] = finish.spec()
    arrays = frames.arrays() if result["success"] else {}
    # The worker compresses and saves its own episode; only the metadata travels back.
    _WORKER["work"].save({"meta": meta, "arrays": arrays})
    return meta


def _run_shards(
    cfg: GenerateConfig, pool, ics: list[dict], finished: dict[int, dict], shards: Path, on_shard
) -> list[dict]:
    """The shards that make the dataset, in index order: an interrupted run's, then new ones from the pool.

    The dataset is the first `episodes` successful rollouts in index order (fewer if `frames` are reached
    first), whatever the timing. The initial conditions in flight never outnumber the successes still
    missing, so no rollout past the last one needed is started, and a shard takes at most a worker's share
    of them. A new shard ends where a finished one begins, so that one is reused as it is.
    """
    kept: dict[int, dict] = {}
    running: dict[int, int] = {}  # start -> stop
    frontier = successes = 0
    end = len(ics)  # where `frames` are reached, once the shards before it are all in
    prefix = prefix_frames = 0  # the contiguous kept shards from index 0: where they end, their frames

    def missing() -> int:
        return cfg.episodes - successes - sum(stop - start for start, stop in running.items())

    def keep(shard: dict) -> None:
        nonlocal successes, end, prefix, prefix_frames
        kept[shard["start"]] = shard
        successes += sum(m["success"] for m in shard["episodes"])
        on_shard(shard)
        while cfg.frames is not None and end == len(ics) and prefix in kept:
            for m in kept[prefix]["episodes"]:
                prefix_frames += m["num_frames"] if m["success"] else 0
                if m["success"] and prefix_frames >= cfg.frames:
                    end = m["index"] + 1
                    break
            prefix = kept[prefix]["stop"]

    while True:
        # Two shards per worker in flight: a worker never waits for the driver.
        while frontier < end and len(running) < 2 * cfg.workers and missing() > 0:
            old = finished.pop(frontier, None)
            if old is not None and sum(m["success"] for m in old["episodes"]) <= missing():
                keep(old)
                frontier = old["stop"]
                continue
            if old is not None:  # from a run that asked for more episodes: it may hold more than are missing
                shutil.rmtree(shard_path(shards, frontier))
            # Near the end a shard takes no more than a worker's share of what is missing, so that every
            # worker has some of it: in shards of 10, 10 episodes on 2 workers ran on one.
            stop = min(
                frontier + cfg.shard_size,
                frontier + math.ceil(missing() / cfg.workers),
                frontier + missing(),
                min((start for start in finished if start > frontier), default=len(ics)),
            )
            pool.submit(_run_shard, (frontier, stop, ics[frontier:stop]))
            running[frontier] = stop
            frontier = stop
        if not running:
            break
        shard = pool.next()[1]
        del running[shard["start"]]
        keep(shard)
    kept = {start: shard for start, shard in kept.items() if start < end}
    last = max(kept, default=None)
    if last is not None and kept[last]["stop"] > end:  # `frames` were reached inside it: run it again, shorter
        shutil.rmtree(shard_path(shards, last))
        pool.submit(_run_shard, (last, end, ics[last:end]))
        kept[last] = pool.next()[1]
    return [kept[start] for start in sorted(kept)]


def _read_shard(path: Path) -> dict | None:
    file = path / SHARD_FILE
    return json.loads(file.read_text()) if file.exists() else None
