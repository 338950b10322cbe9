"""Randomised depth-first rounding of relaxed GCS flows into candidate paths."""

from __future__ import annotations

import numpy as np

from lerobot_gcs_push.planner.graph import ModeGraph


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
    for trial in range(trials):
        path = _walk(graph, outs, flows, rng if trial else None, min_flow)
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


def _walk(graph, outs, flows, rng, min_flow) -> tuple[int, ...] | None:
    stack = [(graph.source, _ranked(outs[graph.source], flows, rng, min_flow))]
    visited = {graph.source}
    edges: list[int] = []
    while stack:
        v, options = stack[-1]
        if v == graph.target:
            return tuple(edges)
        nxt = None
        while options:
            e = options.pop(0)
            if graph.edges[e].v not in visited:
                nxt = e
                break
        if nxt is None:  # dead end: backtrack
            stack.pop()
            visited.discard(v)
            if edges:
                edges.pop()
            continue
        w = graph.edges[nxt].v
        visited.add(w)
        edges.append(nxt)
        stack.append((w, _ranked(outs[w], flows, rng, min_flow)))
    return None


def _ranked(options, flows, rng, min_flow) -> list[int]:
    """Out-edges with flow, ordered greedily (rng None) or by weighted sampling without replacement."""
    opts = [e for e in options if flows[e] > min_flow]
    if rng is None or len(opts) < 2:
        return sorted(opts, key=lambda e: -flows[e])
    w = np.array([flows[e] for e in opts])
    keys = rng.random(len(opts)) ** (1.0 / w)  # Efraimidis-Spirakis weighted order
    return [opts[i] for i in np.argsort(-keys)]
