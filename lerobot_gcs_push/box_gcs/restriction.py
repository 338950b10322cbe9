"""Convex restriction of the mode graph to one path: the exact optimum along a fixed mode sequence.

Used by rounding (each candidate path) and by the brute-force oracle (every simple path). One small
cvxpy program per path, compiled once and cached: the initial state and goal are Parameters (DPP).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import cvxpy as cp
import numpy as np

from lerobot_gcs_push.box_gcs.graph import ModeGraph
from lerobot_gcs_push.box_gcs.transcription import edge_constraint, vertex_constraints, vertex_costs


@dataclass
class PathSolution:
    edges: tuple[int, ...]
    vertices: tuple[int, ...]
    cost: float  # inf when the restriction is infeasible
    points: dict[int, np.ndarray]
    solve_time_s: float
    accurate: bool = True  # False when Clarabel reports OPTIMAL_INACCURATE
    x: np.ndarray | None = None  # the point in the relaxation's conic variables (conic_gcs.py), where solved there

    def rank(self) -> tuple:
        """Order for choosing among candidates: accurate solutions first, then cost."""
        return (not self.accurate, self.cost)


class Restriction:
    def __init__(self, graph: ModeGraph, edges: tuple[int, ...]):
        g = graph
        self.graph, self.edges = g, tuple(edges)
        self.vertices = (g.edges[edges[0]].u,) + tuple(g.edges[i].v for i in edges)
        self.src = cp.Parameter(g.vertices[g.source].dim)
        self.goal = cp.Parameter(g.vertices[g.target].dim)
        self.x: dict[int, cp.Expression] = {g.source: self.src, g.target: self.goal}
        theta = cp.hstack([self.src, self.goal])  # graph.Theta
        cons, cost = [], []
        for v in self.vertices:
            if v in self.x:
                continue
            vert = g.vertices[v]
            x = self.x[v] = cp.Variable(vert.dim)
            cons += vertex_constraints(vert, x, theta)
            cost += vertex_costs(vert, x)
        for i in edges:
            e = g.edges[i]
            cons.append(edge_constraint(e, self.x[e.u], self.x[e.v]))
        self.problem = cp.Problem(cp.Minimize(sum(cost)), cons)

    def solve(self, src: np.ndarray, goal: np.ndarray) -> PathSolution:
        self.src.value = np.asarray(src, float)
        self.goal.value = np.asarray(goal, float)
        t0 = time.perf_counter()
        try:
            self.problem.solve(solver=cp.CLARABEL)
        except cp.SolverError:
            return PathSolution(self.edges, self.vertices, np.inf, {}, time.perf_counter() - t0)
        elapsed = time.perf_counter() - t0
        if self.problem.status not in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE):
            return PathSolution(self.edges, self.vertices, np.inf, {}, elapsed)
        pts = {v: np.asarray(x.value, float) for v, x in self.x.items() if isinstance(x, cp.Variable)}
        return PathSolution(
            self.edges,
            self.vertices,
            float(self.problem.value),
            pts,
            elapsed,
            accurate=self.problem.status == cp.OPTIMAL,
        )


class RestrictionCache:
    """Compiled restrictions by path: the set of distinct paths is small, so compile cost amortises."""

    def __init__(self, graph: ModeGraph):
        self.graph = graph
        self._cache: dict[tuple[int, ...], Restriction] = {}

    def solve(self, edges, src, goal) -> PathSolution:
        key = tuple(edges)
        r = self._cache.get(key)
        if r is None:
            r = self._cache[key] = Restriction(self.graph, key)
        return r.solve(src, goal)

    def __len__(self) -> int:
        return len(self._cache)


def brute_force(graph: ModeGraph, src, goal, cache: RestrictionCache | None = None) -> PathSolution:
    """The exact optimum by enumeration: solve the restriction of every simple path, keep the best."""
    if cache is None:
        cache = RestrictionCache(graph)
    best = None
    for path in graph.simple_paths():
        sol = cache.solve(path, src, goal)
        if best is None or sol.rank() < best.rank():
            best = sol
    return best
