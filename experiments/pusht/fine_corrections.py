"""gym-pusht's closed-loop expert with its corrections near the goal (`ExpertConfig.fine_within`) at each given
distance, start by start: success, steps, CPU seconds, plans and how many were corrections; one JSON line a
start and setting, for gym-pusht's resets of seeds [FIRST, STOP) in one process. 0 turns corrections off.

    python experiments/pusht/fine_corrections.py 11820 11860 0.25
    python experiments/pusht/fine_corrections.py 11820 11860 0,0.25,0.5   # the settings in turn, start by start
"""

import json
import sys
import time

from lerobot_gcs_push.planning.factory import ExpertConfig, make_expert
from lerobot_gcs_push.registration import make_env

if __name__ == "__main__":
    first, stop = int(sys.argv[1]), int(sys.argv[2])
    settings = [float(v) for v in (sys.argv[3] if len(sys.argv) > 3 else "0.25").split(",")]
    env = make_env("gym_pusht/PushT-v0")
    experts = {w: make_expert(env.scene, env.fps, ExpertConfig(mode="closed-loop", fine_within=w)) for w in settings}
    planner = next(iter(experts.values())).expert.planner
    for wrapped in experts.values():  # one planner: its relaxation is built once
        wrapped.expert.planner = planner
    for seed in range(first, stop):
        for within, expert in experts.items():
            obs, info = env.reset(seed=seed)
            cpu = time.process_time()
            expert.reset(obs, info, seed)
            done, steps = False, 0
            while not done:
                obs, _, term, trunc, info = env.step(expert.act(obs, info))
                steps += 1
                done = term or trunc
            plans = expert.expert.plans
            row = {
                "seed": seed,
                "fine_within": within,
                "success": bool(info["is_success"]),
                "steps": steps,
                "cpu": round(time.process_time() - cpu, 2),
                "plans": len(plans),
                "fine": sum(p.method == "fine" for p in plans),
            }
            print(json.dumps(row), flush=True)
