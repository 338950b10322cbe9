"""SNOPT's tolerances on the rounding's restrictions (gym-pusht's T): for the first N of gym-pusht's resets of
SEED, the relaxation solved once, then its sampled paths (from the relaxation's values) and the 20 paths of
most relaxed flow (straight-line guesses) each solved under every variant, the variants' order rotated path
by path; restrictions solved, CPU seconds, and the least and the first-ranked cost over the bound.

    python experiments/pusht/snopt_tolerances.py 11410 8
"""

import sys
import time

import numpy as np
from pydrake.solvers import SnoptSolver, SolverOptions

from lerobot_gcs_push.contact.rounding import ranked_paths, relaxation_guess, sample_paths
from lerobot_gcs_push.planning.factory import make_planner
from lerobot_gcs_push.registration import SCENES, sample_starts

VARIANTS = {
    "base": {},
    "feas1e-6": {"Major feasibility tolerance": 1e-6},
    "feas1e-5": {"Major feasibility tolerance": 1e-5},
    "feas1e-5_opt1e-5": {"Major feasibility tolerance": 1e-5, "Major optimality tolerance": 1e-5},
}
cur = {}
_solve = SnoptSolver.Solve


def patched(self, prog, guess, options):
    opts = SolverOptions()
    sid = SnoptSolver.id()
    base = {"Major feasibility tolerance": 1e-7, "Major optimality tolerance": 1e-6, "Major iterations limit": 500}
    for k, v in {**base, **cur}.items():
        opts.SetOption(sid, k, v)
    return _solve(self, prog, guess, opts)


SnoptSolver.Solve = patched
scene = SCENES["gym_pusht/PushT-v0"]
p = make_planner(scene)
p.warm_up()
names = list(VARIANTS)
S = {k: dict(ok=0, n=0, cpu=0.0, firstcost=[], best=[]) for k in names}
seed = int(sys.argv[1])
n = int(sys.argv[2])
j = 0
for ic in sample_starts(scene, n, seed=seed):
    pose, finger = p.plannable(np.array([*ic.box, ic.heading]), ic.finger)
    start, q, goal, allow = p.query(pose, finger)
    window = p.window(start, goal)
    res = p.relaxation.solve(start, q, goal, allow, window)
    jobs = [("s", path) for path in sample_paths(p.graph, res, p.candidates, np.random.default_rng(p.seed))] + [
        ("r", path) for path in ranked_paths(p.graph, res, allow)[:20]
    ]
    first = {k: None for k in names}
    best = {k: np.inf for k in names}
    for kind, path in jobs:
        j += 1
        order = names[j % len(names) :] + names[: j % len(names)]
        for name in order:
            cur.clear()
            cur.update(VARIANTS[name])
            c = time.process_time()
            if kind == "s":
                r = p._restrict(path, start, q, goal, window, guess=relaxation_guess(res, path))
            else:
                r = p._restrict(path, start, q, goal, window)
            s = S[name]
            s["cpu"] += time.process_time() - c
            s["n"] += 1
            s["ok"] += r.success
            if r.success:
                best[name] = min(best[name], r.cost)
                if first[name] is None and kind == "r":
                    first[name] = r.cost
    b = res.bound or np.nan
    for k in names:
        S[k]["best"].append(round(best[k] / b, 3))
        S[k]["firstcost"].append(round((first[k] or np.inf) / b, 3))
    print({k: (S[k]["ok"], S[k]["n"], round(S[k]["cpu"], 1)) for k in names}, flush=True)
for k in names:
    print("SUM", k, S[k])
