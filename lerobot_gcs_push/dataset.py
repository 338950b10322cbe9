"""Demonstrations: sample initial conditions, plan with GCS, roll out in the env, write a LeRobotDataset.

Crash safety: each finished episode is first saved as one compressed file in a work folder beside the
dataset (`<root>.work/`, written by atomic rename). The LeRobotDataset is assembled from those files in a
staging folder and moved into place only once it is finalized, so the cache never holds a half-written
dataset. `resume` re-uses the episode files of an interrupted run; `overwrite` starts again.

Determinism: the i-th initial condition and its episode seed depend only on (seed, i); episodes are
written in index order whatever the number of worker processes, so the dataset's contents do not
depend on `workers`.
"""

from __future__ import annotations

import contextlib
import itertools
import json
import multiprocessing as mp
import os
import shutil
import time
from collections import deque
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from lerobot_gcs_push.scene import (
    TASK,
    Scene,
    check_sampler,
    episode_seed,
    load_initial_conditions,
    sample_initial_conditions,
)

EPISODES_META = "meta/gcs_push_episodes.jsonl"
FEATURE_KEYS = ("observation.image", "observation.state", "observation.environment_state", "action")


@dataclass
class GenerateConfig:
    episodes: int = 100
    repo_id: str = "local/gcs_push_box"
    root: str | None = None  # default: $HF_LEROBOT_HOME/<repo_id>, where LeRobot looks first
    seed: int = 0
    workers: int = 2
    expert: str = "open-loop"
    method: str = "relaxation"
    sampler: str = "sobol"
    # A JSON list of {"box", "finger"} to use instead of the sampler (e.g. the policy states that
    # `gcs-push collect` picked); then every entry is tried once, and failures are left out.
    initial_conditions: str | None = None
    frames: int | None = None  # stop once this many frames are written (an equal-cost control)
    disturbances: bool = False
    fps: int = Scene.fps
    image_size: int = 96
    max_sim_time_s: float = Scene.timeout_s
    overwrite: bool = False
    resume: bool = False
    push_to_hub: bool = False
    progress: bool = True
    max_attempts_factor: float = 2.0  # give up after episodes * factor initial conditions

    def __post_init__(self) -> None:
        if self.episodes < 1:
            raise ValueError(f"episodes must be >= 1, got {self.episodes}")
        if self.workers < 1:
            raise ValueError(f"workers must be >= 1, got {self.workers}")
        if self.overwrite and self.resume:
            raise ValueError("choose one of --overwrite and --resume, not both")
        if "/" not in self.repo_id:
            raise ValueError(f"repo_id must look like 'owner/name', got {self.repo_id!r}")
        from lerobot_gcs_push.expert import EXPERTS

        if self.expert not in EXPERTS:
            raise ValueError(f"unknown expert {self.expert!r}: choose one of {EXPERTS}")
        check_sampler(self.sampler)
        if self.frames is not None and self.frames < 1:
            raise ValueError(f"frames must be >= 1, got {self.frames}")


def lerobot_home() -> Path:
    env = os.environ.get("HF_LEROBOT_HOME")
    if env:
        return Path(env).expanduser()
    from lerobot.utils.constants import HF_LEROBOT_HOME

    return Path(HF_LEROBOT_HOME)


def dataset_root(cfg: GenerateConfig) -> Path:
    return Path(cfg.root).expanduser() if cfg.root else lerobot_home() / cfg.repo_id


def features(image_size: int) -> dict:
    return {
        "observation.image": {"dtype": "image", "shape": (image_size, image_size, 3),
                              "names": ["height", "width", "channel"]},
        "observation.state": {"dtype": "float32", "shape": (2,), "names": ["finger_x", "finger_y"]},
        "observation.environment_state": {"dtype": "float32", "shape": (2,), "names": ["box_x", "box_y"]},
        "action": {"dtype": "float32", "shape": (2,), "names": ["finger_target_x", "finger_target_y"]},
    }


# --- one episode, in a worker process ------------------------------------------------------------
_WORKER: dict = {}


def _init_worker(cfg_dict: dict, work_path: str) -> None:
    import gymnasium as gym

    import lerobot_gcs_push  # noqa: F401  (registers the env)
    from lerobot_gcs_push.expert import ExpertConfig, GcsExpert
    from lerobot_gcs_push.planner import GcsPlanner

    cfg = GenerateConfig(**cfg_dict)
    env = gym.make("GcsPushBox-v0", fps=cfg.fps, image_size=cfg.image_size, disturbances=cfg.disturbances,
                   max_sim_time_s=cfg.max_sim_time_s).unwrapped
    planner = GcsPlanner(env.scene, method=cfg.method)
    _WORKER.update(cfg=cfg, env=env, work=WorkDir(Path(work_path)), expert=GcsExpert(planner, cfg.fps, ExpertConfig(mode=cfg.expert, method=cfg.method)))


