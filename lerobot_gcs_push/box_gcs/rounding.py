"""Candidate paths from relaxed GCS flows: the flow walk (`flow_walk.walk`) and a flow decomposition."""

from __future__ import annotations

import numpy as np

from lerobot_gcs_push.box_gcs.graph import ModeGraph
from lerobot_gcs_push.planning.flow_walk import walk


def candidate_paths(
    graph: ModeGraph,
    flows: np.ndarray,
    rng: np.random.Generator,
    trials: int,
    min_flow: float = 1e-4,
    decomposed: int = 2,
) -> list[tuple[int, ...]]:
    """Distinct source-target paths (edge tuples): the greedy one first, then random walks that pick
    each out-edge with probability proportional to its flow, backtracking at dead ends, then the first
    `decomposed` paths of a flow decomposition. Walks can all miss a branch that carries nearly half the
    flow (a box with two equally good first pushes: 0.56 / 0.44 on one hard initial condition left the
    optimum out of 8 walks); the decomposition takes the widest branches in turn, so none is missed."""
    outs = {v: graph.out_edges(v) for v in range(len(graph.vertices))}
    found: list[tuple[int, ...]] = []

    def out(v):
        return [(e, graph.edges[e].v, flows[e]) for e in outs[v]]

    for trial in range(trials):
        path = walk(out, graph.source, graph.target, rng if trial else None, min_flow)
        if path is not None and path not in found:
            found.append(path)
    remaining = np.array(flows, float)
    for _ in range(decomposed):
        path = _widest_path(graph, outs, remaining, min_flow)
        if path is None:
            break
        remaining[list(path)] -= min(remaining[e] for e in path)
        if path not in found:
            found.append(path)
    return found


def _widest_path(graph, outs, flows, min_flow) -> tuple[int, ...] | None:
    """The source-target path whose smallest flow is largest (a max-bottleneck Dijkstra)."""
    import heapq

    best = {graph.source: np.inf}
    via: dict[int, int] = {}
    heap = [(-np.inf, graph.source)]
    done = set()
    while heap:
        width, v = heapq.heappop(heap)
        if v in done:
            continue
        done.add(v)
        if v == graph.target:
            break
        for e in outs[v]:
            w = graph.edges[e].v
            cap = min(-width, flows[e])
            if flows[e] > min_flow and w not in done and cap > best.get(w, 0.0):
                best[w], via[w] = cap, e
                heapq.heappush(heap, (-cap, w))
    if graph.target not in done:
        return None
    edges, v = [], graph.target
    while v != graph.source:
        edges.append(via[v])
        v = graph.edges[via[v]].u
    return tuple(reversed(edges))
