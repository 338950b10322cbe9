"""gym-pusht's expert with a far agent planned from the staging point first (`stage_first`, the setting) and
from the agent's own place first, alternated start by start in one process: success, steps, CPU seconds
(which the load barely moves), plan calls and plans, one JSON line per start and order.

    python experiments/pusht/stage_first.py 10500 10524
"""

import json
import sys
import time

from lerobot_gcs_push.planning.factory import ExpertConfig, make_expert
from lerobot_gcs_push.registration import make_env


def main(first: int, stop: int) -> None:
    env = make_env("gym_pusht/PushT-v0")
    expert = make_expert(env.scene, env.fps, ExpertConfig(mode="closed-loop"))
    planner, calls = expert.planner, [0]
    plan = planner.plan

    def counted(*args, **kwargs):
        calls[0] += 1
        return plan(*args, **kwargs)

    planner.plan = counted
    for seed in range(first, stop):
        for stage_first in (False, True) if seed % 2 == 0 else (True, False):
            expert.expert.stage_first = stage_first
            obs, info = env.reset(seed=seed)
            calls[0], cpu = 0, time.process_time()
            expert.reset(obs, info, seed)
            steps, done = 0, False
            while not done:
                obs, _, term, trunc, info = env.step(expert.act(obs, info))
                steps, done = steps + 1, term or trunc
            row = {
                "seed": seed,
                "stage_first": stage_first,
                "success": bool(info["is_success"]),
                "steps": steps,
                "cpu": round(time.process_time() - cpu, 2),
                "calls": calls[0],
                "plans": len(expert.plans),
            }
            print(json.dumps(row), flush=True)


if __name__ == "__main__":
    main(int(sys.argv[1]), int(sys.argv[2]))