def _run_episode(job: tuple[int, dict]) -> dict:
    from lerobot_gcs_push.expert import rollout

    index, ic = job
    env, expert, cfg = _WORKER["env"], _WORKER["expert"], _WORKER["cfg"]
    frames: dict[str, list] = {k: [] for k in FEATURE_KEYS}

    def record(obs, action, info):
        frames["observation.image"].append(obs["pixels"])
        frames["observation.state"].append(np.asarray(obs["agent_pos"], np.float32))
        frames["observation.environment_state"].append(np.asarray(info["box"], np.float32))
        frames["action"].append(np.asarray(action, np.float32))

    t0 = time.perf_counter()
    result = rollout(env, expert, ic["box"], ic["finger"], seed=episode_seed(cfg.seed, index), on_step=record)
    plan = result["plan"]
    meta = {
        "index": index, "box_initial": ic["box"], "finger_initial": ic["finger"],
        "success": result["success"], "final_distance": result["final_distance"],
        "sim_time_s": result["sim_time_s"], "plan_time_s": result["plan_time_s"],
        "plan_cost": plan.cost, "plan_lower_bound": plan.lower_bound, "modes": plan.modes,
        "replans": result["replans"], "num_frames": len(frames["action"]),
        "wall_time_s": time.perf_counter() - t0, "disturbances": result["disturbances"],
    }
    arrays = {k: np.stack(v) for k, v in frames.items()} if result["success"] else {}
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
                    f"an interrupted run left {self.path}: pass --resume to continue it or --overwrite to start again")
            old = json.loads(self.settings_file().read_text()) if self.settings_file().exists() else None
            if old is not None and old != settings:
                diff = {k: (old.get(k), v) for k, v in settings.items() if old.get(k) != v}
                raise ValueError(f"--resume with different settings than the interrupted run: {diff}")
        self.path.mkdir(parents=True, exist_ok=True)
        _atomic_write(self.settings_file(), json.dumps(settings, indent=1).encode())

    def episode_file(self, index: int) -> Path:
        return self.path / f"episode_{index:06d}.npz"

    def done(self) -> dict[int, dict]:
        out = {}
        for f in sorted(self.path.glob("episode_*.npz")):
            with np.load(f, allow_pickle=False) as z:
                out[int(f.stem.split("_")[1])] = json.loads(str(z["meta"]))
        return out

    def save(self, result: dict) -> None:
        meta = result["meta"]
        path = self.episode_file(meta["index"])
        tmp = path.with_name("." + path.name)  # not matched by done()'s glob until renamed
        np.savez_compressed(tmp, meta=json.dumps(meta), **{k.replace(".", "__"): v for k, v in result["arrays"].items()})
        os.replace(tmp, path)

    def load_arrays(self, index: int) -> dict[str, np.ndarray]:
        with np.load(self.episode_file(index), allow_pickle=False) as z:
            return {k: z[k.replace(".", "__")] for k in FEATURE_KEYS}


def _atomic_write(path: Path, data: bytes) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_bytes(data)
    os.replace(tmp, path)


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


def generate(cfg: GenerateConfig) -> GenerateReport:
    scene = Scene()
    root = dataset_root(cfg)
    work = WorkDir(root.with_name(root.name + ".work"))
    if cfg.overwrite:
        shutil.rmtree(root, ignore_errors=True)
        shutil.rmtree(work.path, ignore_errors=True)
    if root.exists():
        raise FileExistsError(f"a dataset already exists at {root}: pass --overwrite to replace it "
                              f"(or choose another --repo-id / --root)")
    settings = {k: v for k, v in asdict(cfg).items() if k not in ("workers", "overwrite", "resume", "progress",
                                                                    "push_to_hub", "episodes", "root")}
    work.open(settings, cfg.resume)

    t0 = time.perf_counter()
    done = work.done()
    if cfg.initial_conditions:
        ics = [{"box": ic["box"], "finger": ic["finger"]} for ic in load_initial_conditions(cfg.initial_conditions)]
        max_attempts = len(ics)
    else:
        max_attempts = int(np.ceil(cfg.episodes * cfg.max_attempts_factor)) + 10
        ics = [ic.to_json() for ic in sample_initial_conditions(scene, max_attempts, seed=cfg.seed,
                                                                sampler=cfg.sampler)]
    todo = ((i, ics[i]) for i in range(max_attempts) if i not in done)

    bar = _progress(cfg)
    writer = _Writer(cfg, root)
    pool = None
    failures = 0
    try:
        if cfg.workers > 1:
            # concurrent.futures, not multiprocessing.Pool: a Pool silently replaces a worker that dies
            # (a crash in the renderer, the OOM killer) and then waits forever for its episode.
            pool = ProcessPoolExecutor(cfg.workers, mp_context=mp.get_context("forkserver"),
                                       initializer=_init_worker, initargs=(asdict(cfg), str(work.path)))
            fresh = _in_order(pool, todo, window=2 * cfg.workers, work=work.path)
        else:
            _init_worker(asdict(cfg), str(work.path))
            fresh = map(_run_episode, todo)
        # Walk the indices in order, taking finished episodes from the work folder and new ones from the
        # workers (imap keeps their order), so the dataset is the same whatever the worker count.
        for index in range(max_attempts):
            meta = done[index] if index in done else next(fresh)
            if not meta["success"]:
                failures += 1
                bar.set_postfix(failures=failures)
                continue
            writer.add(meta, work.load_arrays(index))
            bar.update(1)
            if writer.episodes == cfg.episodes or (cfg.frames is not None and writer.frames >= cfg.frames):
                break
        else:
            # A given list is tried once and its failures are reported, not an error.
            if not (cfg.initial_conditions and writer.episodes):
                raise RuntimeError(f"only {writer.episodes} of {cfg.episodes} episodes succeeded after "
                               f"{max_attempts} initial conditions; their records are in {work.path}")
    finally:
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)
        bar.close()
    attempts = index + 1
    writer.finish()
    shutil.rmtree(work.path, ignore_errors=True)
    wall = time.perf_counter() - t0
    report = GenerateReport(str(root), cfg.repo_id, writer.episodes, writer.frames, attempts, failures, wall,
                            60.0 * writer.episodes / wall if wall > 0 else float("inf"))
    if cfg.push_to_hub:
        push_to_hub(cfg.repo_id, root)
    return report


