"""The relaxation with its dead start vertices removed: Clarabel's time, the bound and the flows, against
the program the planner solves.

    python experiments/pusht/dead_starts.py [N] [SEED]

A start vertex whose free-space piece does not hold the agent carries no flow (phi <= allow = 0), so its
perspective variables are 0 in every feasible point; `Conic.fix` removes them. For the first N (default 6)
of gym-pusht's resets of SEED (default 9413), prints the program's size before and after, the CPU seconds
of each solve, both objectives and certified bounds, and the largest difference in the free vertices' flows.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from lerobot_gcs_push.conic.certificate import certify, solve_with_dual
from lerobot_gcs_push.conic.program import _scatter
from lerobot_gcs_push.planning.factory import make_planner
from lerobot_gcs_push.registration import SCENES, sample_starts


def main(n: int = 6, seed: int = 9413) -> None:
    scene = SCENES["gym_pusht/PushT-v0"]
    p = make_planner(scene)
    p.warm_up()
    rel = p.relaxation
    index = {id(v): i for i, v in enumerate(rel.variables)}
    columns = rel.data.n
    flows = rel.data.unpacked[index[id(rel.phi_f)]]
    for ic in sample_starts(scene, n, seed=seed):
        pose, finger = p.plannable(np.array([*ic.box, ic.heading]), ic.finger)
        start, q, goal, allow = p.query(pose, finger)
        rel.set_query(start, q, goal, allow, p.window(start, goal))
        conic = rel.data.at(np.concatenate([np.ravel(np.asarray(x.value, float), order="F") for x in rel.params]))
        values = np.full(columns, np.nan)
        starts = [k for k, v in enumerate(rel.graph.frees) if v.layer < 0]
        dead = [k for k in starts if not allow[rel.graph.frees[k].source]]
        for k in dead:
            for var in (rel.frees[k].q, rel.frees[k].pose, rel.frees[k].moments):
                idx = rel.data.unpacked[index[id(var)]].ravel()
                values[idx[idx < columns]] = 0.0
            values[flows[k]] = 0.0
        small = conic.fix(values)
        out = []
        for program in (conic, small):
            t0 = time.process_time()
            _, x, z = solve_with_dual(program)
            cpu = time.process_time() - t0
            out.append((program.A.shape, cpu, program.c @ x + program.d, certify(program, x, z)[0], x))
        full = _scatter(small.fixed, small.free, out[1][4])
        bounds = [f"{b:.4f}" if b is not None else "-" for b in (out[0][3], out[1][3])]
        print(
            f"{len(dead)} of {len(starts)} start vertices dead: {out[0][0]} -> {out[1][0]}, CPU {out[0][1]:.2f} -> "
            f"{out[1][1]:.2f} s, objective {out[0][2]:.5f} / {out[1][2]:.5f}, bound {bounds[0]} / {bounds[1]}, "
            f"flows differ by {np.max(np.abs(out[0][4][flows] - full[flows])):.1e}",
            flush=True,
        )


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:3]))
