"""Demonstrations: sample initial conditions, plan with GCS, roll out in the env, write a LeRobotDataset.

Shards: the initial conditions are cut into contiguous ranges, each run by one job on a worker (a local
process or a Ray actor: see `workers`), which writes that range's successful episodes as a LeRobotDataset of
its own, the shard, beside the dataset (`<root>.shards/shard_<first index>`). The driver merges the shards
with LeRobot's aggregation into a staging folder, moved into place only once it is complete, so the cache
never holds a half-written dataset.

Crash safety: a job saves each finished episode as one compressed file in a work folder beside the dataset
(`<root>.work/`), and a shard appears by atomic rename, whole or not at all. A job run again (Ray retries the
job of a worker that died; `resume` repeats an interrupted run) keeps the finished shards and episodes and
never leaves half a shard. `overwrite` starts again.

Determinism: the i-th initial condition and its episode seed depend only on (seed, i), and the dataset is the
first `episodes` successful rollouts in index order, so its contents do not depend on the backend, `workers`
or `shard_size`.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import time
import uuid
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from lerobot_gcs_push.files import atomic_path
from lerobot_gcs_push.pusht_dataset import PUSHT_FEATURE_KEYS, PushTFrames, pusht_features
from lerobot_gcs_push.registration import ENV_ID, PUSHT_ENV_ID, SCENES, sample_starts
from lerobot_gcs_push.replay import REPLAY_META, START_KEYS, ReplayActions, dataset_replay, write_replay
from lerobot_gcs_push.scene import (
    Disturbances,
    Scene,
    check_sampler,
    check_seed,
    episode_seed,
    load_initial_conditions,
)
from lerobot_gcs_push.settings import changed, describe

EPISODES_META = "meta/gcs_push_episodes.jsonl"
SETTINGS_META = "meta/gcs_push_settings.json"  # the settings a finished dataset was made with (see _finished)
FEATURE_KEYS = ("observation.image", "observation.state", "observation.environment_state", "action")
# Settings a dataset or work folder made before the field existed holds implicitly.
_IMPLICIT_SETTINGS = {"env_id": ENV_ID}


@dataclass
class GenerateConfig:
    # The registered env to record in: GcsPushBox-v0 (the box that cannot turn), GcsPushBoxSE2-v0 or
    # GcsPushT-v0 (rotating sliders, whose GCS expert plans through contact: --method=relaxation only), or
    # gym_pusht/PushT-v0 (gym-pusht's own env, written in lerobot/pusht's format: see pusht_dataset.py).
    env_id: str = ENV_ID
    # Successful demonstrations to write (failed rollouts are left out). Default: 100 from the sampler,
    # or as many as --initial_conditions has entries.
    episodes: int | None = None
    # LeRobot dataset id, "owner/name".
    repo_id: str = "local/gcs_push_box"
    # Dataset folder; default: $HF_LEROBOT_HOME/<repo_id>, where LeRobot looks first.
    root: str | None = None
    # The i-th initial condition and episode depend only on (seed, i).
    seed: int = 0
    # Worker processes (or Ray actors); the dataset does not depend on it.
    workers: int = 2
    # open-loop (plan once, the paper's), closed-loop (replans after disturbances) or replay (runs the
    # "actions" of each --initial_conditions entry: a dataset's meta/gcs_push_replay.json rebuilds it, see
    # replay.py). Default: replay for a list whose entries all carry actions; else open-loop for the box
    # that cannot turn, closed-loop for a rotating slider, which strays from any plan pushed open-loop.
    expert: str | None = None
    # relaxation (convex relaxation + rounding) or micp (exact, SCIP).
    method: str = "relaxation"
    # Initial conditions: sobol (space-filling), uniform (the paper's) or hard (see scene.py).
    sampler: str = "sobol"
    # A JSON list of {"box", "finger"} (and "heading" for a rotating slider) to use instead of the sampler
    # (e.g. the policy states that `gcs-push collect` picked); its entries are tried once each, in order,
    # until `episodes` succeed, and failures are left out.
    initial_conditions: str | None = None
    # Stop once this many frames are written (an equal-cost control); episodes is then an upper bound.
    frames: int | None = None
    # Record under the paper's random pushes on the box (use with the closed-loop expert).
    disturbances: bool = False
    # Env steps (frames) per simulated second.
    fps: int = Scene.fps
    # Observation image side, pixels.
    image_size: int = 96
    # Simulated seconds before a rollout counts as failed. Default: the env's (500 s, the paper's; 30 s, that
    # is 300 steps, for gym-pusht, so its episodes succeed within gym-pusht's own limit).
    max_sim_time_s: float | None = None
    # Replace an existing dataset (and an interrupted run's work).
    overwrite: bool = False
    # Continue an interrupted run, keeping its finished episodes and shards.
    resume: bool = False
    # Upload with LeRobot's push_to_hub (needs the network and a token).
    push_to_hub: bool = False
    # Show a progress bar.
    progress: bool = True
    # Give up after episodes * factor initial conditions.
    max_attempts_factor: float = 2.0
    # process (worker processes here) or ray (Ray actors; see lerobot_gcs_push.workers).
    backend: str = "process"
    # With backend ray: "auto" or "HOST:PORT" joins a running cluster; none starts Ray here.
    ray_address: str | None = None
    # Initial conditions per job, at most; each job writes one shard, merged at the end.
    shard_size: int = 10

    def __post_init__(self) -> None:
        from lerobot_gcs_push.expert import EXPERTS
        from lerobot_gcs_push.rollout import check_env_id

        check_env_id(self.env_id)
        scene = SCENES[self.env_id]
        ics = load_initial_conditions(self.initial_conditions, scene) if self.initial_conditions else None
        if self.episodes is None:
            self.episodes = len(ics) if ics else 100
        if self.episodes < 1:
            raise ValueError(f"episodes must be >= 1, got {self.episodes}")
        if self.workers < 1:
            raise ValueError(f"workers must be >= 1, got {self.workers}")
        if self.overwrite and self.resume:
            raise ValueError("choose one of overwrite and resume, not both")
        if "/" not in self.repo_id:
            raise ValueError(f"repo_id must look like 'owner/name', got {self.repo_id!r}")
        rotates = SCENES[self.env_id].rotates
        replayable = bool(ics) and all("actions" in ic for ic in ics)
        if self.expert is None:
            self.expert = "replay" if replayable else "closed-loop" if rotates else "open-loop"
        if self.expert not in (*EXPERTS, "replay"):
            raise ValueError(f"unknown expert {self.expert!r}: choose one of {(*EXPERTS, 'replay')}")
        if self.expert == "replay":
            if not ics:
                raise ValueError("--expert=replay runs the actions of an --initial_conditions list: pass one")
            missing = next((i for i, ic in enumerate(ics) if "actions" not in ic), None)
            if missing is not None:
                raise ValueError(f'--expert=replay: initial condition {missing} has no "actions"')
            for i, ic in enumerate(ics):  # refused here, not by a worker midway through the run
                try:
                    ReplayActions().load(ic["actions"])
                except (ValueError, TypeError) as err:
                    raise ValueError(f"--expert=replay: initial condition {i}: {err}") from None
            if self.disturbances:
                raise ValueError("--expert=replay repeats undisturbed episodes: drop --disturbances")
        check_sampler(self.sampler)
        from lerobot_gcs_push.planner import check_method

        check_method(self.method)
        if rotates and self.method != "relaxation":
            raise ValueError(f"{self.env_id} plans with the relaxation only: drop --method={self.method}")
        if self.max_sim_time_s is None:
            self.max_sim_time_s = scene.timeout_s
        if self.image_size < 1:
            raise ValueError(f"image_size must be >= 1, got {self.image_size}")
        if not 0 < self.max_sim_time_s < float("inf"):  # inf would roll a failing start out forever
            raise ValueError(f"max_sim_time_s must be positive and finite, got {self.max_sim_time_s}")
        check_seed(self.seed)
        per_s = round(1 / Disturbances.tick_s)
        if self.fps <= 0 or per_s % self.fps:  # an env step is a whole number of disturbance ticks
            raise ValueError(f"fps must divide {per_s}, got {self.fps}")
        if ics:  # refused before any worker starts, each entry named
            for i, ic in enumerate(ics):
                scene.validate_start(ic, f"initial condition {i}")
        if self.frames is not None and self.frames < 1:
            raise ValueError(f"frames must be >= 1, got {self.frames}")
        if self.shard_size < 1:
            raise ValueError(f"shard_size must be >= 1, got {self.shard_size}")
        if self.push_to_hub:  # refused now, not after the whole generation
            check_online()
        from lerobot_gcs_push.workers import check_backend

        check_backend(self.backend, self.ray_address)


def lerobot_home() -> Path:
    env = os.environ.get("HF_LEROBOT_HOME")
    if env:
        return Path(env).expanduser()
    from lerobot.utils.constants import HF_LEROBOT_HOME

    return Path(HF_LEROBOT_HOME)


def dataset_root(cfg: GenerateConfig) -> Path:
    return Path(cfg.root).expanduser() if cfg.root else lerobot_home() / cfg.repo_id


def features(scene: Scene, image_size: int) -> dict:
    """The dataset's features; the environment state is the box's position, or a rotating slider's pose."""
    slider = ["slider_x", "slider_y", "slider_heading"] if scene.rotates else ["box_x", "box_y"]
    return {
        "observation.image": {
            "dtype": "image",
            "shape": (image_size, image_size, 3),
            "names": ["height", "width", "channel"],
        },
        "observation.state": {"dtype": "float32", "shape": (2,), "names": ["finger_x", "finger_y"]},
        "observation.environment_state": {"dtype": "float32", "shape": (len(slider),), "names": slider},
        "action": {"dtype": "float32", "shape": (2,), "names": ["finger_target_x", "finger_target_y"]},
    }


