"""The GCS relaxation and every path's restriction, solved from one conic form of the relaxation.

A query sets theta = [source, goal, allowed] in the relaxation's conic data (conic.py) once; then

* the relaxation drops the edges the query forbids (y, z, w fixed to 0) instead of bounding their flow
  by 0 inside the solve: a smaller program with the same optimum;
* a path's restriction is the relaxation with y fixed to the path's indicator and every other edge
  dropped: flow conservation then carries y = 1 along the path, and each copy of a path vertex's point
  equals the point (the perspective of a bounded set at y = 0 is {0}). Its optimum is the restriction's
  (restriction.py writes it directly; tests/test_box_gcs_conic.py checks both agree), and no path needs
  a program of its own, so nothing compiles per path.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import cvxpy as cp
import numpy as np

from lerobot_gcs_push.box_gcs import gcs, transcription
from lerobot_gcs_push.box_gcs.gcs import FlowSolution, GcsProgram, free_coords
from lerobot_gcs_push.box_gcs.graph import ModeGraph
from lerobot_gcs_push.box_gcs.restriction import PathSolution
from lerobot_gcs_push.conic import Conic, Fixing, Infeasible, ParametricConic, cached
from lerobot_gcs_push.conic.certificate import Certificate, of_solution
from lerobot_gcs_push.conic.solve import ConicSolution, solve
from lerobot_gcs_push.planning.interface import PlanningError


@dataclass
class ConicQuery:
    """One query's conic data and what the relaxation found on it."""

    conic: Conic
    flows: FlowSolution
    relaxed: Conic | None = None  # the relaxation as solved: `conic` with the forbidden edges dropped
    solution: ConicSolution | None = None  # Clarabel's answer on it, its dual point unchecked

    def certificate(self, plan: PathSolution | None = None) -> Certificate:
        """The relaxation's bound on the query's optimum, from its dual point checked (`conic.certificate`);
        `plan`: a path's restriction, a feasible point of the same program near the optimum, which joins
        the region the certificate assumes the optimum lies in, and whose largest entry sets its scale
        (every variable here is a flow, a copy of a point in the workspace or a length there)."""
        if plan is None or plan.x is None:
            return of_solution(self.relaxed, self.solution)
        return of_solution(self.relaxed, self.solution, (plan.x,), float(np.max(np.abs(plan.x))))


def parametric(graph: ModeGraph, integer: bool = False) -> ParametricConic:
    """The GCS program's conic data: the relaxation (Clarabel) or the MICP with its two-cycle cuts
    (SCIP). cvxpy's compilation takes most of a second, so the result is cached on disk (conic.cached),
    keyed by the graph's data and the code that turns it into a program."""

    def build() -> ParametricConic:
        prog = GcsProgram(graph, integer=integer, two_cycles=integer)
        variables = {"y": prog.y, **prog.variables}
        params = [prog.src, prog.goal, prog.allowed]
        return ParametricConic(prog.problem, params, variables, cp.SCIP if integer else cp.CLARABEL)

    sources = [gcs.__file__, transcription.__file__, __file__]
    return cached(f"gcs-{'micp' if integer else 'relaxation'}", _key(graph, integer), sources, build)


def _key(graph: ModeGraph, integer: bool) -> bytes:
    parts = [f"{integer}".encode()]
    for v in graph.vertices:
        parts.append(f"{v.name} {v.kind} {v.dim} {v.k} {v.pin_cols}".encode())
        for a in (v.A, v.c, v.D, v.g, v.pin_S):
            parts.append(b"-" if a is None else np.ascontiguousarray(a, float).tobytes())
    for e in graph.edges:
        parts.append(f"{e.u} {e.v}".encode())
        for a in (e.Mu, e.Mv, e.h):
            parts.append(np.ascontiguousarray(a, float).tobytes())
    return b"|".join(parts)


