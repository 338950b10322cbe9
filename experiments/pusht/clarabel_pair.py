"""Clarabel's factorizations alone and with a second process solving beside it (two `generate` workers).

    python experiments/pusht/clarabel_pair.py [N] [SEED]

Writes the conic data of the first N (default 6) of gym-pusht's resets of SEED (default 9413) as the PushT
expert's relaxation sets it, then, for qdldl and for faer on one thread, solves them in one process and
in two processes at once, and prints each process's median wall seconds a solve and the certified bounds.
"""

from __future__ import annotations

import pickle
import subprocess
import sys
import tempfile
import time

import clarabel
import numpy as np
import scipy.sparse as sp


def solve_all(path: str, method: str) -> None:
    from lerobot_gcs_push.conic.certificate import certify

    walls, bounds = [], []
    for conic in pickle.loads(open(path, "rb").read()):
        settings = clarabel.DefaultSettings()
        settings.verbose = False
        settings.tol_gap_abs = settings.tol_gap_rel = settings.tol_feas = 1e-7
        if method == "faer":
            settings.direct_solve_method, settings.max_threads = "faer", 1
        n = len(conic.c)
        t0 = time.perf_counter()
        sol = clarabel.DefaultSolver(sp.csc_matrix((n, n)), conic.c, conic.A, conic.b, conic.cones(), settings).solve()
        walls.append(time.perf_counter() - t0)
        bounds.append(certify(conic, np.asarray(sol.x), np.asarray(sol.z))[0])
    walls_s, bounds_s = np.round(walls, 2).tolist(), np.round(bounds, 4).tolist()
    print(f"{method:6s} median {np.median(walls):.2f} s  {walls_s}  bounds {bounds_s}")


def main(n: int = 6, seed: int = 9413) -> None:
    sys.path.insert(0, __file__.rsplit("/", 1)[0])
    from clarabel_settings import conics

    path = tempfile.mkstemp(suffix=".pkl")[1]
    with open(path, "wb") as f:
        pickle.dump(conics(n, seed), f)
    me = [sys.executable, __file__, "--solve", path]
    for method in ("qdldl", "faer"):
        print(f"{method}, alone:", flush=True)
        subprocess.run([*me, method], check=True)
        print(f"{method}, two at once:", flush=True)
        procs = [subprocess.Popen([*me, method]) for _ in range(2)]
        for p in procs:
            p.wait()


if __name__ == "__main__":
    if sys.argv[1:2] == ["--solve"]:
        solve_all(sys.argv[2], sys.argv[3])
    else:
        main(*(int(a) for a in sys.argv[1:3]))