def _in_order(pool: ProcessPoolExecutor, jobs, window: int, work: Path):
    """Episode results in job order, with at most `window` episodes in flight, so that stopping early
    (enough successes) wastes little work."""
    jobs = iter(jobs)
    pending = deque(pool.submit(_run_episode, job) for job in itertools.islice(jobs, window))
    while pending:
        try:
            result = pending.popleft().result()
        except BrokenProcessPool as e:
            raise RuntimeError(f"a demonstration worker died ({e}); the finished episodes are kept in {work}: "
                               f"run again with --resume") from e
        job = next(jobs, None)
        if job is not None:
            pending.append(pool.submit(_run_episode, job))
        yield result


def _progress(cfg: GenerateConfig):
    from tqdm.auto import tqdm

    return tqdm(total=cfg.episodes, desc="demonstrations", unit="ep", disable=not cfg.progress,
                dynamic_ncols=True)


@contextlib.contextmanager
def _batched_image_embedding():
    """Within the block, LeRobot's writer embeds an episode's PNG bytes in one batched call.

    lerobot 0.6.1 embeds them row by row (`datasets.map(embed_table_storage, batched=False)`), which
    rebuilds the Arrow schema for every frame: 3.7 of the writer's 6 ms per 96x96 frame, and the main
    process is the pipeline's bottleneck. Batched, the same function gives the same table (the dataset
    tests read the images back). Scoped to our writer so a user's own LeRobot code is untouched; if a
    later LeRobot moves the function, the unpatched path still works.
    """
    try:
        from datasets.table import embed_table_storage
        from lerobot.datasets import dataset_writer
    except ImportError:
        yield
        return
    original = getattr(dataset_writer, "embed_images", None)
    if original is None:
        yield
        return

    def embed_images(dataset):
        fmt = dataset.format
        return dataset.with_format("arrow").map(embed_table_storage, batched=True).with_format(**fmt)

    dataset_writer.embed_images = embed_images
    try:
        yield
    finally:
        dataset_writer.embed_images = original


class _Writer:
    """Writes episodes into a staging LeRobotDataset; `finish` finalizes it and moves it into place."""

    def __init__(self, cfg: GenerateConfig, root: Path):
        from lerobot.datasets.lerobot_dataset import LeRobotDataset

        self.root = root
        self.staging = root.with_name(root.name + ".staging")
        shutil.rmtree(self.staging, ignore_errors=True)
        self.ds = LeRobotDataset.create(repo_id=cfg.repo_id, fps=cfg.fps, features=features(cfg.image_size),
                                        root=self.staging, robot_type="gcs_push_finger", use_videos=False,
                                        video_backend="pyav")
        self.episodes = 0
        self.frames = 0
        self.lines: list[str] = []

    def add(self, meta: dict, arrays: dict[str, np.ndarray]) -> None:
        n = len(arrays["action"])
        for t in range(n):
            self.ds.add_frame({k: arrays[k][t] for k in FEATURE_KEYS} | {"task": TASK})
        with _batched_image_embedding():
            self.ds.save_episode()
        self.lines.append(json.dumps({"episode_index": self.episodes, **meta}))
        self.episodes += 1
        self.frames += n

    def finish(self) -> None:
        self.ds.finalize()
        (self.staging / EPISODES_META).write_text("\n".join(self.lines) + "\n")
        self.root.parent.mkdir(parents=True, exist_ok=True)
        os.replace(self.staging, self.root)


def read_episode_metadata(root) -> list[dict]:
    path = Path(root) / EPISODES_META
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


def push_to_hub(repo_id: str, root: Path) -> None:
    """LeRobot's own upload; fails clearly without a network or a token."""
    if os.environ.get("HF_HUB_OFFLINE", "0") not in ("0", "", "false", "False"):
        raise RuntimeError("--push-to-hub needs the network, but HF_HUB_OFFLINE is set; unset it and log in "
                           "with `huggingface-cli login` first")
    from huggingface_hub import get_token
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    if not get_token():
        raise RuntimeError("--push-to-hub needs a Hugging Face token: run `huggingface-cli login` or set HF_TOKEN")
    LeRobotDataset(repo_id, root=root).push_to_hub()
