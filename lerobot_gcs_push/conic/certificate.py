"""The one lower bound either planner reports: a solve's dual point, checked (`certify`), or none.

Weak duality, measured rather than taken on the solver's word. z is projected onto the dual cone K*, so
z.s >= 0 for every slack s in K; then for every feasible x (A x + s = b, s in K)

    c.x + d = d - b.z + r.x + z.s >= d - b.z + r.x,    r = A'z + c (the dual residual).

Clarabel's own dual objective takes r.x as 0. Here r is measured, and its term bounded by |r|.R, where R
bounds the optimum's entries: |x_opt,i| <= R_i.

The assumption, stated: the optimum lies within R, entrywise, where R_i = max(|x*_i|, |p_i|, scale) +
MARGIN: x* the solve's own point, p the caller's other feasible points of the program, `scale` the
magnitude the caller knows its variables reach. The contact planner passes neither: its R is |x*| + 1
(its entries reach 80 in a few epigraph columns, so one scale for all would cost 5 % of the bound). The
box planner passes its rounded plan's point and, as `scale`, that point's largest entry: every variable
of its program is a flow in [0, 1], a copy y * x of a point in the workspace, or a segment's length
there, so no entry of its optimum exceeds the workspace's scale, which the plan's point reaches. Without
them the box's optimum lay outside |x*| + 1 (its split flows shrink the copies y * x). The assumption is
checked where the optimum can be found: tests/test_certificate.py puts the box's global optimum (SCIP's
MICP path) inside R on every start it tries. The term itself is returned (`Certificate.assumed`), so
that a bound leaning on it can be seen (measured: under 1e-4 of the bound on the box, 6e-4 on the T).
tests/test_certificate.py and tests/test_contact_graph_global.py check bounds against global optima
found by SCIP.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from lerobot_gcs_push.conic.cones import dual_residual, project_dual
from lerobot_gcs_push.conic.solve import STATUS, ConicSolution, solve_with_dual

if TYPE_CHECKING:
    from lerobot_gcs_push.conic.program import Conic

# The largest dual residual |A'z + c|_inf / max(1, |c|_inf) (z projected onto the dual cone) a bound is
# certified at. Measured on 6 rotating-box and 4 T queries: 4e-7 to 3e-6, whether Clarabel said Solved or
# AlmostSolved (most say AlmostSolved; Clarabel's own test scales by |A'z| too, so Solved is no check here).
CERTIFY_TOL = 1e-5
# How far beyond the solve's own point the optimum is assumed to lie, entrywise (the module's docstring).
MARGIN = 1.0
CLARABEL_STATUS = STATUS


@dataclass(frozen=True)
class Certificate:
    bound: float | None  # a lower bound on the program's optimum; None: nothing certified
    residual: float  # the dual residual, relative (`cones.dual_residual`)
    assumed: float = np.nan  # |r|.R: what the bound spends on the assumption about where the optimum lies
    reason: str = ""  # why nothing is certified, when nothing is
    radius: np.ndarray | None = None  # R: where the optimum is assumed to lie, |x_opt| <= R entrywise


def check_dual(
    conic: Conic,
    x: np.ndarray,
    z: np.ndarray,
    tol: float = CERTIFY_TOL,
    points: tuple[np.ndarray, ...] = (),
    scale: float = 0.0,
) -> Certificate:
    """The bound that the dual point z certifies on the conic's optimum, x the solve's primal point,
    `points` other feasible points of the program and `scale` the magnitude every entry may reach (the
    module's docstring: they widen the region the optimum is assumed to lie in). Nothing is certified
    when the residual exceeds `tol` (relative to the cost's scale) or when a point is not finite."""
    zp = project_dual(conic, z)
    r, residual = dual_residual(conic, zp)
    if not np.isfinite(residual) or residual > tol:
        return Certificate(None, residual, reason=f"dual residual {residual:.2g} above {tol:g}")
    if not all(np.all(np.isfinite(p)) for p in (x, *points)):
        return Certificate(None, residual, reason="a point is not finite")
    radius = np.maximum(np.max(np.abs([x, *points]), axis=0), scale) + MARGIN
    assumed = float(np.abs(r) @ radius)
    bound = conic.d - float(conic.b @ zp) - assumed
    if not np.isfinite(bound):
        return Certificate(None, residual, assumed, reason="the bound is not finite")
    return Certificate(float(bound), residual, assumed, radius=radius)


def of_solution(
    conic: Conic, sol: ConicSolution, points: tuple[np.ndarray, ...] = (), scale: float = 0.0
) -> Certificate:
    """`check_dual` of `solve.solve(conic)`'s answer (its x and the `points` given in the original program's
    variables, as `ConicSolution.x` is)."""
    own = (lambda v: v) if conic.free is None else (lambda v: v[conic.free])
    return check_dual(conic, own(sol.x), sol.z, points=tuple(own(p) for p in points), scale=scale)


def certify(conic: Conic, x: np.ndarray, z: np.ndarray, tol: float = CERTIFY_TOL) -> tuple[float | None, float]:
    """(lower bound, dual residual) of `check_dual` (the bound None when nothing is certified)."""
    cert = check_dual(conic, x, z, tol)
    return cert.bound, cert.residual


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
    the last that Clarabel solved (its bound None). A ValueError names the status when none solved.
    A near-solution's primal point only guides rounding here: the bound is the certificate's."""
    found = None
    for settings in SOLVES:
        status, x, z = solve_with_dual(conic, **settings)
        if status not in STATUS:
            continue
        bound, residual = certify(conic, x, z)
        found = (status, x, z, bound, residual)
        if bound is not None:
            break
    if found is None:
        raise ValueError(f"Clarabel returned status {status!r}")
    return found
