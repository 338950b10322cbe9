"""Tried on 2026-12-05 and not kept: the closed-loop expert's replans on gym-pusht as restrictions of the
last plan's remaining modes (`ContactPlanner.replan`, `ExpertConfig.replan="restriction"`) instead of a new
relaxation, alternated start by start with the relaxation's replans (one worker, beside a training run).

    python experiments/pusht/replan_restriction.py 9720 9740 relaxation,restriction

One JSON line per start and setting: success, steps, wall seconds, each plan's method and seconds.
"""

import json
import sys
import time

from lerobot_gcs_push.expert import ExpertConfig, make_expert, make_planner
from lerobot_gcs_push.registration import make_env

env = make_env("gym_pusht/PushT-v0")
planner = make_planner(env.scene)
planner.warm_up()
modes = sys.argv[3].split(",")
experts = {m: make_expert(env.scene, env.fps, ExpertConfig(mode="closed-loop", replan=m), planner) for m in modes}
for seed in range(int(sys.argv[1]), int(sys.argv[2])):
    for m, expert in experts.items():
        obs, info = env.reset(seed=seed)
        t0 = time.perf_counter()
        expert.reset(obs, info, seed)
        steps = 0
        while True:
            obs, _, term, trunc, info = env.step(expert.act(obs, info))
            steps += 1
            if term or trunc:
                break
        plans = expert.expert.plans
        row = {
            "seed": seed,
            "replan": m,
            "success": bool(info.get("is_success")),
            "steps": steps,
            "wall": round(time.perf_counter() - t0, 2),
            "methods": [p.method for p in plans],
            "plan_s": [round(p.solve_time_s, 2) for p in plans],
            "costs": [round(p.cost, 3) for p in plans],
        }
        print(json.dumps(row), flush=True)
