"""Smaller contact graphs for gym-pusht's T: plan time and whether a plan is found, against the planner's.

    python experiments/pusht/graph_sizes.py [LAYERSxKNOTS,...] [SEED]

Builds a ContactPlanner for each size (default 3x7, the planner's, then 2x4, 3x4, 2x7; a new size compiles
once, about a minute and 12 GB), then plans with each from 8 near-goal states (the T within 6 cm and 0.6
rad of its goal, the agent 13 cm from its centre, drawn with numpy's generator seeded 0) and from the
first 8 of gym-pusht's resets of SEED (default 9413), and prints each plan's cost, bound and CPU seconds.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from lerobot_gcs_push.contact import ContactPlanner
from lerobot_gcs_push.planning import PlanningError
from lerobot_gcs_push.registration import SCENES, sample_starts


def main(sizes: str = "3x7,2x4,3x4,2x7", seed: int = 9413) -> None:
    scene = SCENES["gym_pusht/PushT-v0"]
    configs = [tuple(int(v) for v in c.split("x")) for c in sizes.split(",")]
    planners = {c: ContactPlanner(scene, layers=c[0], knots=c[1]) for c in configs}
    for p in planners.values():
        p.warm_up()
    first = planners[configs[0]]
    goal, rng = first.goal_of(np.zeros(3)), np.random.default_rng(0)
    near = []
    for _ in range(8):
        pose = np.array([*(goal[:2] + rng.uniform(-0.06, 0.06, 2)), goal[2] + rng.uniform(-0.6, 0.6)])
        angle = rng.uniform(0, 2 * np.pi)
        near.append(first.plannable(pose, pose[:2] + 0.13 * np.array([np.cos(angle), np.sin(angle)])))
    starts = [first.plannable(np.array([*ic.box, ic.heading]), ic.finger) for ic in sample_starts(scene, 8, seed)]
    for name, states in (("near goal", near), ("reset", starts)):
        for i, (pose, finger) in enumerate(states):
            cells = []
            for c, p in planners.items():
                t0 = time.process_time()
                try:
                    plan = p.plan(pose, finger)
                    bound = "-" if plan.lower_bound is None else f"{plan.lower_bound:.2f}"
                    cell = f"{plan.cost:.2f} (bound {bound})"
                except PlanningError as err:
                    cell = "none" if "restriction" in str(err) else "cannot turn so far"
                cells.append(f"{c[0]}x{c[1]}: {cell} {time.process_time() - t0:.1f} s")
            print(f"{name} {i}: " + "; ".join(cells), flush=True)


if __name__ == "__main__":
    main(*(sys.argv[1:2] or []), *(int(a) for a in sys.argv[2:3]))
