"""`make bench`'s T episodes start by start: for the bench's starts [FIRST, STOP) of
`benchmarks.rotation_bench.random_starts(planner, 50, 0)`, the closed-loop expert's episode in `GcsPushT-v0`
(60 s, no disturbances, as `rotation_bench.execute` runs them), one JSON line a start: whether the first
plan was found, success, final coverage, simulated time, plans and corrections.

    python experiments/rotation/bench_tee_episodes.py 0 25 & python experiments/rotation/bench_tee_episodes.py 25 50
"""

import json
import sys

import gymnasium as gym

import lerobot_gcs_push  # noqa: F401  (registers the envs)
from benchmarks.rotation_bench import random_starts
from lerobot_gcs_push.contact import ContactPlanner
from lerobot_gcs_push.episodes.rollout import rollout
from lerobot_gcs_push.planning.factory import ExpertConfig, make_expert
from lerobot_gcs_push.registration import SCENES, TEE_ENV_ID

if __name__ == "__main__":
    first, stop = int(sys.argv[1]), int(sys.argv[2])
    planner = ContactPlanner(SCENES[TEE_ENV_ID])
    starts = random_starts(planner, 50, 0)
    env = gym.make(TEE_ENV_ID, max_sim_time_s=60.0, image_size=(32, 32)).unwrapped
    expert = make_expert(env.scene, env.fps, ExpertConfig(mode="closed-loop"), planner)
    for k in range(first, stop):
        pose, finger = starts[k]
        res = rollout(env, expert, pose[:2], finger, seed=k, heading=float(pose[2]))
        row = {
            "start": k,
            "pose": [round(float(v), 3) for v in pose],
            "finger": [round(float(v), 3) for v in finger],
            "first_plan": expert.plan is not None,
            "success": bool(res["success"]),
            "coverage": round(float(res["coverage"]), 3),
            "sim_time_s": res["sim_time_s"],
            "plans": len(expert.plans),
            "corrections": sum(p.method == "fine" for p in expert.plans),
            "failed_replans": res["failed_replans"],
        }
        print(json.dumps(row), flush=True)
