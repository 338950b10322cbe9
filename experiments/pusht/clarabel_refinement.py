"""Clarabel on the T's relaxation with and without its iterative refinement (at 1e-7 and 1e-6, without
equilibration, and unrefined at 1e-5 and 1e-4): CPU seconds, iterations, status, the certified bound
(`certificate.certify`) and how far x moves, for the first plan of gym-pusht's resets of seeds [FIRST, STOP).

    python experiments/pusht/clarabel_refinement.py gym_pusht/PushT-v0 10320 10340
"""

import sys
import time

import clarabel
import numpy as np
import scipy.sparse as sp

from lerobot_gcs_push.conic.certificate import certify
from lerobot_gcs_push.planning.factory import make_planner
from lerobot_gcs_push.registration import make_env

VARIANTS = {  # Clarabel's settings; tolerances 1e-7 unless `tol` is given
    "refined": {},
    "unrefined": {"iterative_refinement_enable": False},
    "unrefined_1e-6": {"iterative_refinement_enable": False, "tol": 1e-6},
    "unrefined_1e-5": {"iterative_refinement_enable": False, "tol": 1e-5},
    "unrefined_1e-4": {"iterative_refinement_enable": False, "tol": 1e-4},
    "unrefined_unequilibrated": {"iterative_refinement_enable": False, "equilibrate_enable": False},
}


def conics(env_id: str, seeds) -> list:
    env = make_env(env_id)
    planner = make_planner(env.scene)
    planner.warm_up()
    relax = planner.relaxation
    out = []
    for seed in seeds:
        _, info = env.reset(seed=seed)
        p, q, goal, allow = planner.query(*planner.plannable(info["slider_pose"], info["finger"]))
        relax.set_query(p, q, goal, allow, planner.window(p, goal))
        out.append(
            relax.data.at(np.concatenate([np.ravel(np.asarray(v.value, float), order="F") for v in relax.params]))
        )
    return out


def solve(conic, **settings):
    n = len(conic.c)
    st = clarabel.DefaultSettings()
    st.verbose = False
    settings = dict(settings)
    st.tol_gap_abs = st.tol_gap_rel = st.tol_feas = settings.pop("tol", 1e-7)
    for k, v in settings.items():
        setattr(st, k, v)
    t0 = time.process_time()
    sol = clarabel.DefaultSolver(sp.csc_matrix((n, n)), conic.c, conic.A, conic.b, conic.cones(), st).solve()
    dt = time.process_time() - t0
    x, z = np.asarray(sol.x), np.asarray(sol.z)
    return dt, sol.iterations, str(sol.status), certify(conic, x, z), x


def main(env_id: str, first: int, stop: int) -> None:
    times = {k: [] for k in VARIANTS}
    certified = dict.fromkeys(VARIANTS, 0)
    for i, conic in enumerate(conics(env_id, range(first, stop))):
        base = None
        for name, settings in VARIANTS.items():
            dt, its, status, (bound, residual), x = solve(conic, **settings)
            base = x if base is None else base
            times[name].append(dt)
            certified[name] += bound is not None
            print(
                f"{first + i} {name}: {dt:.2f} s, {its} its, {status}, bound {bound}, residual {residual:.1e}, "
                f"|x - x_refined| {np.max(np.abs(x - base)):.1e}",
                flush=True,
            )
    for name in VARIANTS:
        print(f"{name}: median {np.median(times[name]):.2f} s, certified {certified[name]} / {len(times[name])}")


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]), int(sys.argv[3]))
