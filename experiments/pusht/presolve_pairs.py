"""Presolve by hand: the T's relaxation with its two-entry equality rows (a_i x_i + a_j x_j = b) eliminated,
one variable substituted by the other, solved by Clarabel (unrefined, 1e-6), the full solution and dual point
recovered (the eliminated rows' duals from stationarity on the eliminated columns) and certified on the full
program; against the full program, on the first plan of gym-pusht's resets of seeds [FIRST, STOP).
Variants: every such row (`red`), the same refined, and only rows with |a_i| = |a_j| (`red_unit`).

    python experiments/pusht/presolve_pairs.py 11200 11210
"""

import sys
import time

import numpy as np
import scipy.sparse as sp

sys.path.insert(0, "experiments/pusht")
from clarabel_refinement import conics

from lerobot_gcs_push.conic import Conic
from lerobot_gcs_push.conic.certificate import certify, solve_with_dual


def reduce(conic, unit=False):
    A = sp.csr_matrix(conic.A)
    n = A.shape[1]
    root = np.arange(n)
    scale = np.ones(n)
    off = np.zeros(n)

    def resolve(i):
        s, o = 1.0, 0.0
        while root[i] != i:
            o = s * off[i] + o
            s = s * scale[i]
            i = root[i]
        return i, s, o

    elim_rows, elim_cols = [], []
    nnz = np.diff(A.indptr)
    for e in range(conic.zero):
        if nnz[e] != 2:
            continue
        (i, j), (ai, aj) = A.indices[A.indptr[e] : A.indptr[e + 1]], A.data[A.indptr[e] : A.indptr[e + 1]]
        be = conic.b[e]
        if unit and not np.isclose(abs(ai), abs(aj)):
            continue
        ri, si, oi = resolve(i)
        rj, sj, oj = resolve(j)
        if ri == rj:
            continue
        # ai(si x_ri + oi) + aj(sj x_rj + oj) = be  ->  x_ri = (be - ai oi - aj oj - aj sj x_rj)/(ai si)
        ci = ai * si
        if abs(ci) < 1e-9:
            continue
        root[ri] = rj
        scale[ri] = -aj * sj / ci
        off[ri] = (be - ai * oi - aj * oj) / ci
        elim_rows.append(e)
        elim_cols.append(ri)
    keep_cols = np.setdiff1d(np.arange(n), elim_cols)
    pos = -np.ones(n, int)
    pos[keep_cols] = np.arange(len(keep_cols))
    rows, cols, vals, o = [], [], [], np.zeros(n)
    for i in range(n):
        r, s, oo = resolve(i)
        rows.append(i)
        cols.append(pos[r])
        vals.append(s)
        o[i] = oo
    T = sp.csc_matrix((vals, (rows, cols)), shape=(n, len(keep_cols)))
    keep_rows = np.setdiff1d(np.arange(A.shape[0]), elim_rows)
    Ak = sp.csc_matrix(conic.A[keep_rows] @ T)
    Ak.eliminate_zeros()
    red = Conic(
        A=Ak,
        b=conic.b[keep_rows] - conic.A[keep_rows] @ o,
        c=T.T @ conic.c,
        d=conic.d + conic.c @ o,
        zero=conic.zero - len(elim_rows),
        nonneg=conic.nonneg,
        soc=conic.soc,
        psd=conic.psd,
    )
    return red, T, o, np.array(elim_rows), np.array(elim_cols), keep_rows


def recover(conic, T, o, er, ec, kr, xr, zr):
    x = T @ xr + o
    z = np.zeros(conic.A.shape[0])
    z[kr] = zr
    A = sp.csc_matrix(conic.A)
    # c_E + A[:,E]' z = 0  -> A[E rows, E cols]' z_E = -(c_E + A[kept rows, E cols]' z_K)
    AE = A[:, ec]
    rhs = -(conic.c[ec] + AE[kr].T @ zr)
    M = sp.csc_matrix(AE[er].T)
    from scipy.sparse.linalg import spsolve

    z[er] = spsolve(M, rhs)
    return x, z


cs = conics("gym_pusht/PushT-v0", range(int(sys.argv[1]), int(sys.argv[2])))
V = {"full": None, "red": (False, False), "red_refine": (False, True), "red_unit": (True, False)}
T_ = {k: [] for k in V}
C = {k: 0 for k in V}
for k, c in enumerate(cs):
    line = []
    for name, v in V.items():
        t = time.process_time()
        if v is None:
            st, x, z = solve_with_dual(c, tol=1e-6, refine=False)
        else:
            red, T, o, er, ec, kr = reduce(c, unit=v[0])
            st, xr, zr = solve_with_dual(red, tol=1e-6, refine=v[1])
            x, z = recover(c, T, o, er, ec, kr, xr, zr)
        T_[name].append(time.process_time() - t)
        b, r = certify(c, x, z)
        C[name] += b is not None
        line.append(f"{name} {T_[name][-1]:.2f}s {st[:6]} {b and round(b, 4)} {r:.0e}")
    print(k, " | ".join(line), flush=True)
for name in V:
    print(name, "median", round(float(np.median(T_[name])), 2), "certified", C[name], "/", len(cs))
