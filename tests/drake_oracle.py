"""A second, independent solver for the planner's shortest-path problem: Drake's `GraphOfConvexSets`.

A test oracle (also timed by benchmarks/planner_bench.py), not part of the package. The mode graph
(`lerobot_gcs_push/box_gcs/graph.py`) is plain numpy data; here it is handed to Drake, which builds its
own transcription (perspective relaxation, flow conservation, degree and two-cycle constraints) and its
own rounding. Nothing from the planner's cvxpy programs is used, so agreement between the two is
evidence that both pose the same problem.

    q = planner.query(box, finger)                           # the problem GcsPlanner.plan solves
    dg = build_drake_gcs(graph, q.src, q.goal, q.allowed)    # one Drake GCS per query
    res = solve_drake_gcs(dg, drake_options())               # one SolveShortestPath call (timed)
    res = solve_with_drake(graph, q.src, q.goal, q.allowed)  # relaxation bound + rounding, in one go

Per query: every vertex set becomes an `HPolyhedron` (the pinned coordinates, evaluated at
theta = [src, goal], become pairs of inequalities); the source and target are `Point`s; each vertex
cost is an `L2NormCost` on D x plus a `LinearCost` g.x + k; each edge carries the linear equality
`Mu x_u + Mv x_v == h`; edges whose `allowed` entry is 0 are not added.

Drake has no mixed-integer solver without a Mosek/Gurobi licence, so `relaxation=False` computes the
exact optimum by solving Drake's convex restriction (`SolveConvexRestriction`) of every simple path.
"""

from __future__ import annotations

import contextlib
import logging
import time
from dataclasses import dataclass, field

import numpy as np
from pydrake.geometry.optimization import GraphOfConvexSets, GraphOfConvexSetsOptions, HPolyhedron, Point
from pydrake.solvers import Binding, ClarabelSolver, Constraint, Cost, L2NormCost, LinearCost, LinearEqualityConstraint

from lerobot_gcs_push.box_gcs.graph import ModeGraph


@dataclass
class DrakeResult:
    cost: float  # rounded cost (relaxation) or exact optimum (enumeration); inf when nothing is feasible
    lower_bound: float  # optimum of Drake's convex relaxation; nan when it was not computed
    vertex_names: list[str]  # the returned path, source to target
    solve_time_s: float
    status: str
    edges: tuple[int, ...] = ()  # the path as indices into graph.edges
    extra: dict = field(default_factory=dict)


@dataclass
class DrakeGcs:
    graph: ModeGraph
    gcs: GraphOfConvexSets
    vertices: list  # Drake vertex per graph vertex
    edges: dict  # graph edge index -> Drake edge (only allowed edges)
    source: object
    target: object

    def edge_index(self, drake_edge) -> int:
        ids = {e.id(): i for i, e in self.edges.items()}
        return ids[drake_edge.id()]

    def path_result(self, drake_edges) -> tuple[tuple[int, ...], list[str]]:
        idx = tuple(self.edge_index(e) for e in drake_edges)
        names = [self.graph.vertices[self.graph.edges[idx[0]].u].name] if idx else []
        names += [self.graph.vertices[self.graph.edges[i].v].name for i in idx]
        return idx, names


def _vertex_set(vert, theta: np.ndarray):
    """The vertex's polyhedron, its pinned coordinates as pairs of inequalities."""
    A, c = np.asarray(vert.A, float), np.asarray(vert.c, float)
    if vert.pin_cols:
        P = np.eye(vert.dim)[list(vert.pin_cols)]
        val = vert.pin_S @ theta
        A = np.vstack([A, P, -P])
        c = np.concatenate([c, val, -val])
    return HPolyhedron(A, c)


def build_drake_gcs(graph: ModeGraph, src, goal, allowed=None) -> DrakeGcs:
    """One Drake GCS for the query (src = [box0, finger0], goal); edges with allowed == 0 are left out."""
    src = np.asarray(src, float)
    goal = np.asarray(goal, float)
    theta = np.concatenate([src, goal])  # graph.Theta
    gcs = GraphOfConvexSets()
    dv = []
    for i, vert in enumerate(graph.vertices):
        if i == graph.source:
            s = Point(src)
        elif i == graph.target:
            s = Point(goal)
        else:
            s = _vertex_set(vert, theta)
        v = gcs.AddVertex(s, vert.name)
        x = v.x()
        if vert.D is not None:
            D = np.asarray(vert.D, float)
            v.AddCost(Binding[Cost](L2NormCost(D, np.zeros(D.shape[0])), x))
        if vert.g is not None or vert.k:
            g = np.zeros(vert.dim) if vert.g is None else np.asarray(vert.g, float)
            v.AddCost(Binding[Cost](LinearCost(g, float(vert.k)), x))
        dv.append(v)
    de = {}
    for i, e in enumerate(graph.edges):
        if allowed is not None and allowed[i] <= 0.5:
            continue
        edge = gcs.AddEdge(dv[e.u], dv[e.v], f"e{i}")
        M = np.hstack([np.asarray(e.Mu, float), np.asarray(e.Mv, float)])
        vars_ = np.concatenate([edge.xu(), edge.xv()])
        edge.AddConstraint(Binding[Constraint](LinearEqualityConstraint(M, np.asarray(e.h, float)), vars_))
        de[i] = edge
    return DrakeGcs(graph, gcs, dv, de, dv[graph.source], dv[graph.target])


