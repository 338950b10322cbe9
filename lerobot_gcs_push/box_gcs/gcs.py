"""The shortest-path problem in the mode graph, posed directly in cvxpy.

The standard perspective (homogenised) formulation of Marcucci et al.: each edge e = (u, v) carries a
flow y_e in [0, 1] and two copies of its end points' variables, z_e ~ y_e x_u and w_e ~ y_e x_v, that lie
in the cones of the vertex sets; the edge constraints hold in perspective; flows and copies are conserved
at every vertex; each vertex is entered at most once. With y binary this is the exact mixed-integer
program (SCIP); with y in [0, 1] its convex relaxation (Clarabel), a lower bound.

What makes the relaxation tight here is in the graph, not in extra cuts: every box position is pinned to
the query (graph.py), which took the median lower-bound gap from about 15% to 6% on random instances,
and push edges whose direction disagrees with the goal offset get an upper bound of 0 (a parameter).
The two-cycle constraints of Drake's GraphOfConvexSets (`two_cycles=True`) change no relaxation bound
on this graph (20 instances: median gap 5.97% with and without) and add 60% to Clarabel's time, so the
relaxation leaves them out; but they are valid cuts that SCIP uses well: MICP median 0.44 s with them
against 1.14 s without (p95 0.75 s against 4.1 s, 16 instances, same optima), so the MICP keeps them.
The remaining gap comes from the finger's route splitting around both sides of the box; randomized
rounding recovers the optimum (tests/test_box_gcs_planner.py).

The graph is fixed, so the initial state, the goal and the edge bounds are cvxpy Parameters and the
program is compiled once (DPP); a new query is only a solver call.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import cvxpy as cp
import numpy as np

from lerobot_gcs_push.box_gcs.graph import ModeGraph, VertexKind
from lerobot_gcs_push.box_gcs.transcription import edge_constraint, in_set, vertex_costs
from lerobot_gcs_push.planning.interface import PlanningError


@dataclass
class FlowSolution:
    value: float
    flows: np.ndarray  # y per edge
    solve_time_s: float
    status: str


def free_coords(vert) -> list[int]:
    """The coordinates of a vertex's point that the query does not pin."""
    return [j for j in range(vert.dim) if j not in vert.pin_cols]


