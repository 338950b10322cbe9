"""The runs themselves, in worker processes (or Ray actors): one episode of one policy on one initial
condition, its trajectory and video saved, its record returned; the box's regret scored on the way."""

from __future__ import annotations

import json
import os
from dataclasses import replace
from pathlib import Path

import numpy as np

from lerobot_gcs_push.evaluation.config import GCS_POLICIES, EvaluateConfig, variant_label
from lerobot_gcs_push.evaluation.learned import PIXELS_OBS, LearnedPolicy
from lerobot_gcs_push.evaluation.records import Trajectory, _slug, video_path
from lerobot_gcs_push.scene import episode_seed

GCS_CHUNK_STEPS = 8  # the experts act every step; their regret is scored over the CPU preset's chunk length


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

        # Made once each, keyed by (disturbances, obs_type): the env with disturbances only if a run asks for
        # it (gym-pusht has none); a keypoint policy's with the observations it reads, the experts' (which
        # read the state from info) and image policies' with pixels.
        self.envs = _Lazy(
            lambda key: make_env(
                cfg.starts.env_id,
                disturbances=key[0],
                obs_type=key[1],
                max_sim_time_s=cfg.timeout_s,
                success_threshold=cfg.success_thresholds[0],
            )
        )
        self._experts: dict = {}
        self._learned: dict = {}
        self._cost_to_go = None

    def regret(self, boxes, fingers, every: int) -> dict:
        from lerobot_gcs_push.planning.factory import CostToGo, chunk_regret

        if self._cost_to_go is None:
            self._cost_to_go = CostToGo(self.envs[False, PIXELS_OBS].scene)
        chunks = chunk_regret(self._cost_to_go, boxes, fingers, every)
        regrets = np.array([c["regret"] for c in chunks])
        large = [c for c in chunks if c["regret"] > self.cfg.large_regret_m]
        fps = self.envs[False, PIXELS_OBS].fps
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
            from lerobot_gcs_push.planning.factory import make_expert

            env = self.envs[False, PIXELS_OBS]
            config = replace(self.cfg.expert, mode=name.removeprefix("gcs-"))  # the policy names the mode
            expert = make_expert(env.scene, env.fps, config, self._experts.get("_planner"))
            self._experts["_planner"] = expert.planner  # one planner for both experts
            self._experts[name] = expert
        return self._experts[name]

    def learned(self, path: str):
        if path not in self._learned:
            from lerobot_gcs_push.artifacts.shipped import shipped_path
            from lerobot_gcs_push.registration import SCENES

            # The env's task is its scene's: no env of the policy's obs_type need be made for it.
            self._learned[path] = LearnedPolicy(
                shipped_path(path), self.cfg.device, SCENES[self.cfg.starts.env_id].task
            )
        return self._learned[path]

    def run(self, job: dict) -> dict:
        policy, dist, i, r, ic = job["policy"], job["disturbances"], job["ic_index"], job["run"], job["ic"]
        actor = self.expert(policy) if policy in GCS_POLICIES else self.learned(policy)
        env = self.envs[dist, getattr(actor, "obs_type", PIXELS_OBS)]
        if policy not in GCS_POLICIES:
            actor.check_env(env)
        seed = episode_seed(self.cfg.starts.seed, (i * self.cfg.runs + r) * 2 + int(dist))
        frames = [] if job["video"] else None
        traj = Trajectory(env.scene.kind.trajectory_keys)

        def on_step(obs, action, info):
            traj.add(info)
            if frames is not None:
                frames.append(env.render())

        from lerobot_gcs_push.episodes.rollout import rollout

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
            from lerobot_gcs_push.evaluation.videos import write_video

            write_video(video_path(self.out, label, i), frames, env.fps)
        regret = self.regret(traj.rows["box"], traj.rows["finger"], chunk) if self.cfg.regret else {}
        return regret | {
            "policy": policy,
            "label": label,
            "disturbances": dist,
            # What the policy saw (pixels or gym-pusht's keypoints): `collect` records its expert the same way.
            "obs_type": env.obs_type,
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


_RUNNER: dict = {}


def _init_worker(cfg: EvaluateConfig, out: str) -> None:
    if cfg.workers > 1 or cfg.backend != "process":  # a pool's worker: one process per core
        try:
            import torch

            torch.set_num_threads(1)
        except ImportError:  # pragma: no cover
            pass
    _RUNNER["r"] = _Runner(cfg, Path(out))


def _run_job(job: dict) -> dict:
    return _RUNNER["r"].run(job)


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

    from lerobot_gcs_push.episodes.workers import open_pool

    try:
        with open_pool(
            cfg.backend,
            cfg.workers,
            _init_worker,
            (cfg, str(out)),
            address=cfg.ray_address,
            hint=f"the finished runs are kept in {runs_path}: run the same command again to go on",
        ) as pool:
            for rec in pool.map(_run_job, jobs):
                append(rec)
    finally:
        bar.close()