def drake_options(
    max_rounded_paths: int = 10, relaxation: bool = True, preprocessing: bool = False, seed: int = 0
) -> GraphOfConvexSetsOptions:
    opts = GraphOfConvexSetsOptions()
    opts.convex_relaxation = relaxation
    opts.max_rounded_paths = max_rounded_paths
    opts.preprocessing = preprocessing
    opts.rounding_seed = seed
    opts.solver = ClarabelSolver()
    opts.restriction_solver = ClarabelSolver()
    opts.preprocessing_solver = ClarabelSolver()
    return opts


@contextlib.contextmanager
def quiet_drake(level: int = logging.WARNING):
    """Silence Drake's per-solve INFO lines (they go to the Python logger "drake")."""
    logger = logging.getLogger("drake")
    old = logger.level
    logger.setLevel(max(level, old))
    try:
        yield
    finally:
        logger.setLevel(old)


def _cost(result) -> float:
    return float(result.get_optimal_cost()) if result.is_success() else np.inf


def solve_drake_gcs(dg: DrakeGcs, options: GraphOfConvexSetsOptions) -> DrakeResult:
    """One `SolveShortestPath` call (with rounding when options.max_rounded_paths > 0). The returned
    cost is Drake's rounded cost; with max_rounded_paths == 0 it is the relaxation's optimum.
    convex_relaxation=False would need a licensed mixed-integer solver (Mosek/Gurobi): use
    `solve_with_drake(..., relaxation=False)` for the exact optimum instead."""
    with quiet_drake():
        t0 = time.perf_counter()
        result = dg.gcs.SolveShortestPath(dg.source, dg.target, options)
        elapsed = time.perf_counter() - t0
    status = str(result.get_solution_result())
    if not result.is_success():
        return DrakeResult(np.inf, np.nan, [], elapsed, status)
    rounded = bool(options.convex_relaxation) and (options.max_rounded_paths or 0) > 0
    cost = _cost(result)
    idx, names = dg.path_result(dg.gcs.GetSolutionPath(dg.source, dg.target, result, tolerance=0.5 if rounded else 1.0))
    lower = np.nan if rounded else cost
    return DrakeResult(cost, lower, names, elapsed, status, idx)


def solve_with_drake(
    graph: ModeGraph,
    src,
    goal,
    allowed=None,
    max_rounded_paths: int = 10,
    relaxation: bool = True,
    preprocessing: bool = False,
    seed: int = 0,
) -> DrakeResult:
    """Drake's answer to the query.

    relaxation=True: solve Drake's convex relaxation (its value is the lower bound), sample up to
    `max_rounded_paths` paths from its flows with Drake's `SamplePaths` and keep the best of Drake's
    convex restrictions: the same steps as one `SolveShortestPath` call with rounding, split so that
    the relaxation value is kept.
    relaxation=False: the exact optimum, by Drake's convex restriction of every simple path
    (no licensed mixed-integer solver is available to Drake here)."""
    dg = build_drake_gcs(graph, src, goal, allowed)
    with quiet_drake():
        return _solve_split(dg, relaxation, max_rounded_paths, preprocessing, seed)


def _solve_split(dg: DrakeGcs, relaxation, max_rounded_paths, preprocessing, seed) -> DrakeResult:
    graph = dg.graph
    t0 = time.perf_counter()
    if relaxation:
        opts = drake_options(0, True, preprocessing, seed)
        relax = dg.gcs.SolveShortestPath(dg.source, dg.target, opts)
        if not relax.is_success():
            return DrakeResult(np.inf, np.nan, [], time.perf_counter() - t0, str(relax.get_solution_result()))
        lower = _cost(relax)
        opts.max_rounded_paths = max_rounded_paths
        paths = dg.gcs.SamplePaths(dg.source, dg.target, relax, opts) if max_rounded_paths > 0 else []
    else:
        lower = np.nan
        opts = drake_options(0, False, preprocessing, seed)
        paths = [[dg.edges[i] for i in p] for p in graph.simple_paths() if all(i in dg.edges for i in p)]
    best_cost, best_path, best_status = np.inf, None, "no path"
    for p in paths:
        r = dg.gcs.SolveConvexRestriction(p, opts)
        c = _cost(r)
        if c < best_cost:
            best_cost, best_path, best_status = c, p, str(r.get_solution_result())
    elapsed = time.perf_counter() - t0
    if best_path is None:
        return DrakeResult(np.inf, lower, [], elapsed, best_status, extra={"paths": len(paths)})
    idx, names = dg.path_result(best_path)
    if not relaxation:
        lower = best_cost
    return DrakeResult(best_cost, lower, names, elapsed, best_status, idx, {"paths": len(paths)})
