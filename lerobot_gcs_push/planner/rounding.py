"""Randomised depth-first rounding of relaxed GCS flows into candidate paths."""

from __future__ import annotations

import numpy as np

from lerobot_gcs_push.planner.graph import ModeGraph


def candidate_paths(
    graph: ModeGraph, flows: np.ndarray, rng: np.random.Generator, trials: int, min_flow: float = 1e-4
) -> list[tuple[int, ...]]:
    """Distinct source-target paths (edge tuples): the greedy one first, then random walks that pick
    each out-edge with probability proportional to its flow, backtracking at dead ends."""
    outs = {v: graph.out_edges(v) for v in range(len(graph.vertices))}
    found: list[tuple[int, ...]] = []
    for trial in range(trials):
        path = _walk(graph, outs, flows, rng if trial else None, min_flow)
        if path is not None and path not in found:
            found.append(path)
    return found


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
