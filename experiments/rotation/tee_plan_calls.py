"""Every plan call of the Drake T's closed-loop expert on one start, as it runs: the step, the slider and
finger, the target, the distance to it, and the plan's cost, bound, restrictions tried, fallback, end pose
and how far its slider path strays from the target (`maxdev`), or the failure; one line a call.

    python experiments/rotation/tee_plan_calls.py '{"box": [3.32, -0.45], "finger": [-2.6, 0.51], "heading": 2.107}'
"""

import json
import sys
import time

import numpy as np

from lerobot_gcs_push.episodes.rollout import rollout
from lerobot_gcs_push.planning import PlanningError
from lerobot_gcs_push.planning.factory import ExpertConfig, make_expert
from lerobot_gcs_push.registration import make_env

env = make_env("GcsPushT-v0", max_sim_time_s=60)
expert = make_expert(env.scene, env.fps, ExpertConfig(mode="closed-loop"))
planner = expert.planner
plan = planner.plan
st = {"n": 0}


def logged(slider, finger, goal=None):
    c = time.process_time()
    g = planner.goal_of(slider) if goal is None else goal
    row = dict(
        n=st["n"],
        steps=expert._steps,
        slider=np.round(slider, 2).tolist(),
        finger=np.round(finger, 2).tolist(),
        goal=np.round(g, 2).tolist(),
        dist=round(planner.distance(slider, g), 3),
    )
    st["n"] += 1
    try:
        p = plan(slider, finger, goal)
        row.update(
            ok=True,
            cost=round(p.cost, 2),
            lb=p.lower_bound and round(p.lower_bound, 2),
            tried=p.candidates,
            fb=p.extra["fallback"],
            end=np.round(p.slider_poses[-1], 2).tolist(),
            maxdev=round(max(planner.distance(q, g) for q in p.slider_poses), 2),
        )
        return p
    except PlanningError as e:
        row.update(ok=False, err=str(e)[:50])
        raise
    finally:
        row["cpu"] = round(time.process_time() - c, 2)
        print(row, flush=True)


planner.plan = logged
ic = json.loads(sys.argv[1])
r = rollout(env, expert, ic["box"], ic["finger"], seed=0, heading=ic["heading"])
print("success", r["success"], r["sim_time_s"], r["slider_pose_final"])
