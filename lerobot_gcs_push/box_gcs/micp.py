"""The exact MICP in SCIP, from the program's conic data.

cvxpy's SCIP interface rebuilds the model from a dictionary-of-keys matrix on every solve and offers
no way to pass a starting solution. Here the MICP's conic data (conic.py, with its two-cycle cuts) is
set for the query, the edges it forbids are dropped, and the model is built from it directly: as fast
as cvxpy's interface on the same program to 1.9x faster (benchmarks/planner_profile.py, 20 queries,
three runs at load 4 to 8: 1.0x, 1.2x, 1.9x).

A known plan can be passed as a starting point (`start`: its path as a partial solution that SCIP
completes) or as an objective limit (`cutoff`). Measured one by one against SCIP's defaults in the
profile (same runs, rotating order): start from 7% faster to 10% slower; cutoff 7%, 20% and 25%
faster, but it needs the rounded plan first (9-14 ms) and turns SCIP's answer into "infeasible"
whenever the limit sits below SCIP's own value of that plan, so neither is used yet. Nor are the settings
tried: separating off 4-5x slower, presolving off 5x slower with 3 of 20 optima wrong, assumeconvex and
RENS off within the noise. Plans use SCIP's defaults.
"""

from __future__ import annotations

import time

import numpy as np
from pyscipopt import Model, quicksum

from lerobot_gcs_push.box_gcs.conic_gcs import EdgeColumns, parametric
from lerobot_gcs_push.box_gcs.gcs import FlowSolution
from lerobot_gcs_push.box_gcs.graph import ModeGraph
from lerobot_gcs_push.conic import Conic, Infeasible
from lerobot_gcs_push.planning.interface import PlanningError


class ScipMicp:
    def __init__(self, graph: ModeGraph):
        self.graph = graph
        self.data = parametric(graph, integer=True)
        self.cols = EdgeColumns(graph, self.data)
        self.build_time_s = 0.0  # the last solve's model building, for the profile

    def solve(
        self,
        src,
        goal,
        allowed,
        start: tuple[int, ...] | None = None,
        cutoff: float | None = None,
        params: dict | None = None,
    ) -> FlowSolution:
        """The MICP's flows. `start`: a feasible path (edge indices) to begin from; `cutoff`: the cost of
        a feasible plan, above which SCIP may discard any node."""
        t0 = time.perf_counter()
        dropped = [i for i in range(len(allowed)) if allowed[i] <= 0]
        try:
            conic = self.data.at(np.concatenate([src, goal, allowed])).fix(self.cols.fixed(dropped, {}))
        except Infeasible:
            raise PlanningError("SCIP: the GCS MICP is infeasible (no allowed path)") from None
        model, x = _model(conic, self.data.boolean[conic.free])
        model.setParams(params or {})
        if cutoff is not None:
            model.setObjlimit(cutoff - conic.d)
        if start is not None:
            sol = model.createPartialSol()
            on = set(start)
            for i in range(len(allowed)):
                j = np.searchsorted(conic.free, self.cols.y[i])
                if j < len(conic.free) and conic.free[j] == self.cols.y[i]:
                    model.setSolVal(sol, x[j], float(i in on))
            model.addSol(sol)
        self.build_time_s = time.perf_counter() - t0
        model.optimize()
        status = model.getStatus()
        if status not in ("optimal", "gaplimit") or model.getNSols() == 0:
            raise PlanningError(f"SCIP returned status {status!r} on the GCS MICP")
        best = model.getBestSol()
        full = conic.fixed.copy()
        full[conic.free] = [best[v] for v in x]
        flows = np.clip(full[self.cols.y], 0.0, 1.0)
        return FlowSolution(model.getObjVal() + conic.d, flows, time.perf_counter() - t0, status)


def _model(conic: Conic, binary: np.ndarray) -> tuple[Model, list]:
    """SCIP's model of min c.x + d, A x + s = b, s in the cones (a cone's rows: s_0 >= ||s_1:||)."""
    if conic.psd:
        raise ValueError("SCIP's model here has no PSD cones")
    model = Model()
    model.hideOutput()
    x = [
        model.addVar(lb=0.0 if bj else None, ub=1.0 if bj else None, obj=float(cj), vtype="B" if bj else "C")
        for cj, bj in zip(conic.c, binary)
    ]
    A = conic.A.tocsr()
    A.eliminate_zeros()  # the pattern holds every query's entries; SCIP should see this one's only

    def row(i):
        lo, hi = A.indptr[i], A.indptr[i + 1]
        return quicksum(float(a) * x[j] for a, j in zip(A.data[lo:hi], A.indices[lo:hi]))

    for i in range(conic.zero):
        model.addCons(row(i) == float(conic.b[i]))
    for i in range(conic.zero, conic.zero + conic.nonneg):
        model.addCons(row(i) <= float(conic.b[i]))
    start = conic.zero + conic.nonneg
    for k in conic.soc:
        s = [model.addVar(lb=0.0 if j == 0 else None, ub=None) for j in range(k)]
        for j in range(k):
            model.addCons(s[j] + row(start + j) == float(conic.b[start + j]))
        model.addCons(quicksum(v * v for v in s[1:]) <= s[0] * s[0])
        start += k
    return model, x
