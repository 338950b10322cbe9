"""The paper's evaluation protocol (section IV) for any set of policies: records, tables, figures.

In any registered env (`env_id`): the box that cannot turn is scored as in the paper, a rotating slider by
the env's coverage rule, with its heading and pose in the records; the GCS experts and regret are the
box's only, for now.

Policies: `gcs-open-loop` (plan once, execute), `gcs-closed-loop` (replan after disturbances), or a
LeRobot `pretrained_model` directory (loaded through LeRobot's own factory and processors; its action
chunks run exactly as in `lerobot-eval`). With `disturbances`, each closed-loop or learned policy is also
run under the paper's force disturbances.

Every run appends one JSON line to `runs.jsonl` as soon as it ends (with its trajectory saved first), so
an interrupted evaluation keeps its finished runs and continues where it stopped.
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from lerobot_gcs_push.files import atomic_path
from lerobot_gcs_push.registration import ENV_ID, SCENES, sample_starts
from lerobot_gcs_push.scene import (
    TASK,
    check_sampler,
    check_seed,
    episode_seed,
    load_initial_conditions,
)
from lerobot_gcs_push.success import success_measures

GCS_POLICIES = ("gcs-open-loop", "gcs-closed-loop")
# The named evaluation sets: the paper's protocol set (uniform, seed 1000) and the hard set (seed 3000).
NAMED_SET_SEEDS = {"uniform": 1000, "sobol": 1000, "hard": 3000, "hard_v2": 3000}
GCS_CHUNK_STEPS = 8  # the experts act every step; their regret is scored over the CPU preset's chunk length
TIMING_FIELDS = ("run_time_s", "plan_time_s", "total_time_s")
# The paper's Tables I and III, for the columns our variants reproduce.
PAPER = {
    ("gcs", False): {
        "label": "GCS Open Loop",
        "success": 1.00,
        "success_sim_time_s": 111.97,
        "run_time_s": 5.50,
        "plan_time_s": 126.07,
        "total_time_s": 131.57,
    },
    ("learned", False): {
        "label": "Diffusion Policy",
        "success": 0.67,
        "success_0.2": 0.775,
        "success_sim_time_s": 259.36,
        "run_time_s": 63.28,
        "plan_time_s": 0.0,
        "total_time_s": 63.28,
    },
    ("learned", True): {
        "label": "Diffusion Policy (Disturbances)",
        "success": 0.65,
        "success_0.2": 0.775,
        "success_sim_time_s": 259.58,
        "run_time_s": 80.91,
        "plan_time_s": 0.0,
        "total_time_s": 80.91,
    },
}


def check_policy(policy: str) -> str:
    """`policy` as given (it labels the records), once it names an expert or a pretrained_model folder,
    from the working folder or shipped (`shipped.shipped_path`)."""
    from lerobot_gcs_push.checkpoints import is_pretrained_dir
    from lerobot_gcs_push.shipped import shipped_path

    if policy not in GCS_POLICIES and not is_pretrained_dir(shipped_path(policy)):
        raise ValueError(
            f"unknown policy {policy!r}: use {' or '.join(GCS_POLICIES)}, or a LeRobot pretrained_model "
            f"directory (config.json and model.safetensors)"
        )
    return policy


def check_device(device: str) -> str:
    if device not in ("cpu", "cuda", "mps") and not device.startswith("cuda:"):
        raise ValueError(f"unknown device {device!r}: use cpu, cuda, cuda:N or mps")
    return device


@dataclass
class EvaluateConfig:
    # The registered env: GcsPushBox-v0 (the box that cannot turn), GcsPushBoxSE2-v0 or GcsPushT-v0
    # (rotating sliders, which succeed by coverage; their GCS experts plan through contact; no regret yet).
    env_id: str = ENV_ID
    # gcs-open-loop, gcs-closed-loop, or LeRobot pretrained_model directories:
    # --policies='[gcs-open-loop,policies/diffusion_cpu]'.
    policies: list[str] = field(default_factory=lambda: ["gcs-open-loop"])
    # A JSON list of {"box": [x, y], "finger": [x, y]} (and "heading" for a rotating slider); default:
    # sampled from the env's scene with `sampler` and `seed`.
    initial_conditions: str | None = None
    # How many initial conditions to sample (without initial_conditions).
    num_initial_conditions: int = 20
    # Seeds the initial conditions and every run's env (disturbances, diffusion noise); default: the named
    # set of the sampler, 1000 (the paper's protocol set, uniform) or 3000 (the hard set).
    seed: int | None = None
    # The paper samples its evaluation set from the training distribution (uniform); `hard` is the
    # named set of configurations a cloned policy gets wrong (scene.py), with its own seed; `hard_v2` adds
    # fingers far from the box (opposite corners among them).
    sampler: str = "uniform"
    # Regret of each executed chunk against the GCS cost-to-go (expert.chunk_regret); a chunk above
    # `large_regret_m` is a mistake (the GCS experts stay under 0.5 m per chunk, tracking lag included,
    # unless a disturbance strikes). Default: on where the env has a GCS expert (the box).
    regret: bool | None = None
    # Metres of regret that make a chunk a mistake.
    large_regret_m: float = 0.5
    # Runs per initial condition.
    runs: int = 5
    # Also run every closed-loop or learned policy under the paper's random pushes.
    disturbances: bool = False
    # Where runs.jsonl, tables.md, summary.json, figures and videos go; a re-run continues there, unless
    # a learned policy's weights changed since (then it stops and asks for --overwrite).
    output_dir: str = "outputs/eval"
    # Torch device of learned policies: cpu, cuda, cuda:N or mps.
    device: str = "cpu"
    # Worker processes (or Ray actors).
    workers: int = 1
    # Simulated seconds before a run counts as failed. Default: the env's own (the paper's 500 for the Drake
    # envs, gym-pusht's 30, its 300 steps).
    timeout_s: float | None = None
    # Success radii (m) of the box centre around the goal: the paper's 0.1 and a looser one. A rotating
    # slider succeeds by the env's coverage instead, and its tables give the mean coverage.
    success_thresholds: tuple[float, float] = (0.1, 0.2)
    # Repo id (or path) of the training dataset, for Fig. 4.
    dataset: str | None = None
    # Videos of run 0 of the first `videos` initial conditions, per policy.
    videos: int = 2
    # Delete an earlier evaluation in output_dir first.
    overwrite: bool = False
    # process (worker processes here) or ray (Ray actors; see lerobot_gcs_push.workers).
    backend: str = "process"
    # With backend ray: "auto" or "HOST:PORT" joins a running cluster; none starts Ray here.
    ray_address: str | None = None

    def __post_init__(self) -> None:
        from lerobot_gcs_push.expert import check_cost_to_go
        from lerobot_gcs_push.rollout import check_env_id

        check_env_id(self.env_id)
        if not self.policies:
            raise ValueError("give at least one policy")
        if self.runs < 1 or self.num_initial_conditions < 1 or self.workers < 1:
            raise ValueError("runs, num_initial_conditions and workers must be >= 1")
        if self.timeout_s is None:
            self.timeout_s = SCENES[self.env_id].timeout_s
        if not 0 < self.timeout_s < float("inf"):
            raise ValueError(f"timeout_s must be positive and finite, got {self.timeout_s}")
        for p in self.policies:
            check_policy(p)
        if self.regret is None:
            self.regret = not SCENES[self.env_id].rotates
        elif self.regret:
            check_cost_to_go(self.env_id, "regret is scored against it: leave --regret unset or false")
        check_sampler(self.sampler)
        if self.seed is None:
            self.seed = NAMED_SET_SEEDS[self.sampler]
        check_seed(self.seed)
        check_device(self.device)
        if self.dataset is not None:  # read for Fig. 4 only at the end: a typo must not cost the evaluation
            from lerobot_gcs_push.dataset import lerobot_home

            if not (Path(self.dataset).is_dir() or (lerobot_home() / self.dataset).is_dir()):
                raise ValueError(
                    f"dataset {self.dataset!r} is neither a folder nor in the LeRobot cache ({lerobot_home()})"
                )
        from lerobot_gcs_push.workers import check_backend

        check_backend(self.backend, self.ray_address)


def weights_fingerprint(policy: str) -> str:
    """The first 16 hex digits of the sha256 of a learned policy's model.safetensors."""
    from lerobot_gcs_push.shipped import shipped_path

    h = hashlib.sha256()
    with open(Path(shipped_path(policy)) / "model.safetensors", "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()[:16]


def changed_weights(cfg: EvaluateConfig, unrecorded_changed: bool = False) -> list[str]:
    """Learned policies of cfg whose weights differ from those that made the runs already in output_dir.

    A policy is named by its folder, and retraining into the same folder is common: without this check a
    re-run would resume and mix the old weights' runs with the new ones' under one label. Folders written
    before weights were recorded count as unchanged unless `unrecorded_changed`.
    """
    path = Path(cfg.output_dir) / "settings.json"
    if not path.is_file():
        return []
    stored = json.loads(path.read_text()).get("policy_weights", {})
    learned = [p for p in cfg.policies if p not in GCS_POLICIES]
    return [p for p in learned if stored.get(p) != weights_fingerprint(p) and (p in stored or unrecorded_changed)]


def variants(cfg: EvaluateConfig) -> list[tuple[str, bool]]:
    out = []
    for p in cfg.policies:
        out.append((p, False))
        if cfg.disturbances and p != "gcs-open-loop":
            out.append((p, True))
    return out


def variant_label(policy: str, disturbances: bool) -> str:
    name = policy if policy in GCS_POLICIES else _learned_name(policy)
    return name + (" +dist" if disturbances else "")


def _learned_name(path: str) -> str:
    p = Path(path).resolve()
    parts = [x for x in p.parts[-4:] if x not in ("pretrained_model", "checkpoints")]
    return "dp:" + "/".join(parts[-2:])


def _slug(label: str) -> str:
    return "".join(c if c.isalnum() else "_" for c in label).strip("_")


def video_path(out: Path, label: str, ic_index: int) -> Path:
    """Where run 0 of a variant on an initial condition is filmed (the first `videos` conditions)."""
    return Path(out) / "videos" / f"{_slug(label)}_ic{ic_index:03d}.mp4"


def initial_conditions(cfg: EvaluateConfig) -> list[dict]:
    scene = SCENES[cfg.env_id]
    if cfg.initial_conditions:
        ics = load_initial_conditions(cfg.initial_conditions, scene)
        for i, ic in enumerate(ics):
            scene.validate_start(ic, f"initial condition {i}")
        return ics
    return [ic.to_json() for ic in sample_starts(scene, cfg.num_initial_conditions, seed=cfg.seed, sampler=cfg.sampler)]


# --- rollouts, in worker processes --------------------------------------------------------------------
class _Lazy(dict):
    """A dict that makes a missing key's value with `make(key)`."""

    def __init__(self, make):
        super().__init__()
        self._make = make

    def __missing__(self, key):
        self[key] = value = self._make(key)
        return value


class _Runner:
    def __init__(self, cfg: EvaluateConfig, out: Path):
        import lerobot_gcs_push  # noqa: F401
        from lerobot_gcs_push.registration import make_env

        self.cfg, self.out = cfg, out

        # Made once each, the env with disturbances only if a run asks for it (gym-pusht has none).
        self.envs = _Lazy(
            lambda d: make_env(
                cfg.env_id, disturbances=d, max_sim_time_s=cfg.timeout_s, success_threshold=cfg.success_thresholds[0]
            )
        )
        self._experts: dict = {}
        self._learned: dict = {}
        self._cost_to_go = None

    def regret(self, boxes, fingers, every: int) -> dict:
        from lerobot_gcs_push.expert import CostToGo, chunk_regret

        if self._cost_to_go is None:
            self._cost_to_go = CostToGo(self.envs[False].scene)
        chunks = chunk_regret(self._cost_to_go, boxes, fingers, every)
        regrets = np.array([c["regret"] for c in chunks])
        large = [c for c in chunks if c["regret"] > self.cfg.large_regret_m]
        fps = self.envs[False].fps
        return {
            # Over the scored chunks; an unscored one stays NaN in regret_chunks and the summary counts it.
            "regret": float(np.nansum(regrets)),
            "value_initial": chunks[0]["v_before"] if chunks else 0.0,
            "first_large_regret_s": large[0]["step"] / fps if large else None,
            # Chunk start states (box, finger) with their regret: where active data collection branches.
            "regret_chunks": [
                [c["step"], round(c["regret"], 4), *np.round(c["box"], 4).tolist(), *np.round(c["finger"], 4).tolist()]
                for c in chunks
            ],
        }

    def expert(self, name: str):
        if name not in self._experts:
            from lerobot_gcs_push.expert import ExpertConfig, make_expert

            env = self.envs[False]
            config = ExpertConfig(mode=name.removeprefix("gcs-"))
            expert = make_expert(env.scene, env.fps, config, self._experts.get("_planner"))
            self._experts["_planner"] = expert.planner  # one planner for both experts
            self._experts[name] = expert
        return self._experts[name]

    def learned(self, path: str):
        if path not in self._learned:
            from lerobot_gcs_push.shipped import shipped_path

            self._learned[path] = LearnedPolicy(shipped_path(path), self.cfg.device, self.envs[False].task)
        return self._learned[path]

    def run(self, job: dict) -> dict:
        policy, dist, i, r, ic = job["policy"], job["disturbances"], job["ic_index"], job["run"], job["ic"]
        env = self.envs[dist]
        seed = episode_seed(self.cfg.seed, (i * self.cfg.runs + r) * 2 + int(dist))
        frames = [] if job["video"] else None
        traj = Trajectory(env.scene.rotates)

        def on_step(obs, action, info):
            traj.add(info)
            if frames is not None:
                frames.append(env.render())

        from lerobot_gcs_push.rollout import rollout

        actor = self.expert(policy) if policy in GCS_POLICIES else self.learned(policy)
        res = rollout(
            env,
            actor,
            ic["box"],
            ic["finger"],
            seed=seed,
            on_step=on_step,
            heading=ic.get("heading"),
            pusht_state=ic.get("pusht_state"),
        )
        plan_time = res.get("plan_time_s", 0.0)
        chunk = getattr(actor, "chunk_steps", GCS_CHUNK_STEPS)
        traj.add_final(res)
        label = variant_label(policy, dist)
        tdir = self.out / "trajectories" / _slug(label)
        tdir.mkdir(parents=True, exist_ok=True)
        tpath = tdir / f"ic{i:03d}_run{r}.npz"
        traj.save(tpath)
        if frames:
            frames.append(env.render())
            from lerobot_gcs_push.videos import write_video

            write_video(video_path(self.out, label, i), frames, env.fps)
        regret = self.regret(traj.box, traj.finger, chunk) if self.cfg.regret else {}
        return regret | {
            "policy": policy,
            "label": label,
            "disturbances": dist,
            "initial_condition_index": i,
            "box_initial": ic["box"],
            "finger_initial": ic["finger"],
            "run": r,
            "seed": seed,
            "success": bool(res["success"]),
            **self._success_measures(ic, res),
            "final_distance": res["final_distance"],
            "sim_time_s": res["sim_time_s"],
            "run_time_s": res["run_time_s"],
            "plan_time_s": plan_time,
            "total_time_s": res["run_time_s"] + plan_time,
            "num_disturbances": len(res.get("disturbances", [])),
            "trajectory": str(tpath.relative_to(self.out)),
        }

    def _success_measures(self, ic: dict, res: dict) -> dict:
        """The box's looser radius; a rotating slider's heading, start and end, and final coverage."""
        if "coverage" not in res:
            thr2 = self.cfg.success_thresholds[1]
            return {f"success_{thr2:g}": bool(res["success"] or res["final_distance"] <= thr2)}
        return {
            "heading_initial": ic.get("heading", 0.0),
            "slider_pose_final": res["slider_pose_final"],
            "coverage": res["coverage"],
            "heading_error": res["heading_error"],
        }


class Trajectory:
    """A run's states, one row per step and the final state, as saved beside its record: finger and box
    positions, and a rotating slider's pose (x, y, heading) too."""

    def __init__(self, rotates: bool):
        self.rotates = rotates
        self.finger: list[np.ndarray] = []
        self.box: list[np.ndarray] = []
        self.slider_pose: list[np.ndarray] = []

    def add(self, info: dict) -> None:
        self.finger.append(np.asarray(info["finger"], float))
        self.box.append(np.asarray(info["box"], float))
        if self.rotates:
            self.slider_pose.append(np.asarray(info["slider_pose"], float))

    def add_final(self, summary: dict) -> None:
        """The state the episode ended in, from the rollout's summary (no step follows it)."""
        self.finger.append(np.asarray(summary["finger_final"], float))
        self.box.append(np.asarray(summary["box_final"], float))
        if self.rotates:
            self.slider_pose.append(np.asarray(summary["slider_pose_final"], float))

    def save(self, path: Path) -> None:
        arrays = {"finger": np.array(self.finger), "box": np.array(self.box)}
        if self.rotates:
            arrays["slider_pose"] = np.array(self.slider_pose)
        with atomic_path(path) as tmp, open(tmp, "wb") as f:
            np.savez_compressed(f, **arrays)


class LearnedPolicy:
    """A LeRobot checkpoint as a `rollout.Policy`, run the way lerobot-eval runs it (processors, action
    queue: a chunk is predicted every `chunk_steps` steps)."""

    def __init__(self, path: str, device: str, task: str = TASK):
        import torch
        from lerobot.configs.policies import PreTrainedConfig
        from lerobot.envs.utils import preprocess_observation
        from lerobot.policies.factory import make_policy, make_pre_post_processors

        from lerobot_gcs_push.lerobot_plugin import GcsPushEnvConfig

        cfg = PreTrainedConfig.from_pretrained(path)
        cfg.pretrained_path = path
        cfg.device = device
        self.policy = make_policy(cfg, env_cfg=GcsPushEnvConfig())
        self.policy.eval()
        self.pre, self.post = make_pre_post_processors(
            cfg, pretrained_path=path, preprocessor_overrides={"device_processor": {"device": device}}
        )
        self.torch, self._preprocess = torch, preprocess_observation  # resolved once, not at every step
        self.task = task  # the env's language instruction, as lerobot-eval passes it
        self.chunk_steps = int(cfg.n_action_steps)  # actions executed per predicted chunk

    def reset(self, obs, info: dict, seed: int | None) -> None:
        # The diffusion sampler's noise comes from torch's global generator: seeded per episode, a run
        # is reproducible whatever ran before it in this process.
        if seed is not None:
            self.torch.manual_seed(seed)
        self.policy.reset()

    def act(self, obs, info: dict) -> np.ndarray:
        batch = self._preprocess({"pixels": obs["pixels"][None], "agent_pos": obs["agent_pos"][None]})
        batch["task"] = [self.task]
        with self.torch.inference_mode():
            action = self.post(self.policy.select_action(self.pre(batch)))
        return action.reshape(-1)[:2].cpu().numpy().astype(np.float64)


_RUNNER: dict = {}


def _init_worker(cfg_dict: dict, out: str) -> None:
    cfg = EvaluateConfig(**cfg_dict)
    if cfg.workers > 1 or cfg.backend != "process":  # a pool's worker: one process per core
        try:
            import torch

            torch.set_num_threads(1)
        except ImportError:  # pragma: no cover
            pass
    _RUNNER["r"] = _Runner(cfg, Path(out))


def _run_job(job: dict) -> dict:
    return _RUNNER["r"].run(job)


# --- the records ----------------------------------------------------------------------------------------
def read_runs(path: Path) -> list[dict]:
    """Finished runs; a line cut short by a kill is dropped (its run is simply done again)."""
    if not path.exists():
        return []
    out = []
    for line in path.read_text().splitlines():
        try:
            out.append(json.loads(line))
        except json.JSONDecodeError:
            continue
    return out


def _key(rec: dict) -> tuple:
    return rec["policy"], bool(rec["disturbances"]), int(rec["initial_condition_index"]), int(rec["run"])


def evaluate(cfg: EvaluateConfig) -> dict:
    out = Path(cfg.output_dir)
    ics = initial_conditions(cfg)
    settings = {
        "initial_conditions": ics,
        "seed": cfg.seed,
        "runs": cfg.runs,
        "timeout_s": cfg.timeout_s,
        "success_thresholds": list(cfg.success_thresholds),
        "regret": cfg.regret,
        "large_regret_m": cfg.large_regret_m,
        "env_id": cfg.env_id,
    }
    runs_path = out / "runs.jsonl"
    if cfg.overwrite and out.exists():
        import shutil

        if not ((out / "runs.jsonl").is_file() or (out / "settings.json").is_file()) and any(out.iterdir()):
            raise FileExistsError(
                f"--overwrite replaces an evaluation, and {out} holds none (no runs.jsonl): choose another --output_dir"
            )
        shutil.rmtree(out)
    out.mkdir(parents=True, exist_ok=True)
    settings_path = out / "settings.json"
    stored = json.loads(settings_path.read_text()) if settings_path.exists() else None
    # Folders written before weights were recorded hold none: their runs are taken as they are.
    weights = stored.pop("policy_weights", {}) if stored else {}
    # Folders written before these settings were recorded were made with the box and its regret on.
    implicit = {"regret": True, "large_regret_m": EvaluateConfig.large_regret_m, "env_id": ENV_ID}
    if stored is not None and implicit | stored != settings:
        raise FileExistsError(
            f"{out} holds an evaluation with other initial conditions or settings; "
            f"pass --overwrite=true or choose another --output_dir"
        )
    changed = changed_weights(cfg)
    if changed:
        raise FileExistsError(
            f"{out} holds runs of {', '.join(changed)} made with other weights (model.safetensors changed "
            f"since); pass --overwrite=true or choose another --output_dir"
        )
    weights |= {p: weights_fingerprint(p) for p in cfg.policies if p not in GCS_POLICIES}
    with atomic_path(settings_path) as tmp:
        tmp.write_text(json.dumps(settings | {"policy_weights": weights}, indent=1))

    records = read_runs(runs_path)
    # Rewrite without any torn last line, so that appends start on a fresh line.
    with atomic_path(runs_path) as tmp:  # a kill here must not cost the finished runs
        tmp.write_text("".join(json.dumps(r) + "\n" for r in records))
    done = {_key(r) for r in records}
    jobs = []
    for policy, dist in variants(cfg):
        for i, ic in enumerate(ics):
            for r in range(cfg.runs):
                if (policy, dist, i, r) not in done:
                    jobs.append(
                        {
                            "policy": policy,
                            "disturbances": dist,
                            "ic_index": i,
                            "run": r,
                            "ic": ic,
                            "video": r == 0 and i < cfg.videos,
                        }
                    )
    _run_all(cfg, out, jobs, runs_path)
    records = [r for r in read_runs(runs_path) if (r["policy"], r["disturbances"]) in set(variants(cfg))]
    summary = summarize(cfg, records, ics)
    with atomic_path(out / "summary.json") as tmp:
        tmp.write_text(json.dumps({k: v for k, v in summary.items() if k != "tables_md"}, indent=1))
    with atomic_path(out / "tables.md") as tmp:
        tmp.write_text(summary["tables_md"])
    from lerobot_gcs_push.figures import make_figures

    summary["figures"] = make_figures(cfg, out, records, ics)
    return summary


def _run_all(cfg: EvaluateConfig, out: Path, jobs: list[dict], runs_path: Path) -> None:
    if not jobs:
        return
    from tqdm.auto import tqdm

    bar = tqdm(total=len(jobs), desc="evaluation runs", unit="run", dynamic_ncols=True)
    ok = 0

    def append(rec: dict) -> None:
        nonlocal ok
        with open(runs_path, "a") as f:
            f.write(json.dumps(rec) + "\n")
            f.flush()
            os.fsync(f.fileno())
        ok += rec["success"]
        bar.update(1)
        bar.set_postfix(success=f"{ok}/{bar.n}")

    from lerobot_gcs_push.workers import open_pool

    try:
        with open_pool(
            cfg.backend,
            cfg.workers,
            _init_worker,
            (asdict(cfg), str(out)),
            address=cfg.ray_address,
            hint=f"the finished runs are kept in {runs_path}: run the same command again to go on",
        ) as pool:
            for rec in pool.map(_run_job, jobs):
                append(rec)
    finally:
        bar.close()


# --- tables -----------------------------------------------------------------------------------------------
def _mean(xs) -> float | None:
    xs = list(xs)
    return float(np.mean(xs)) if xs else None


def summarize(cfg: EvaluateConfig, records: list[dict], ics: list[dict]) -> dict:
    s2 = success_measures(cfg).loose_key
    per_variant = {}
    for policy, dist in variants(cfg):
        recs = [r for r in records if r["policy"] == policy and r["disturbances"] == dist]
        succ = [r for r in recs if r["success"]]
        per_variant[variant_label(policy, dist)] = {
            "policy": policy,
            "disturbances": dist,
            "runs": len(recs),
            "success": _mean(r["success"] for r in recs),
            s2: _mean(r[s2] for r in recs),
            "success_sim_time_s": _mean(r["sim_time_s"] for r in succ),
            "run_time_s": _mean(r["run_time_s"] for r in succ),
            "plan_time_s": _mean(r["plan_time_s"] for r in succ),
            "total_time_s": _mean(r["total_time_s"] for r in succ),
            **_regret_summary(recs, cfg.large_regret_m),
            "per_initial_condition": {
                i: {
                    "success": _mean(r["success"] for r in recs if r["initial_condition_index"] == i),
                    s2: _mean(r[s2] for r in recs if r["initial_condition_index"] == i),
                }
                for i in range(len(ics))
            },
        }
    return {"variants": per_variant, "tables_md": _tables_md(cfg, per_variant, ics)}


def _regret_summary(recs: list[dict], large: float) -> dict:
    recs = [r for r in recs if "regret" in r]
    if not recs:
        return {}
    chunks = np.array([c[1] for r in recs for c in r["regret_chunks"]], float)
    unscored = int(np.isnan(chunks).sum())
    chunks = chunks[np.isfinite(chunks)]
    firsts = [r["first_large_regret_s"] for r in recs if r["first_large_regret_s"] is not None]
    return {
        "regret_mean": _mean(r["regret"] for r in recs),
        "regret_p95": float(np.percentile([r["regret"] for r in recs], 95)),
        "chunk_regret_p95": float(np.percentile(chunks, 95)) if len(chunks) else None,
        "runs_with_large_regret": _mean(r["first_large_regret_s"] is not None for r in recs),
        "first_large_regret_s_median": float(np.median(firsts)) if firsts else None,
        "large_regret_m": large,
        # Chunks whose cost-to-go the planner could not compute: left out of the sums above, so named.
        "unscored_chunks": unscored,
    }


def _fmt(x, digits=2) -> str:
    return "-" if x is None else f"{x:.{digits}f}"


def _paper_ref(cfg: EvaluateConfig, v: dict) -> dict | None:
    if cfg.env_id != ENV_ID:  # the paper's numbers are the box's that cannot turn
        return None
    kind = "gcs" if v["policy"] == "gcs-open-loop" else ("learned" if v["policy"] not in GCS_POLICIES else None)
    return PAPER.get((kind, v["disturbances"])) if kind else None


def _tables_md(cfg: EvaluateConfig, pv: dict, ics: list[dict]) -> str:
    m = success_measures(cfg)
    s2 = m.loose_key
    on = "" if cfg.env_id == ENV_ID else f" on {cfg.env_id}"  # the box's tables read as they always have
    lines = [
        f"# Evaluation{on}: {len(ics)} initial conditions x {cfg.runs} runs, timeout {cfg.timeout_s:g} s\n",
        f"## Table I: {m.title} and mean success simulation time\n",
        f"| policy | runs | {m.strict} | {m.loose} | sim time (s) | paper success | paper sim time (s) |",
        "|---|---|---|---|---|---|---|",
    ]
    for label, v in pv.items():
        ref = _paper_ref(cfg, v) or {}
        lines.append(
            f"| {label} | {v['runs']} | {_fmt(v['success'])} | {_fmt(v[s2])} | "
            f"{_fmt(v['success_sim_time_s'], 1)} | {_fmt(ref.get('success'))} | "
            f"{_fmt(ref.get('success_sim_time_s'), 1)} |"
        )
    lines += ["", f"## Table II: {m.per_ic}\n"]
    labels = list(pv)
    lines.append("| IC | box | " + " | ".join(labels) + " |")
    lines.append("|---|---|" + "---|" * len(labels))
    for i, ic in enumerate(ics):
        cells = []
        for label in labels:
            c = pv[label]["per_initial_condition"][i]
            cells.append(f"{_fmt(c['success'])} / {_fmt(c[s2])}")
        lines.append(f"| {i} | ({ic['box'][0]:.2f}, {ic['box'][1]:.2f}) | " + " | ".join(cells) + " |")
    lines += [
        "",
        "## Table III: mean run, plan and total time of successful runs (s)\n",
        "| policy | run | plan | total | paper run | paper plan | paper total |",
        "|---|---|---|---|---|---|---|",
    ]
    for label, v in pv.items():
        ref = _paper_ref(cfg, v) or {}
        lines.append(
            f"| {label} | {_fmt(v['run_time_s'], 3)} | {_fmt(v['plan_time_s'], 3)} | "
            f"{_fmt(v['total_time_s'], 3)} | {_fmt(ref.get('run_time_s'))} | {_fmt(ref.get('plan_time_s'))} | "
            f"{_fmt(ref.get('total_time_s'))} |"
        )
    if any("regret_mean" in v for v in pv.values()):
        lines += [
            "",
            "## Regret along each policy's own path (m of finger travel)\n",
            f"Chunk regret = finger path over the chunk + V(after) - V(before), V the GCS cost-to-go; "
            f"zero for the optimal plan. Large: a chunk above {cfg.large_regret_m:g} m.\n",
            "| policy | mean regret per run | p95 per run | p95 per chunk | runs with a large regret | "
            "median time of the first (s) |",
            "|---|---|---|---|---|---|",
        ]
        for label, v in pv.items():
            if "regret_mean" in v:
                lines.append(
                    f"| {label} | {_fmt(v['regret_mean'])} | {_fmt(v['regret_p95'])} | "
                    f"{_fmt(v['chunk_regret_p95'])} | {_fmt(v['runs_with_large_regret'])} | "
                    f"{_fmt(v['first_large_regret_s_median'], 1)} |"
                )
        unscored = {label: v["unscored_chunks"] for label, v in pv.items() if v.get("unscored_chunks")}
        if unscored:
            lines.append(
                "\nChunks the planner could not score (left out of the sums above): "
                + ", ".join(f"{label} {n}" for label, n in unscored.items())
            )
    lines.append(
        "\nRun time: wall time of the rollout, policy inference and closed-loop replanning included; plan "
        "time: the GCS plan made before execution (paper IV-B). Simulation time is simulated seconds."
    )
    return "\n".join(lines) + "\n"
