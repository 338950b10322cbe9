"""Clarabel's settings on the T's contact relaxation, on the conic data of gym-pusht's own resets.

    python experiments/pusht/clarabel_settings.py [N] [SEED]

Builds the planner the PushT expert uses, sets the relaxation's query for the first N resets of SEED
(default 6 of 9412), then solves each conic program with each variant twice and prints, per variant, the
median CPU seconds of a solve (process time, so a busy machine changes it little), the iterations, the
statuses and the certified bounds (`certificate.certify`, the bound the planner reports).
"""

from __future__ import annotations

import sys
import time

import clarabel
import numpy as np
import scipy.sparse as sp

from lerobot_gcs_push.conic.certificate import certify
from lerobot_gcs_push.planning.factory import make_planner
from lerobot_gcs_push.registration import SCENES, sample_starts

VARIANTS = {
    "qdldl, tol 1e-7 (the planner's)": {"tol": 1e-7},
    "qdldl, tol 1e-6": {"tol": 1e-6},
    "faer, tol 1e-7": {"tol": 1e-7, "direct_solve_method": "faer"},
    "faer, tol 1e-7, 1 thread": {"tol": 1e-7, "direct_solve_method": "faer", "max_threads": 1},
    "qdldl, no chordal decomposition": {"tol": 1e-7, "chordal_decomposition_enable": False},
}


def conics(n: int, seed: int) -> list:
    scene = SCENES["gym_pusht/PushT-v0"]
    planner = make_planner(scene)
    planner.warm_up()
    rel, out = planner.relaxation, []
    for ic in sample_starts(scene, n, seed=seed):
        pose, finger = planner.plannable(np.array([*ic.box, ic.heading]), ic.finger)
        p, q, goal, allow = planner.query(pose, finger)
        rel.set_query(p, q, goal, allow, planner.window(p, goal))
        out.append(rel.data.at(np.concatenate([np.ravel(np.asarray(x.value, float), order="F") for x in rel.params])))
    return out


def solve(conic, opts: dict):
    opts = dict(opts)
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    settings.tol_gap_abs = settings.tol_gap_rel = settings.tol_feas = opts.pop("tol")
    for name, value in opts.items():
        setattr(settings, name, value)
    n = len(conic.c)
    t0 = time.process_time()
    sol = clarabel.DefaultSolver(sp.csc_matrix((n, n)), conic.c, conic.A, conic.b, conic.cones(), settings).solve()
    cpu = time.process_time() - t0
    bound, _ = certify(conic, np.asarray(sol.x), np.asarray(sol.z))
    return cpu, sol.iterations, str(sol.status), bound


def main(n: int = 6, seed: int = 9412) -> None:
    data = conics(n, seed)
    c = data[0]
    print(f"{len(c.c)} variables, {c.A.shape[0]} rows, {c.A.nnz} nonzeros, {len(c.psd)} PSD and {len(c.soc)} SOC cones")
    runs = {name: [[solve(conic, opts) for conic in data] for _ in range(2)] for name, opts in VARIANTS.items()}
    for name, (first, second) in runs.items():
        cpu = np.median([r[0] for r in first + second])
        bounds = [None if r[3] is None else round(r[3], 4) for r in first]
        print(
            f"{name:34s} {cpu:.2f} s CPU  iterations {[r[1] for r in first]}  "
            f"{sorted({r[2] for r in first})}  bounds {bounds}"
        )


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:3]))
