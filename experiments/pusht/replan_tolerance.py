"""The closed-loop expert on gym-pusht's resets at two or more replan tolerances, alternated start by start
(one process; plan counts and steps do not depend on the load). One JSON line per start and setting.

    python experiments/pusht/replan_tolerance.py 9780 9810 0.03,0.06
"""

import json
import sys
import time

from lerobot_gcs_push.planning.factory import ExpertConfig, make_expert, make_planner
from lerobot_gcs_push.registration import make_env

env = make_env("gym_pusht/PushT-v0")
planner = make_planner(env.scene)
planner.warm_up()
tols = [float(t) for t in sys.argv[3].split(",")]
experts = {
    t: make_expert(env.scene, env.fps, ExpertConfig(mode="closed-loop", replan_tolerance=t), planner) for t in tols
}
for seed in range(int(sys.argv[1]), int(sys.argv[2])):
    for t in tols if seed % 2 == 0 else tols[::-1]:
        expert = experts[t]
        obs, info = env.reset(seed=seed)
        t0 = time.perf_counter()
        expert.reset(obs, info, seed)
        steps = 0
        while True:
            obs, _, term, trunc, info = env.step(expert.act(obs, info))
            steps += 1
            if term or trunc:
                break
        e = expert.expert
        row = {
            "seed": seed,
            "tol": t,
            "success": bool(info.get("is_success")),
            "steps": steps,
            "wall": round(time.perf_counter() - t0, 2),
            "plans": len(e.plans),
            "failed": e.failed_replans,
            "staged": ["staged_from" in p.extra for p in e.plans],
        }
        print(json.dumps(row), flush=True)
