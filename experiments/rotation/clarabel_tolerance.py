"""The contact relaxation's conic on gym-pusht's T at several Clarabel tolerances, the same data each time:
iterations (which the load does not move), seconds, the checked bound and the dual residual it rests on.

    python experiments/rotation/clarabel_tolerance.py 9800 6 1e-7,1e-5,3e-5,1e-4
"""

import sys

import clarabel
import numpy as np
import scipy.sparse as sp

from lerobot_gcs_push.conic.certificate import certify
from lerobot_gcs_push.contact import ContactPlanner
from lerobot_gcs_push.pusht.env import pusht_scene, reset_states

planner = ContactPlanner(pusht_scene())
planner.warm_up()
rel = planner.relaxation
tols = [float(t) for t in sys.argv[3].split(",")]
for i, ic in enumerate(reset_states(planner.scene, int(sys.argv[2]), seed=int(sys.argv[1]))):
    slider, finger = planner.plannable((*ic.box, ic.heading), ic.finger)
    pose, q, goal, allow = planner.query(slider, finger)
    rel.set_query(pose, q, goal, allow, planner.window(pose, goal))
    conic = rel.data.at(np.concatenate([np.ravel(np.asarray(p.value, float), order="F") for p in rel.params]))
    for tol in tols if i % 2 == 0 else tols[::-1]:
        settings = clarabel.DefaultSettings()
        settings.verbose = False
        settings.tol_gap_abs = settings.tol_gap_rel = settings.tol_feas = tol
        n = len(conic.c)
        sol = clarabel.DefaultSolver(sp.csc_matrix((n, n)), conic.c, conic.A, conic.b, conic.cones(), settings).solve()
        bound, residual = certify(conic, np.asarray(sol.x), np.asarray(sol.z), tol=1.0)  # the bound at any residual
        print(
            f"start {i} tol {tol:.0e}: {sol.status}, {sol.iterations} iterations, {sol.solve_time:.2f} s, "
            f"bound {bound:.4f}, dual residual {residual:.1e}",
            flush=True,
        )
