"""Why gym-pusht's expert replans: at each replan, the step, whether the plan had run out, the segment then
running, how far the T had strayed from the plan (`PlanExpert.strayed_by`) and how far it was from its goal;
one JSON line a start for gym-pusht's resets of seeds [FIRST, STOP), one process.

    python experiments/pusht/replan_reasons.py 11320 11336
"""

import json
import sys

from lerobot_gcs_push.planning import expert as ex
from lerobot_gcs_push.planning.factory import ExpertConfig, make_expert
from lerobot_gcs_push.planning.plan import PUSH
from lerobot_gcs_push.registration import make_env

env = make_env("gym_pusht/PushT-v0")
pe = make_expert(env.scene, env.fps, ExpertConfig(mode="closed-loop"))
inner = pe.expert
orig = ex.PlanExpert._should_replan
log = []


def why(self, info):
    r = orig(self, info)
    if r:
        sched = self._schedule
        ran_out = self._k >= len(sched)
        i = min(self._k, len(sched) - 1)
        kind = sched.kinds[i]
        first_push = PUSH not in sched.kinds[:i]
        goal = self.planner.goal_of(ex._slider(info))
        log.append(
            dict(
                step=self._steps,
                ran_out=ran_out,
                k=self._k,
                n=len(sched),
                kind=str(kind),
                before_first_push=first_push,
                strayed=round(self.strayed_by(ex._slider(info)), 3),
                to_goal=round(self.planner.distance(ex._slider(info), goal), 3),
            )
        )
    return r


ex.PlanExpert._should_replan = why
for seed in range(int(sys.argv[1]), int(sys.argv[2])):
    obs, info = env.reset(seed=seed)
    log.clear()
    pe.reset(obs, info, seed)
    done = False
    steps = 0
    while not done:
        obs, _, term, trunc, info = env.step(pe.act(obs, info))
        steps += 1
        done = term or trunc
    print(json.dumps({"seed": seed, "ok": bool(info["is_success"]), "steps": steps, "replans": list(log)}), flush=True)
