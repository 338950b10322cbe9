"""Every `ContactPlanner.plan` call of gym-pusht's expert, start by start: the step it was made at, how far
the T was from its target (`Planner.distance`), whether it was a waypoint, the agent's distance from the T,
the outcome (restrictions tried, fallback, relaxation and rounding seconds, gap) and its CPU seconds; one
JSON line a start, for gym-pusht's resets of seeds [FIRST, STOP) in one process.

    python experiments/pusht/plan_calls.py 11320 11336
    py-spy record -r 50 -f raw -o spy.txt -- python experiments/pusht/plan_calls.py 11350 11362  # pip install py-spy
"""

import json
import sys
import time

import numpy as np

from lerobot_gcs_push.planning import PlanningError
from lerobot_gcs_push.planning.factory import ExpertConfig, make_expert
from lerobot_gcs_push.registration import make_env

env = make_env("gym_pusht/PushT-v0")
expert = make_expert(env.scene, env.fps, ExpertConfig(mode="closed-loop"))
planner = expert.planner
plan = planner.plan
state = {"step": 0}
log = []


def logged(slider, finger, goal=None):
    c = time.process_time()
    g = planner.goal_of(slider) if goal is None else goal
    row = {
        "step": state["step"],
        "dist": round(planner.distance(slider, g), 3),
        "waypoint": goal is not None,
        "far": float(np.linalg.norm(np.asarray(finger) - np.asarray(slider)[:2])),
    }
    try:
        p = plan(slider, finger, goal)
        row.update(
            ok=True,
            tried=p.candidates,
            fallback=p.extra["fallback"],
            relax=round(p.extra["relaxation_s"], 2),
            rnd=round(p.extra["rounding_s"], 2),
            gap=round(p.gap, 3) if p.gap is not None else None,
        )
        return p
    except PlanningError as e:
        row.update(ok=False, err=str(e)[:60])
        raise
    finally:
        row["cpu"] = round(time.process_time() - c, 2)
        log.append(row)


planner.plan = logged
for seed in range(int(sys.argv[1]), int(sys.argv[2])):
    obs, info = env.reset(seed=seed)
    log.clear()
    state["step"] = 0
    cpu = time.process_time()
    expert.reset(obs, info, seed)
    done = False
    while not done:
        obs, _, term, trunc, info = env.step(expert.act(obs, info))
        state["step"] += 1
        done = term or trunc
    print(
        json.dumps(
            {
                "seed": seed,
                "success": bool(info["is_success"]),
                "steps": state["step"],
                "cpu": round(time.process_time() - cpu, 2),
                "calls": list(log),
            }
        ),
        flush=True,
    )