class EpisodeFrames:
    """A rollout's frames as the dataset stores them; pass it to `rollout` as `on_step`."""

    def __init__(self, scene: Scene):
        self.rotates = scene.rotates
        self.frames: dict[str, list] = {k: [] for k in FEATURE_KEYS}

    def __call__(self, obs, action, info) -> None:
        state = info["slider_pose"] if self.rotates else info["box"]
        self.frames["observation.image"].append(obs["pixels"])
        self.frames["observation.state"].append(np.asarray(obs["agent_pos"], np.float32))
        self.frames["observation.environment_state"].append(np.asarray(state, np.float32))
        self.frames["action"].append(np.asarray(action, np.float32))

    def __len__(self) -> int:
        return len(self.frames["action"])

    def arrays(self) -> dict[str, np.ndarray]:
        return {k: np.stack(v) for k, v in self.frames.items()}


# --- one shard of episodes, in a worker ----------------------------------------------------------
_WORKER: dict = {}
SHARD_FILE = "gcs_push_shard.json"  # in a shard: its range and the metadata of every rollout in it, failures too
CRASH_ENV = "GCS_PUSH_TEST_CRASH_DIR"  # tests: a file `episode_<i>` there kills the worker once, before episode i


def _init_worker(cfg_dict: dict, work_path: str, shards_path: str) -> None:
    import lerobot_gcs_push  # noqa: F401  (registers the env)
    from lerobot_gcs_push.expert import ExpertConfig, make_expert
    from lerobot_gcs_push.registration import make_env

    cfg = GenerateConfig(**cfg_dict)
    env = make_env(
        cfg.env_id,
        fps=cfg.fps,
        image_size=cfg.image_size,
        disturbances=cfg.disturbances,
        max_sim_time_s=cfg.max_sim_time_s,
    )
    _WORKER.update(
        cfg=cfg,
        env=env,
        work=WorkDir(Path(work_path)),
        shards=Path(shards_path),
        expert=ReplayActions()
        if cfg.expert == "replay"
        else make_expert(env.scene, cfg.fps, ExpertConfig(mode=cfg.expert, method=cfg.method)),
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
    from lerobot_gcs_push.rollout import rollout

    index, ic = job
    env, expert, cfg = _WORKER["env"], _WORKER["expert"], _WORKER["cfg"]
    pusht = cfg.env_id == PUSHT_ENV_ID  # lerobot/pusht's frames, recorded from the env's own steps
    frames = PushTFrames(env) if pusht else EpisodeFrames(env.scene)
    if cfg.expert == "replay":
        expert.load(ic["actions"])
    t0 = time.perf_counter()
    seed = episode_seed(cfg.seed, index)
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
    if "slider_pose_final" in result:  # a rotating slider: where it started and how much of the goal it covers
        meta |= {"heading_initial": ic.get("heading", 0.0), "coverage": result["coverage"]}
    if ic.get("pusht_state") is not None:  # gym-pusht's start, as its obs_type="state" reports it
        meta["pusht_state_initial"] = [float(v) for v in ic["pusht_state"]]
    arrays = frames.arrays() if result["success"] else {}
    # The worker compresses and saves its own episode; only the metadata travels back.
    _WORKER["work"].save({"meta": meta, "arrays": arrays})
    return meta


# --- the work folder ---------------------------------------------------------------------------------
class WorkDir:
    """Finished episodes of a run, one file each, plus the run's settings (to refuse mixing runs)."""

    def __init__(self, path: Path):
        self.path = path

    def settings_file(self) -> Path:
        return self.path / "settings.json"

    def open(self, settings: dict, resume: bool) -> None:
        if self.path.exists():
            if not resume:
                raise FileExistsError(
                    f"an interrupted run left {self.path}: pass --resume=true to continue it "
                    "or --overwrite=true to start again"
                )
            old = json.loads(self.settings_file().read_text()) if self.settings_file().exists() else None
            diff = changed(old, settings, _IMPLICIT_SETTINGS) if old is not None else {}
            if diff:
                raise ValueError(f"--resume with different settings than the interrupted run: {describe(diff)}")
        self.path.mkdir(parents=True, exist_ok=True)
        with atomic_path(self.settings_file()) as tmp:
            tmp.write_text(json.dumps(settings, indent=1))

    def episode_file(self, index: int) -> Path:
        return self.path / f"episode_{index:06d}.npz"

    def meta(self, index: int) -> dict:
        with np.load(self.episode_file(index), allow_pickle=False) as z:
            return json.loads(str(z["meta"]))

    def save(self, result: dict) -> None:
        meta = result["meta"]
        arrays = {k.replace(".", "__"): v for k, v in result["arrays"].items()}
        with atomic_path(self.episode_file(meta["index"])) as tmp, open(tmp, "wb") as f:
            np.savez_compressed(f, meta=json.dumps(meta), **arrays)

    def load_arrays(self, index: int) -> dict[str, np.ndarray]:
        with np.load(self.episode_file(index), allow_pickle=False) as z:
            return {k.replace("__", "."): z[k] for k in z.files if k != "meta"}


# --- the generator -----------------------------------------------------------------------------------
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

    from lerobot_gcs_push.workers import open_pool

    scene = SCENES[cfg.env_id]
    root = dataset_root(cfg)
    work = WorkDir(root.with_name(root.name + ".work"))
    shards = root.with_name(root.name + ".shards")
    if cfg.overwrite:
        if root.exists() and not (root / "meta" / "info.json").is_file() and any(root.iterdir()):
            raise FileExistsError(
                f"--overwrite replaces a LeRobotDataset, and {root} is not one: choose another --root"
            )
        for path in (root, work.path, shards):
            shutil.rmtree(path, ignore_errors=True)
    # Where and how the jobs run may change on --resume; what they compute may not.
    settings = {
        k: v
        for k, v in asdict(cfg).items()
        if k
        not in (
            "workers",
            "overwrite",
            "resume",
            "progress",
            "push_to_hub",
            "episodes",
            "root",
            "backend",
            "ray_address",
            "shard_size",
        )
    }
    if root.exists():
        return _finished(cfg, root, settings)
    if not work.path.exists():  # shards are only trusted with the settings they were made with
        shutil.rmtree(shards, ignore_errors=True)
    work.open(settings, cfg.resume)
    shards.mkdir(parents=True, exist_ok=True)
    for stale in shards.glob(".shard_*"):  # staging folders of jobs cut short with an interrupted run
        shutil.rmtree(stale, ignore_errors=True)

    t0 = time.perf_counter()
    if cfg.initial_conditions:
        # A file's other keys (a branch state's source) stay out of the jobs.
        keys = (*START_KEYS, "actions")
        ics = [{k: ic[k] for k in keys if k in ic} for ic in load_initial_conditions(cfg.initial_conditions, scene)]
    else:
        max_attempts = int(np.ceil(cfg.episodes * cfg.max_attempts_factor)) + 10
        ics = [ic.to_json() for ic in sample_starts(scene, max_attempts, seed=cfg.seed, sampler=cfg.sampler)]
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
            (asdict(cfg), str(work.path), str(shards)),
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
    if not enough and not (cfg.initial_conditions and metas):
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
        cfg.repo_id,
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
        push_to_hub(cfg.repo_id, root)
    return report


def _run_shards(
    cfg: GenerateConfig, pool, ics: list[dict], finished: dict[int, dict], shards: Path, on_shard
) -> list[dict]:
    """The shards that make the dataset, in index order: an interrupted run's, then new ones from the pool.

    The dataset is the first `episodes` successful rollouts in index order (fewer if `frames` are reached
    first), whatever the timing. The initial conditions in flight never outnumber the successes still
    missing, so no rollout past the last one needed is started. A new shard ends where a finished one
    begins, so that one is reused as it is.
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
            stop = min(
                frontier + cfg.shard_size,
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


def _finished(cfg: GenerateConfig, root: Path, settings: dict) -> GenerateReport:
    """An existing dataset: its report if --resume asks for exactly what it holds, else a named refusal.

    A finished run leaves no work folder, so its settings are kept in the dataset itself: a script that
    re-runs every step after a kill can pass --resume=true to a step that already finished.
    """
    hint = "pass --overwrite=true to replace it (or choose another --repo_id / --root)"
    if not cfg.resume:
        raise FileExistsError(f"a dataset already exists at {root}: {hint}")
    wanted = settings | {"episodes": cfg.episodes}
    file = root / SETTINGS_META
    if not file.exists():
        raise FileExistsError(f"a dataset already exists at {root}, made before its settings were recorded: {hint}")
    diff = changed(json.loads(file.read_text()), wanted, _IMPLICIT_SETTINGS)
    if diff:
        raise FileExistsError(f"the finished dataset at {root} was made with other settings ({describe(diff)}): {hint}")
    metas = read_episode_metadata(root)
    return GenerateReport(
        str(root),
        cfg.repo_id,
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
        aggregate_datasets([cfg.repo_id] * len(shard_roots), cfg.repo_id, roots=shard_roots, aggr_root=staging)
    (staging / EPISODES_META).write_text(
        "".join(json.dumps({"episode_index": i, **meta}) + "\n" for i, meta in enumerate(metas))
    )
    (staging / SETTINGS_META).write_text(json.dumps(settings, indent=1))
    write_replay(staging / REPLAY_META, *dataset_replay(staging, metas))
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


@contextlib.contextmanager
def _batched_image_embedding():
    """Within the block, LeRobot's writer and its aggregation embed PNG bytes in one batched call per table,
    quietly.

    lerobot 0.6.1 embeds them row by row (`datasets.map(embed_table_storage, batched=False)`), which
    rebuilds the Arrow schema for every frame: 3.7 of the writer's 6 ms per 96x96 frame, paid again for
    every frame when the shards are merged. Batched, the same function gives the same table (the dataset
    tests read the images back). Scoped to our writer and merge so a user's own LeRobot code is untouched;
    if a later LeRobot moves the function, the unpatched path still works.
    """
    try:
        from datasets.table import embed_table_storage
        from lerobot.datasets import dataset_writer, io_utils
    except ImportError:
        yield
        return
    # Each module looks the function up in its own namespace (the writer imported it by name).
    modules = [m for m in (dataset_writer, io_utils) if getattr(m, "embed_images", None) is not None]
    originals = [m.embed_images for m in modules]

    def embed_images(dataset):
        fmt = dataset.format
        return dataset.with_format("arrow").map(embed_table_storage, batched=True).with_format(**fmt)

    with _quiet_library_bars():
        for m in modules:
            m.embed_images = embed_images
        try:
            yield
        finally:
            for m, original in zip(modules, originals, strict=True):
                m.embed_images = original


@contextlib.contextmanager
def _quiet_library_bars():
    """No library bars under our own one bar per stage: `datasets` draws "Generating train split" and
    "Map" for every episode saved or loaded, LeRobot's aggregation "Copy data and videos". LeRobot's own
    SuppressProgressBars turns datasets' bars back on when it exits, so that switch is held off too."""
    from datasets.utils import logging as datasets_logging
    from lerobot.datasets import aggregate

    bars_were_on = datasets_logging.is_progress_bar_enabled()
    enable, library_tqdm = datasets_logging.enable_progress_bar, aggregate.tqdm
    datasets_logging.disable_progress_bar()
    datasets_logging.enable_progress_bar = lambda: None
    aggregate.tqdm = _SilentTqdm
    try:
        yield
    finally:
        datasets_logging.enable_progress_bar, aggregate.tqdm = enable, library_tqdm
        if bars_were_on:
            enable()


class _SilentTqdm:
    """Stands in for the `tqdm` module inside lerobot.datasets.aggregate."""

    @staticmethod
    def tqdm(iterable=None, *args, **kwargs):
        from tqdm.auto import tqdm

        return tqdm(iterable, *args, **{**kwargs, "disable": True})


class _Writer:
    """Writes episodes into a new LeRobotDataset at `root` (a job's staging folder)."""

    def __init__(self, cfg: GenerateConfig, root: Path):
        from lerobot.datasets.lerobot_dataset import LeRobotDataset

        scene = SCENES[cfg.env_id]
        pusht = cfg.env_id == PUSHT_ENV_ID  # lerobot/pusht's features, its image as video
        self.task = scene.task
        self.keys = PUSHT_FEATURE_KEYS if pusht else FEATURE_KEYS
        self.ds = LeRobotDataset.create(
            repo_id=cfg.repo_id,
            fps=cfg.fps,
            features=pusht_features(cfg.image_size) if pusht else features(scene, cfg.image_size),
            root=root,
            robot_type=None if pusht else "gcs_push_finger",
            use_videos=pusht,
            video_backend="pyav",
        )

    def add(self, arrays: dict[str, np.ndarray]) -> None:
        for t in range(len(arrays["action"])):
            self.ds.add_frame({k: arrays[k][t] for k in self.keys} | {"task": self.task})
        with _batched_image_embedding():
            self.ds.save_episode()

    def finish(self) -> None:
        self.ds.finalize()


def read_episode_metadata(root) -> list[dict]:
    path = Path(root) / EPISODES_META
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


def check_online() -> None:
    # `gcs-push` sets HF_HUB_OFFLINE=1 unless the caller set it, so the way out is to set it to 0.
    if os.environ.get("HF_HUB_OFFLINE", "0") not in ("0", "", "false", "False"):
        raise ValueError(
            "push_to_hub needs the network, but HF_HUB_OFFLINE is on: run with HF_HUB_OFFLINE=0, after `hf auth login`"
        )


def push_to_hub(repo_id: str, root: Path) -> None:
    """LeRobot's own upload; fails clearly without a network or a token."""
    check_online()
    from huggingface_hub import get_token
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    if not get_token():
        raise RuntimeError("push_to_hub needs a Hugging Face token: run `hf auth login` or set HF_TOKEN")
    LeRobotDataset(repo_id, root=root).push_to_hub()
