"""Clarabel on a `Conic`, and which of its answers count as solved.

Clarabel says "Solved" when its residuals meet the tolerances asked, and "AlmostSolved" when they meet
only its reduced ones (about 5e-5, Clarabel's defaults). A near-solution is taken here only after its
residuals are measured (`near_solution`): primal feasibility, dual feasibility and the duality gap, each
within NEAR_TOL. Whether a solution's dual objective bounds the optimum is the certificate's question
(certificate.py), not the solver's status's.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import clarabel
import numpy as np
import scipy.sparse as sp

from lerobot_gcs_push.conic.cones import dual_residual, primal_residual, project_dual

if TYPE_CHECKING:
    from lerobot_gcs_push.conic.program import Conic

# Clarabel's statuses that carry a solution, by cvxpy's names for them.
STATUS = {"Solved": "optimal", "AlmostSolved": "optimal_inaccurate"}
# The residuals (relative, as `cones` measures them) a near-solution must meet: the certificate's own
# tolerance on the dual residual (certificate.CERTIFY_TOL), and the same on the primal and the gap.
NEAR_TOL = 1e-5


@dataclass
class ConicSolution:
    status: str  # Clarabel's: "Solved", "AlmostSolved", "PrimalInfeasible", ...
    value: float  # the primal objective; inf unless solved
    x: np.ndarray  # every variable of the program `fix` was called on (fixed ones at their values)
    solve_time_s: float
    # Clarabel's dual point, unchecked: no bound until `certificate.certify` has vouched for it.
    z: np.ndarray | None = None
    accepted: bool = False  # Solved, or AlmostSolved with residuals within NEAR_TOL

    @property
    def solved(self) -> bool:
        return self.accepted


def clarabel_solve(conic: Conic, tol: float = 1e-7, refine: bool = True):
    """Clarabel's solution on the conic data at tolerances `tol` (cvxpy passes its defaults, 1e-8);
    `refine`: its iterative refinement of each step's linear solve (its default). A new solver each time:
    reusing one through Clarabel's `update` saves its setup (a fifth of a relaxation's time), but where the
    relaxation's optimum is not unique its flows then differ from a fresh solve's (by up to 0.26 on 120
    queries), and a plan would depend on what the planner solved before."""
    n = len(conic.c)
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    settings.tol_gap_abs = settings.tol_gap_rel = settings.tol_feas = tol
    settings.iterative_refinement_enable = refine
    return clarabel.DefaultSolver(sp.csc_matrix((n, n)), conic.c, conic.A, conic.b, conic.cones(), settings).solve()


def solve_with_dual(conic: Conic, tol: float = 1e-7, refine: bool = True) -> tuple[str, np.ndarray, np.ndarray]:
    """Clarabel's status, primal point x and dual point z on the conic data (`clarabel_solve`)."""
    sol = clarabel_solve(conic, tol, refine)
    return str(sol.status), np.asarray(sol.x, float), np.asarray(sol.z, float)


def near_solution(conic: Conic, x: np.ndarray, z: np.ndarray, tol: float = NEAR_TOL) -> bool:
    """x and z within `tol` of primal and dual feasibility, and of each other's objective: measured here,
    where Clarabel's AlmostSolved says only that its reduced tolerances were met."""
    zp = project_dual(conic, z)
    _, dual = dual_residual(conic, zp)
    primal_value, dual_value = float(conic.c @ x), -float(conic.b @ zp)
    gap = abs(primal_value - dual_value) / max(1.0, abs(primal_value + conic.d))
    return bool(primal_residual(conic, x) <= tol and dual <= tol and gap <= tol)


def solve(conic: Conic, tol: float = 1e-7) -> ConicSolution:
    """Clarabel on the conic data at `tol`: solved when Clarabel says Solved, or AlmostSolved and its
    residuals pass `near_solution`."""
    # 1e-7 instead of Clarabel's 1e-8: plans 6 % faster, every reference cost unchanged to 1e-6.
    sol = clarabel_solve(conic, tol)
    status = str(sol.status)
    x, z = np.asarray(sol.x, float), np.asarray(sol.z, float)
    accepted = status == "Solved" or (status == "AlmostSolved" and near_solution(conic, x, z))
    value = float(sol.obj_val) + conic.d if accepted else np.inf
    return ConicSolution(status, value, conic.full(x), float(sol.solve_time), z, accepted)
