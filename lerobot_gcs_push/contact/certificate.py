"""Clarabel on a relaxation's conic data, and the lower bound its dual point certifies (`certify`): the
one place a bound through contact comes from. Apart from the program's own modules, so that how it is
solved does not change the cached program's key."""

from __future__ import annotations

import functools

import numpy as np

from lerobot_gcs_push.planner.conic import Conic

CLARABEL_STATUS = {"Solved": "optimal", "AlmostSolved": "optimal_inaccurate"}
# The largest dual residual |A'z + c|_inf / max(1, |c|_inf) (z projected onto the dual cone) a bound is
# certified at. Measured on 6 rotating-box and 4 T queries: 4e-7 to 3e-6, whether Clarabel said Solved or
# AlmostSolved (most say AlmostSolved; Clarabel's own test scales by |A'z| too, so Solved is no check here).
CERTIFY_TOL = 1e-5


def solve_with_dual(conic: Conic, tol: float = 1e-7, refine: bool = True) -> tuple[str, np.ndarray, np.ndarray]:
    """Clarabel on the conic data (as `Conic.solve`, whose solution keeps no dual point): its status, the
    primal point x and the dual point z. `refine`: Clarabel's iterative refinement of each step's linear
    solve (its default)."""
    import clarabel
    import scipy.sparse as sp

    n = len(conic.c)
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    settings.tol_gap_abs = settings.tol_gap_rel = settings.tol_feas = tol
    settings.iterative_refinement_enable = refine
    sol = clarabel.DefaultSolver(sp.csc_matrix((n, n)), conic.c, conic.A, conic.b, conic.cones(), settings).solve()
    return str(sol.status), np.asarray(sol.x, float), np.asarray(sol.z, float)


def project_dual(conic: Conic, z: np.ndarray) -> np.ndarray:
    """z projected onto the dual cone K* (K is self-dual but for the zero cone, whose dual is free):
    nonnegative entries clipped, each second-order cone's block and each PSD block (the upper triangle
    column by column, off-diagonals times sqrt 2) projected exactly; cones of one size at once."""
    z = np.array(z, float)
    i = conic.zero
    z[i : i + conic.nonneg] = np.maximum(z[i : i + conic.nonneg], 0.0)
    i += conic.nonneg
    cones = [("soc", k, k) for k in conic.soc] + [("psd", n, n * (n + 1) // 2) for n in conic.psd]
    starts = i + np.concatenate([[0], np.cumsum([length for _, _, length in cones])[:-1]]).astype(int)
    for cone in set(cones):
        at = np.array([s for s, c in zip(starts, cones) if c == cone], int)
        kind, n, length = cone
        idx = at[:, None] + np.arange(length)[None, :]
        z[idx] = _project_soc(z[idx]) if kind == "soc" else _project_psd(z[idx], n)
    return z


def _project_soc(blocks: np.ndarray) -> np.ndarray:
    """Each row (t, v) onto {|v| <= t}: itself inside, the apex below the polar cone, else the boundary."""
    t, v = blocks[:, 0], blocks[:, 1:]
    norm = np.linalg.norm(v, axis=1)
    out = blocks.copy()
    outside = norm > t
    scale = np.maximum((t + norm) / 2, 0.0)
    out[outside, 0] = scale[outside]
    ratio = np.divide(scale, norm, out=np.zeros_like(norm), where=norm > 0)
    out[outside, 1:] = v[outside] * ratio[outside, None]
    return out


def _project_psd(blocks: np.ndarray, n: int) -> np.ndarray:
    """Each row (a packed n x n symmetric matrix) onto the PSD cone: negative eigenvalues set to 0."""
    rows, cols = _triangle(n)
    scale = np.where(rows != cols, np.sqrt(2), 1.0)
    m = np.zeros((len(blocks), n, n))
    m[:, rows, cols] = blocks / scale
    m[:, cols, rows] = blocks / scale
    w, u = np.linalg.eigh(m)
    bad = w[:, 0] < 0
    out = blocks.copy()
    if bad.any():
        fixed = np.einsum("bij,bj,bkj->bik", u[bad], np.maximum(w[bad], 0.0), u[bad])
        out[bad] = fixed[:, rows, cols] * scale
    return out


@functools.cache
def _triangle(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Row and column of each entry of a packed n x n PSD cone: the upper triangle, column by column."""
    return tuple(np.array([(r, c) for c in range(n) for r in range(c + 1)]).T)


def certify(conic: Conic, x: np.ndarray, z: np.ndarray, tol: float = CERTIFY_TOL) -> tuple[float | None, float]:
    """(lower bound, dual residual) from a solve's dual point z, checked rather than taken on the solver's
    word: z is projected onto the dual cone (so z.s >= 0 for every slack s in K), then for every feasible
    x, c.x + d = d - b.z + (A'z + c).x + z.s >= d - b.z + r.x with r = A'z + c, the dual residual. Clarabel's
    own dual objective takes r.x as 0; here r is measured and its term bounded by |r|.(|x*| + 1), x* the
    solution found (this assumes the optimum's entries within |x*_i| + 1 of 0: the relaxation's variables are
    flows <= 1 and perspective copies within the workspace; the term measured 1e-4 of the bound on the box,
    6e-4 on the T). tests/test_contact_graph_global.py checks the bound against SCIP's global optima.
    A residual above `tol` (relative to the cost's scale) certifies nothing: the bound is None."""
    zp = project_dual(conic, z)
    r = conic.c + conic.A.T @ zp
    residual = float(np.max(np.abs(r), initial=0.0) / max(1.0, float(np.max(np.abs(conic.c), initial=0.0))))
    if not np.isfinite(residual) or residual > tol or not np.all(np.isfinite(x)):
        return None, residual
    bound = conic.d - float(conic.b @ zp) - float(np.abs(r) @ (np.abs(x) + 1.0))
    return (float(bound), residual) if np.isfinite(bound) else (None, residual)


# The solves `solve_certified` tries, in order, until one is certified. Without iterative refinement a T's
# relaxation solved in a median 1.77 s against 2.42 s with it (gym-pusht's resets of seeds 10320-10339, one
# process, quiet machine; 1.66 against 2.31 s on 10310-10317), the same iterations, its bound within 0.4 %
# of the refined one's; 27 of those 28 were certified. At 1e-6 rather than 1e-7, 1.43 s against 1.62 s
# (seeds 10320-10331, beside another job), 12 of 12 certified, the bounds 0-0.19 % lower. Where the bound is
# not certified, the solve is repeated with refinement at 1e-7, and then at 1e-6, where Clarabel's
# numerical errors (about 1 solve in 30) clear (experiments/pusht/clarabel_refinement.py).
SOLVES = ({"refine": False, "tol": 1e-6}, {}, {"tol": 1e-6})


def solve_certified(conic: Conic) -> tuple[str, np.ndarray, np.ndarray, float | None, float]:
    """(status, x, z, bound, dual residual) of the first of `SOLVES` whose bound is certified; if none is,
    the last that Clarabel solved (its bound None). A ValueError names the status when none solved."""
    found = None
    for settings in SOLVES:
        status, x, z = solve_with_dual(conic, **settings)
        if status not in CLARABEL_STATUS:
            continue
        bound, residual = certify(conic, x, z)
        found = (status, x, z, bound, residual)
        if bound is not None:
            break
    if found is None:
        raise ValueError(f"Clarabel returned status {status!r}")
    return found