class EdgeColumns:
    """Where each edge's flow and copies sit in a GCS program's conic x, to fix them per query."""

    def __init__(self, graph: ModeGraph, data: ParametricConic):
        cols = data.columns
        self.n = data.n
        self.y = np.arange(cols["y"].start, cols["y"].stop)
        # Per edge, the columns of its flow and of its copies' variables (those not y * parameter).
        self.edge = [
            np.r_[self.y[i], _cols(cols.get(f"z{i}")), _cols(cols.get(f"w{i}"))] for i in range(len(graph.edges))
        ]
        self.w = [_cols(cols.get(f"w{i}")) for i in range(len(graph.edges))]

    def fixed(self, dropped, flows: dict[int, float]) -> np.ndarray:
        """x's values for `Conic.fix`: the `dropped` edges at 0, the `flows` given, the rest NaN (free)."""
        values = np.full(self.n, np.nan)
        for i in dropped:
            values[self.edge[i]] = 0.0
        for i, y in flows.items():
            values[self.y[i]] = y
        return values


class ConicGcs:
    def __init__(self, graph: ModeGraph, data: ParametricConic | None = None):
        self.graph = graph
        self.data = data or parametric(graph)
        self.cols = EdgeColumns(graph, self.data)
        self._fixings: dict[tuple, Fixing] = {}

    def fixing(self, conic: Conic, key: tuple, values: np.ndarray) -> Fixing:
        """Every query's conic data has the same pattern (ParametricConic.at), so one per key."""
        if key not in self._fixings:
            self._fixings[key] = Fixing(conic, ~np.isnan(values))
        return self._fixings[key]

    def relax(self, src, goal, allowed) -> ConicQuery:
        """The relaxation of the query; raises PlanningError when it has no optimum."""
        conic = self.at(src, goal, allowed)
        t0 = time.perf_counter()
        try:
            dropped = tuple(i for i in range(len(allowed)) if allowed[i] <= 0)
            values, key = self.cols.fixed(dropped, {}), ("relaxation", dropped)
            relaxed = conic.fix(values, self.fixing(conic, key, values))
            sol = solve(relaxed)
        except Infeasible:
            sol = None
        elapsed = time.perf_counter() - t0
        if sol is None or not sol.solved:
            status = "infeasible" if sol is None else sol.status
            raise PlanningError(f"CLARABEL returned status {status!r} on the GCS relaxation")
        flows = np.clip(sol.x[self.cols.y], 0.0, 1.0)
        return ConicQuery(conic, FlowSolution(sol.value, flows, elapsed, sol.status), relaxed, sol)

    def at(self, src, goal, allowed) -> Conic:
        return self.data.at(np.concatenate([src, goal, allowed]))

    def restrict(self, conic: Conic, edges, src, goal) -> PathSolution:
        """The exact optimum along the path `edges` (an inf cost when it is infeasible)."""
        g = self.graph
        edges = tuple(edges)
        vertices = (g.edges[edges[0]].u,) + tuple(g.edges[i].v for i in edges)
        on = set(edges)
        t0 = time.perf_counter()
        try:
            values = self.cols.fixed([i for i in range(len(g.edges)) if i not in on], {i: 1.0 for i in edges})
            key = ("path", edges)
            sol = solve(conic.fix(values, self.fixing(conic, key, values)))
        except Infeasible:
            return PathSolution(edges, vertices, np.inf, {}, time.perf_counter() - t0)
        elapsed = time.perf_counter() - t0
        if not sol.solved:
            return PathSolution(edges, vertices, np.inf, {}, elapsed)
        theta = np.concatenate([src, goal])
        points = {g.edges[i].v: self._point(g.edges[i].v, sol.x[self.cols.w[i]], theta) for i in edges[:-1]}
        return PathSolution(edges, vertices, sol.value, points, elapsed, accurate=sol.status == "Solved", x=sol.x)

    def _point(self, v: int, unpinned: np.ndarray, theta: np.ndarray) -> np.ndarray:
        vert = self.graph.vertices[v]
        x = np.zeros(vert.dim)
        x[free_coords(vert)] = unpinned
        if vert.pin_cols:
            x[list(vert.pin_cols)] = vert.pin_S @ theta
        return x


def _cols(s: slice | None) -> np.ndarray:
    return np.arange(0) if s is None else np.arange(s.start, s.stop)