class GcsProgram:
    def __init__(self, graph: ModeGraph, integer: bool = False, two_cycles: bool = False):
        self.graph = graph
        self.integer = integer
        V, E = graph.vertices, graph.edges
        nE = len(E)
        self.src = cp.Parameter(V[graph.source].dim, name="source")
        self.goal = cp.Parameter(V[graph.target].dim, name="goal")
        theta = cp.hstack([self.src, self.goal])  # graph.Theta
        self.allowed = cp.Parameter(nE, nonneg=True, name="allowed")
        # No `nonneg` attribute: cvxpy would swap in a new variable, and conic.py finds y by its id.
        self.y = cp.Variable(nE, boolean=True, name="y") if integer else cp.Variable(nE, name="y")
        y = self.y
        self.variables: dict[str, cp.Variable] = {}  # the copies' unpinned coordinates, by name
        self.z: dict[int, cp.Expression] = {}
        self.w: dict[int, cp.Expression] = {}
        for i, e in enumerate(E):
            self.z[i] = y[i] * self.src if e.u == graph.source else self._copy(V[e.u], y[i], theta, f"z{i}")
            self.w[i] = y[i] * self.goal if e.v == graph.target else self._copy(V[e.v], y[i], theta, f"w{i}")

        cons: list[cp.Constraint] = [y <= self.allowed] + ([] if integer else [y >= 0])
        for i, e in enumerate(E):
            # The pins hold by construction of the copies (`_copy`); the source and target have no set.
            cons += in_set(V[e.u], self.z[i], y[i])
            cons += in_set(V[e.v], self.w[i], y[i])
            cons.append(edge_constraint(e, self.z[i], self.w[i], y[i]))

        ins = {v: graph.in_edges(v) for v in range(len(V))}
        outs = {v: graph.out_edges(v) for v in range(len(V))}
        cost_terms = []
        for v, vert in enumerate(V):
            if v == graph.source:
                cons.append(cp.sum(y[outs[v]]) == 1)
                continue
            if v == graph.target:
                cons.append(cp.sum(y[ins[v]]) == 1)
                continue
            phi_in = cp.sum(y[ins[v]])
            cons += [phi_in == cp.sum(y[outs[v]]), phi_in <= 1]
            cons.append(sum(self.w[i] for i in ins[v]) == sum(self.z[i] for i in outs[v]))
            for i in ins[v]:
                cost_terms += vertex_costs(vert, self.w[i], y[i])
            if two_cycles and vert.kind == VertexKind.FREE:
                cons += self._two_cycles(v, ins[v], outs[v])
        self.problem = cp.Problem(cp.Minimize(sum(cost_terms)), cons)
        assert self.problem.is_dcp(dpp=True), "GCS program must be DPP so that queries skip compilation"
        self.compile_time_s = 0.0

    def _copy(self, vert, y, theta, name: str) -> cp.Expression:
        """An edge's copy of a vertex point, y x. Its pinned coordinates are y S theta, no variables: half
        of a free vertex's point and all of a push vertex's are pinned, so Clarabel and SCIP get a
        program with about half the variables and none of the pin equalities."""
        free = free_coords(vert)
        eye = np.eye(vert.dim)
        parts = []
        if free:
            self.variables[name] = cp.Variable(len(free), name=name)
            parts.append(eye[:, free] @ self.variables[name])
        if vert.pin_cols:
            parts.append(eye[:, list(vert.pin_cols)] @ (y * (vert.pin_S @ theta)))
        return sum(parts[1:], parts[0])

    def _two_cycles(self, v: int, ins: list[int], outs: list[int]) -> list[cp.Constraint]:
        E, y = self.graph.edges, self.y
        vert = self.graph.vertices[v]
        phi = cp.sum(y[ins])
        total_in = sum(self.w[i] for i in ins)
        cons = []
        for i in ins:
            u = E[i].u
            for j in outs:
                if E[j].v == u:
                    rest = phi - y[i] - y[j]
                    cons.append(rest >= 0)
                    # The pins need no cut: those of each copy imply them.
                    cons += in_set(vert, total_in - self.w[i] - self.z[j], rest)
        return cons

    def set_query(self, src: np.ndarray, goal: np.ndarray, allowed: np.ndarray) -> None:
        self.src.value = np.asarray(src, float)
        self.goal.value = np.asarray(goal, float)
        self.allowed.value = np.asarray(allowed, float)

    def compile(self) -> float:
        """Canonicalise once (with placeholder parameters); returns the compile time."""
        if self.src.value is None:
            V = self.graph.vertices
            self.set_query(
                np.zeros(V[self.graph.source].dim), np.zeros(V[self.graph.target].dim), np.ones(len(self.graph.edges))
            )
        t0 = time.perf_counter()
        self.problem.get_problem_data(self._solver(), ignore_dpp=False)
        self.compile_time_s = time.perf_counter() - t0
        return self.compile_time_s

    def _solver(self) -> str:
        return cp.SCIP if self.integer else cp.CLARABEL

    def solve(self, **solver_opts) -> FlowSolution:
        solver = self._solver()
        t0 = time.perf_counter()
        try:
            self.problem.solve(solver=solver, **solver_opts)
        except cp.SolverError as err:
            raise PlanningError(
                f"{solver} failed on the GCS {'MICP' if self.integer else 'relaxation'}: {err}"
            ) from err
        elapsed = time.perf_counter() - t0
        status = self.problem.status
        if status not in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE):
            raise PlanningError(
                f"{solver} returned status {status!r} on the GCS {'MICP' if self.integer else 'relaxation'}"
            )
        flows = np.clip(np.asarray(self.y.value, float), 0.0, 1.0)
        return FlowSolution(float(self.problem.value), flows, elapsed, status)
