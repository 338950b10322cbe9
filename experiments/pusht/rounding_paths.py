"""What the rounding finds on gym-pusht's T: the sampled paths' restrictions (from the relaxation's values),
SNOPT's exit codes, and the first K paths ranked by relaxed flow (from the straight-line guess).

    python experiments/pusht/rounding_paths.py [N] [SEED] [K]

For the first N (default 8) of gym-pusht's resets of SEED (default 9414), prints the relaxation's
certified bound, the faces each sampled path pushes, each sampled restriction's cost (- : SNOPT found it
infeasible) and exit code, and, over the K (default 40) paths of most relaxed flow, the rank of the first
that solves, its cost and the least cost among them (the planner keeps the first).
"""

from __future__ import annotations

import sys

import numpy as np
from pydrake.solvers import SnoptSolver

from lerobot_gcs_push.contact.rounding import ranked_paths, relaxation_guess, sample_paths
from lerobot_gcs_push.planning.factory import make_planner
from lerobot_gcs_push.registration import SCENES, sample_starts

EXITS: list[int] = []
_solve = SnoptSolver.Solve


def _recording(self, prog, guess, options):
    result = _solve(self, prog, guess, options)
    EXITS.append(result.get_solver_details().info)
    return result


def main(n: int = 8, seed: int = 9414, k: int = 40) -> None:
    SnoptSolver.Solve = _recording
    scene = SCENES["gym_pusht/PushT-v0"]
    p = make_planner(scene)
    p.warm_up()
    for ic in sample_starts(scene, n, seed=seed):
        pose, finger = p.plannable(np.array([*ic.box, ic.heading]), ic.finger)
        start, q, goal, allow = p.query(pose, finger)
        window = p.window(start, goal)
        res = p.relaxation.solve(start, q, goal, allow, window)
        sampled, EXITS[:] = [], []
        for path in sample_paths(p.graph, res, p.candidates, np.random.default_rng(p.seed)):
            r = p._restrict(path, start, q, goal, window, guess=relaxation_guess(res, path))
            faces = "".join(str(p.graph.contacts[c].face) for c in path.contacts)
            sampled.append(f"{faces}:{r.cost:.2f}" if r.success else f"{faces}:-")
        exits = list(EXITS)
        ranked = [p._restrict(path, start, q, goal, window) for path in ranked_paths(p.graph, res, allow)[:k]]
        solved = [(i, r.cost) for i, r in enumerate(ranked) if r.success]
        first = f"rank {solved[0][0]} cost {solved[0][1]:.2f}" if solved else "none"
        best = f"{min(c for _, c in solved):.2f}" if solved else "-"
        bound = "uncertified" if res.bound is None else f"{res.bound:.2f}"
        print(f"bound {bound}  sampled {' '.join(sampled)}  exits {exits}", end="  |  ")
        print(f"ranked: first {first}, best {best}, {len(solved)} of {k} solve", flush=True)


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:4]))
