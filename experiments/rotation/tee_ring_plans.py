"""Plans of the Drake T from points round the staging circle (the T's radius about its pivot, the finger's,
and `STAGE_MARGIN_M`), 8 of them 45 degrees apart from the world's x axis: for each given [slider pose,
finger], the distance to the goal, then each point's plan cost and the farthest its slider gets from the
goal (`Planner.distance`), or - where no plan was found.

    python experiments/rotation/tee_ring_plans.py '[[[0.02, -0.04, -0.84], [1.55, -0.27]]]'
"""

import json
import sys

import numpy as np

from lerobot_gcs_push.planning import PlanningError
from lerobot_gcs_push.planning.expert import STAGE_MARGIN_M
from lerobot_gcs_push.planning.factory import ExpertConfig, make_expert
from lerobot_gcs_push.registration import SCENES

ex = make_expert(SCENES["GcsPushT-v0"], 10, ExpertConfig(mode="closed-loop"))
p = ex.planner
p.warm_up()
for slider, _finger in json.loads(sys.argv[1]):  # the finger does not matter: each plan starts on the circle
    slider = np.array(slider)
    goal = p.goal_of(slider)
    d0 = p.distance(slider, goal)
    centre = slider[:2]
    R = p.scene.shape.r_max + p.scene.finger_radius + STAGE_MARGIN_M
    out = []
    for k in range(8):
        a = 2 * np.pi * k / 8
        pt = p.plannable(slider, centre + R * np.array([np.cos(a), np.sin(a)]))[1]
        try:
            plan = p.plan(slider, pt)
            dev = max(p.distance(q, goal) for q in plan.slider_poses)
            out.append((k * 45, round(plan.cost, 2), round(dev, 2)))
        except PlanningError:
            out.append((k * 45, "-"))
    print(f"d0 {d0:.3f}", out, flush=True)
