"""The mode graph's vertices and edges as cvxpy constraints and costs, written once for every program.

Each function takes a scale y, as in the homogenised (perspective) formulation of GCS and as gcsopt
writes it: with y = 1 and x a vertex's point it states x in the vertex's set (the convex restriction
of a path, restriction.py); with y an edge's flow and x the edge's copy of the point (~ y x) the same
expression is the perspective, x in y X (the GCS program, gcs.py). The sets are polyhedra and the costs
a norm plus a linear term, all positively homogeneous, so scaling the constants by y is the whole
perspective.
"""

from __future__ import annotations

import cvxpy as cp

from lerobot_gcs_push.box_gcs.graph import Edge, Vertex


def in_set(vert: Vertex, x, y=1) -> list[cp.Constraint]:
    """A x <= c y. The source and target have no rows: their points are parameters."""
    return [vert.A @ x <= vert.c * y] if len(vert.c) else []


def pinned(vert: Vertex, x, theta, y=1) -> list[cp.Constraint]:
    """The coordinates that the query fixes: x[pin_cols] == y S theta."""
    return [x[list(vert.pin_cols)] == y * (vert.pin_S @ theta)] if vert.pin_cols else []


def vertex_constraints(vert: Vertex, x, theta, y=1) -> list[cp.Constraint]:
    return in_set(vert, x, y) + pinned(vert, x, theta, y)


def vertex_costs(vert: Vertex, x, y=1) -> list[cp.Expression]:
    """||D x||_2 and g . x + k y, those that the vertex has."""
    terms = []
    if vert.D is not None:
        terms.append(cp.norm(vert.D @ x, 2))
    if vert.g is not None:
        terms.append(vert.g @ x + vert.k * y)
    return terms


def edge_constraint(edge: Edge, xu, xv, y=1) -> cp.Constraint:
    """Mu x_u + Mv x_v == h y."""
    return edge.Mu @ xu + edge.Mv @ xv == edge.h * y
