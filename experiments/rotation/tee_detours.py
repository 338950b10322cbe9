"""Every solved restriction from given states of the T in Drake: for each [slider pose, finger], the
relaxation's bound, then each sampled path's restriction (`s`, from the relaxation's values) and each of the
20 paths of most relaxed flow (`r`, straight-line guesses) that solved, with its cost and the farthest its
slider gets from the goal (`Planner.distance`), and how many failed.

    python experiments/rotation/tee_detours.py '[[[0.02, -0.04, -0.84], [1.55, -0.27]]]'
"""

import json
import sys

import numpy as np

from lerobot_gcs_push.contact.rounding import ranked_paths, relaxation_guess, sample_paths
from lerobot_gcs_push.planning.factory import make_planner
from lerobot_gcs_push.registration import SCENES

p = make_planner(SCENES["GcsPushT-v0"])
p.warm_up()
for slider, finger in json.loads(sys.argv[1]):
    pose, fg = p.plannable(np.array(slider), np.array(finger))
    start, q, goal, allow = p.query(pose, fg)
    window = p.window(start, goal)
    res = p.relaxation.solve(start, q, goal, allow, window)
    d0 = p.distance(start, goal)
    out = []

    def dev(r, goal=goal):
        return max(
            p.distance([x, y, np.arctan2(s, c)], goal)
            for ct in r.contacts
            for x, y, c, s in zip(ct["x"], ct["y"], ct["c"], ct["s"])
        )

    for path in sample_paths(p.graph, res, p.candidates, np.random.default_rng(p.seed)):
        r = p._restrict(path, start, q, goal, window, guess=relaxation_guess(res, path))
        out.append(("s", round(r.cost, 2), round(dev(r), 2)) if r.success else ("s", "-"))
    for path in ranked_paths(p.graph, res, allow)[:20]:
        r = p._restrict(path, start, q, goal, window)
        out.append(("r", round(r.cost, 2), round(dev(r), 2)) if r.success else ("r", "-"))
    print(
        f"d0 {d0:.3f} bound {res.bound and round(res.bound, 3)}:",
        [o for o in out if o[1] != "-"],
        "failed",
        sum(o[1] == "-" for o in out),
        flush=True,
    )
