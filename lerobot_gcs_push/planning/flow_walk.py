"""The one rounding walk: from the edge flows of a relaxed shortest-path program to a source-target path.

Both planners round with it: the box's mode graph (`box_gcs/rounding.py`) and the layered graph through
contact (`contact/rounding.py`). A graph is given to it by `out(vertex)`: the vertex's out-edges as
(edge, head, flow) in a fixed order, so neither graph's types leak in here.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable, Iterator, Sequence

import numpy as np

OutEdges = Callable[[Hashable], Sequence[tuple[Hashable, Hashable, float]]]


def walk(
    out: OutEdges, source: Hashable, target: Hashable, rng: np.random.Generator | None = None, min_flow: float = 0.0
) -> tuple | None:
    """The edges of one path from `source` to `target` through edges of flow > `min_flow`, or None.

    With `rng` None the walk is greedy (the largest flow out of each vertex, the first of equals); with a
    generator each next edge is drawn with probability proportional to its flow. A vertex whose edges all
    lead to visited vertices or dead ends is backed out of, and the next choice taken (in drawn order)."""
    if source == target:
        return ()
    stack = [(source, _choices(out(source), rng, min_flow))]
    visited = {source}
    edges: list = []
    while stack:
        v, options = stack[-1]
        nxt = next((o for o in options if o[1] not in visited), None)
        if nxt is None:  # dead end: back up
            stack.pop()
            visited.discard(v)
            if edges:
                edges.pop()
            continue
        edge, head, _ = nxt
        edges.append(edge)
        if head == target:  # never asked for its out-edges
            return tuple(edges)
        visited.add(head)
        stack.append((head, _choices(out(head), rng, min_flow)))
    return None


def _choices(options, rng, min_flow) -> Iterator[tuple]:
    """The out-edges with flow, greedily ordered, or drawn one at a time without replacement (lazily: a walk
    that never backs up draws once per vertex, `rng.choice` over the flows, even where one edge is left)."""
    opts = [o for o in options if o[2] > min_flow]
    if rng is None:
        yield from sorted(opts, key=lambda o: -o[2])
        return
    while opts:
        w = np.array([o[2] for o in opts], float)
        yield opts.pop(int(rng.choice(len(opts), p=w / w.sum())))
