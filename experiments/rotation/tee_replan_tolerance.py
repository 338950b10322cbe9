"""The closed-loop expert on `GcsPushT-v0` starts of an evaluation (its settings.json) at one or more replan
tolerances, 60 s each: success, coverage, simulated time and replans, one JSON line per start and setting.

    python experiments/rotation/tee_replan_tolerance.py outputs/eval/tee_expert_seed5150/settings.json 0.03,0.06 2,19
"""

import json
import sys
import time

import gymnasium as gym

import lerobot_gcs_push  # noqa: F401  (registers the envs)
from lerobot_gcs_push.episodes.rollout import rollout
from lerobot_gcs_push.planning.factory import ExpertConfig, make_expert, make_planner
from lerobot_gcs_push.registration import TEE_ENV_ID

settings = json.load(open(sys.argv[1]))
env = gym.make(TEE_ENV_ID, max_sim_time_s=60.0, image_size=(32, 32)).unwrapped
planner = make_planner(env.scene)
planner.warm_up()
for i in map(int, sys.argv[3].split(",")):
    ic = settings["initial_conditions"][i]
    for tol in map(float, sys.argv[2].split(",")):
        expert = make_expert(env.scene, env.fps, ExpertConfig(mode="closed-loop", replan_tolerance=tol), planner)
        t0 = time.perf_counter()
        res = rollout(env, expert, ic["box"], ic["finger"], heading=ic["heading"], seed=settings["seed"])
        row = {
            "ic": i,
            "tol": tol,
            "success": bool(res["success"]),
            "coverage": round(float(res["coverage"]), 3),
            "sim_time_s": res["sim_time_s"],
            "replans": res.get("replans"),
            "wall": round(time.perf_counter() - t0, 1),
        }
        print(json.dumps(row), flush=True)
