"""The planner's shortest-path answers against independent GCS implementations.

Drake's `GraphOfConvexSets` (its own transcription, relaxation and rounding; tests/drake_oracle.py)
and, when installed, Tobia Marcucci's `gcsopt` (a cvxpy GCS library with a vertex-based formulation;
it reads the vertices through the planner's own `transcription`, and does its own perspective, flow
constraints and rounding) solve the same mode graph for the same queries. Our MICP value is the exact
optimum (SCIP picks the path, Clarabel solves its restriction), so:

* no oracle may find a cheaper path (that would mean our program cuts off feasible plans);
* their exact answers must equal ours, and their relaxations must bound ours from below.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from drake_oracle import build_drake_gcs, drake_options, solve_drake_gcs, solve_with_drake

from lerobot_gcs_push.box_gcs import GcsPlanner
from lerobot_gcs_push.box_gcs.graph import build_graph
from lerobot_gcs_push.box_gcs.transcription import edge_constraint, vertex_constraints, vertex_costs
from lerobot_gcs_push.scene import Scene, sample_initial_conditions

N_CASES = 12
REL = 1e-4  # rounded / MICP agreement
EXACT_REL = 1e-6  # two exact convex solves of the same restriction (both Clarabel)
BOUND_TOL = 1e-6


@pytest.fixture(scope="module")
def planner() -> GcsPlanner:
    return GcsPlanner(Scene(), method="micp")


@pytest.fixture(scope="module")
def cases(planner):
    """(initial condition, the planner's query, MICP plan) for each sampled query."""
    out = []
    for ic in sample_initial_conditions(Scene(), N_CASES, seed=11):
        q = planner.query(ic.box, ic.finger)
        assert q is not None, f"{ic}: box already at the goal, the oracle test needs a push"
        out.append((ic, q, planner.plan(ic.box, ic.finger, method="micp")))
    return out


def _close(a: float, b: float, rel: float) -> bool:
    return abs(a - b) <= rel * max(1.0, abs(b))


@pytest.mark.parametrize("i", range(N_CASES))
def test_drake_matches_micp(planner, cases, i):
    ic, q, plan = cases[i]
    src, goal, allowed, extra = q.src, q.goal, q.allowed, q.extra_cost
    ours = plan.cost
    # One SolveShortestPath call: relaxation + Drake's rounding (what the benchmark times).
    single = solve_drake_gcs(build_drake_gcs(planner.graph, src, goal, allowed), drake_options(10))
    # Relaxation value kept, then Drake's SamplePaths + SolveConvexRestriction.
    split = solve_with_drake(planner.graph, src, goal, allowed, max_rounded_paths=10)
    # Exact: Drake's restriction of every simple path.
    exact = solve_with_drake(planner.graph, src, goal, allowed, relaxation=False)
    msg = (
        f"{ic}: ours {ours:.6f} ({plan.modes}), Drake rounded {single.cost + extra:.6f} "
        f"{single.vertex_names}, split {split.cost + extra:.6f}, exact {exact.cost + extra:.6f} "
        f"{exact.vertex_names}, Drake bound {split.lower_bound + extra:.6f}"
    )
    assert np.isfinite(single.cost) and np.isfinite(exact.cost), msg
    # A cheaper Drake path would mean our formulation cuts off feasible plans.
    assert exact.cost + extra >= ours - EXACT_REL * max(1.0, ours), msg
    assert _close(exact.cost + extra, ours, EXACT_REL), msg
    assert _close(single.cost + extra, ours, REL), msg
    assert _close(split.cost + extra, ours, REL), msg
    assert split.lower_bound + extra <= ours + BOUND_TOL * max(1.0, ours), msg
    # Drake's path, re-solved with our restriction, costs what Drake says.
    mine = planner.conic.restrict(planner.conic.at(src, goal, allowed), single.edges, src, goal)
    assert _close(mine.cost, single.cost, EXACT_REL), msg


def test_drake_push_pruning_loses_nothing(planner, cases):
    """Disabling pushes against the goal offset (edge_allowed) never removes the optimum."""
    for ic, q, _ in cases[:4]:
        assert q.allowed.min() == 0.0  # something was pruned
        full = solve_with_drake(planner.graph, q.src, q.goal, None, relaxation=False)
        pruned = solve_with_drake(planner.graph, q.src, q.goal, q.allowed, relaxation=False)
        assert _close(full.cost, pruned.cost, EXACT_REL), (ic, full.cost, pruned.cost)


def test_drake_oracle_detects_a_different_problem(planner, cases):
    """The comparison has teeth: a graph from another scene (longer transition buffer) gives Drake a
    different optimum for the same query, so a mismatch in sets or costs does not go unnoticed."""
    other = build_graph(Scene(transition_buffer=0.3))
    _, q, plan = cases[0]
    res = solve_with_drake(other, q.src, q.goal, q.allowed, relaxation=False)
    assert res.cost + q.extra_cost > plan.cost + 0.1


# ------------------------------------------------------------------------------------------ gcsopt
GCSOPT_MICP_CASES = 3  # SCIP on gcsopt's (untightened) MICP takes a few seconds per query


def _gcsopt_graph(gcsopt, graph, q):
    G = gcsopt.GraphOfConvexSets()
    theta = np.concatenate([q.src, q.goal])
    xs, vs = [], []
    for i, vert in enumerate(graph.vertices):
        v = G.add_vertex(vert.name)
        x = v.add_variable(vert.dim)
        if i == graph.source:
            v.add_constraint(x == q.src)
        elif i == graph.target:
            v.add_constraint(x == q.goal)
        for c in vertex_constraints(vert, x, theta):
            v.add_constraint(c)
        for cost in vertex_costs(vert, x):
            v.add_cost(cost)
        xs.append(x)
        vs.append(v)
    for i, e in enumerate(graph.edges):
        if q.allowed[i] > 0.5:
            G.add_edge(vs[e.u], vs[e.v]).add_constraint(edge_constraint(e, xs[e.u], xs[e.v]))
    return G, vs[graph.source], vs[graph.target]


def _gcsopt_path(G, source, target):
    """Follow edges with binary value 1 from the source (disjoint zero-cost cycles are ignored)."""
    path, v = [source], source
    while v is not target:
        nxt = [e for e in G.outgoing_edges(v) if e.binary_variable.value is not None and e.binary_variable.value > 0.5]
        assert len(nxt) == 1, f"gcsopt solution leaves {v.name} along {len(nxt)} edges"
        v = nxt[0].head
        assert v not in path, "gcsopt path revisits a vertex"
        path.append(v)
    return path


@pytest.mark.slow
def test_gcsopt_relaxation_and_rounding(planner, cases):
    gcsopt = pytest.importorskip("gcsopt")
    import cvxpy as cp
    from gcsopt.graph_problems.rounding.shortest_path import single_dfs

    np.random.seed(0)  # gcsopt's rounding samples with numpy's global generator
    for ic, q, plan in cases:
        G, s, t = _gcsopt_graph(gcsopt, planner.graph, q)
        G.solve_shortest_path(s, t, binary=False, solver=cp.CLARABEL)
        assert G.status == cp.OPTIMAL, (ic, G.status)
        bound = G.value + q.extra_cost
        assert bound <= plan.cost + BOUND_TOL * max(1.0, plan.cost), (ic, bound, plan.cost)
        # gcsopt's randomized_dfs, with the restriction solver named (its default would be Mosek).
        paths = []
        for _ in range(50):
            p = single_dfs(G, s, t)
            if p is not None and p not in paths:
                paths.append(p)
            if len(paths) == 10:
                break
        assert paths, ic
        costs = []
        for p in paths:
            G.solve_convex_restriction(
                p, [G.get_edge(a.name, b.name) for a, b in itertools.pairwise(p)], solver=cp.CLARABEL
            )
            costs.append(G.value if G.status == cp.OPTIMAL else np.inf)
        rounded = min(costs) + q.extra_cost
        assert rounded >= plan.cost - EXACT_REL * max(1.0, plan.cost), (ic, rounded, plan.cost)


@pytest.mark.slow
@pytest.mark.parametrize("i", range(GCSOPT_MICP_CASES))
def test_gcsopt_micp_matches(planner, cases, i):
    gcsopt = pytest.importorskip("gcsopt")
    import cvxpy as cp

    ic, q, plan = cases[i]
    extra = q.extra_cost
    G, s, t = _gcsopt_graph(gcsopt, planner.graph, q)
    G.solve_shortest_path(s, t, binary=True, solver=cp.SCIP)
    assert G.status == cp.OPTIMAL, (ic, G.status)
    # SCIP's objective carries its feasibility tolerances on the norm cones.
    assert _close(G.value + extra, plan.cost, REL), (ic, G.value + extra, plan.cost)
    # gcsopt's path, solved exactly by its own convex restriction.
    path = _gcsopt_path(G, s, t)
    edges = [G.get_edge(a.name, b.name) for a, b in itertools.pairwise(path)]
    G.solve_convex_restriction(path, edges, solver=cp.CLARABEL)
    assert _close(G.value + extra, plan.cost, EXACT_REL), (
        ic,
        [v.name for v in path],
        G.value + extra,
        plan.cost,
        plan.modes,
    )
