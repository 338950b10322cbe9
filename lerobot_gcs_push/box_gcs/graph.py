"""The finger-box mode graph, as plain numpy data.

One description serves every solver: the cvxpy GCS program (`gcs.py`) and the convex restriction of a
path (`restriction.py`), both through `transcription.py`, and the oracles in the tests (Drake's
`GraphOfConvexSets`, gcsopt). Nothing here knows about a solver.

Geometry (relative position r = finger - box, contact distance d = box half-size + finger radius,
buffer t = the paper's transition buffer):

* Free regions, one per box face: L = {r_x <= -d}, R = {r_x >= d}, T = {r_y >= d}, B = {r_y <= -d}.
  Their union is the space where the finger cannot touch the box (the four corner squares, where two
  regions overlap, are where the finger rounds a corner). Inside a free vertex the box is still and the
  finger moves on a straight segment, so convexity of the region keeps the whole segment collision free.
  Segments end in the buffered region (|r| >= d + t on that side), so the finger never grazes a face
  while it moves around the box; only the first segment may start inside the buffer (the initial state).
* Push vertices, one per face: the finger comes in from the approach point at distance d + t along the
  face normal, touches the face centre, pushes the box along the normal (sticking contact at the face
  centre, box sliding on the ground), and backs out to the approach point. Contact only ever happens at
  a face centre and only along the normal, so no torque is applied. The paper's sliding contact modes
  (finger sliding along a face) are empty under the face-centre constraint and are pruned.
  The push's finger path length is |c - a| + 2t, a linear cost.
* Layers: an axis-aligned box that cannot rotate reaches any goal with at most one push per axis, so
  the graph has two branches: x-push then y-push, and y-push then x-push, each with its own copy of the
  free regions between the pushes (so that box positions from different branches never mix in the
  relaxation). Every push vertex can end the plan. Within a free layer the finger may pass through
  several regions; across layers it may revisit a region (leave the right face, round a corner, push
  from the top). `structure="layers"` instead builds K identical layers with any face per push: the
  general graph, used by the tests to show that the branch graph loses nothing.
* Edge pruning: a push along +x is useless when the goal lies at -x. Each push edge carries the
  (axis, sign) it needs; solvers disable edges whose sign disagrees with the goal offset.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum

import numpy as np

from lerobot_gcs_push.scene import Scene

X, Y = 0, 1  # the coordinates of a planar position


class Face(StrEnum):
    """A side of the box. A finger on it pushes the box away from itself, along `normal`."""

    L = "L"
    R = "R"
    T = "T"
    B = "B"

    @property
    def normal(self) -> np.ndarray:
        return _NORMALS[self]

    @property
    def axis(self) -> int:
        return X if self in (Face.L, Face.R) else Y

    @property
    def adjacent(self) -> tuple[Face, Face]:
        """The faces whose free regions overlap this one's (at a corner of the box)."""
        return (Face.T, Face.B) if self.axis == 0 else (Face.L, Face.R)


_NORMALS = {
    Face.L: np.array([1.0, 0.0]),
    Face.R: np.array([-1.0, 0.0]),
    Face.T: np.array([0.0, -1.0]),
    Face.B: np.array([0.0, 1.0]),
}


class VertexKind(StrEnum):
    SOURCE = "source"
    FREE = "free"
    PUSH = "push"
    TARGET = "target"


# Point layouts: every vertex's point is a stack of planar positions (x, y); each class names them.
def _at(i: int) -> slice:
    return slice(2 * i, 2 * i + 2)


class SourcePoint:
    BOX, FINGER = _at(0), _at(1)
    DIM = 4


class TargetPoint:
    BOX = _at(0)
    DIM = 2


class FreePoint:
    """The box (still) and the finger's straight segment from START to END."""

    BOX, START, END = _at(0), _at(1), _at(2)
    DIM = 6


class PushPoint:
    """The box before and after the push."""

    BEFORE, AFTER = _at(0), _at(1)
    DIM = 4


class Theta:
    """The query, theta = [source point, target point], which pinned coordinates read."""

    BOX0, FINGER0, GOAL = _at(0), _at(1), _at(2)
    DIM = 6


def _known_box(x_from: slice, y_from: slice) -> tuple[int, int]:
    """Theta entries of a box position whose x is that of `x_from` and whose y is that of `y_from`."""
    return x_from.start + X, y_from.start + Y


BOX_START = _known_box(Theta.BOX0, Theta.BOX0)
BOX_GOAL = _known_box(Theta.GOAL, Theta.GOAL)
BOX_AFTER_X = _known_box(Theta.GOAL, Theta.BOX0)  # pushed along x first: x at the goal, y not yet
BOX_AFTER_Y = _known_box(Theta.BOX0, Theta.GOAL)


@dataclass
class Vertex:
    name: str
    kind: VertexKind
    dim: int
    A: np.ndarray = field(repr=False)  # set: A x <= c
    c: np.ndarray = field(repr=False)
    face: Face | None = None
    # Cost: ||D x||_2 + g . x + k (k counts once per visit).
    D: np.ndarray | None = field(default=None, repr=False)
    g: np.ndarray | None = field(default=None, repr=False)
    k: float = 0.0
    # Pinned coordinates: x[pin_cols] == pin_S @ theta (layout `Theta`).
    # In the branch graph every box position is known from the query (one push per axis), so pinning
    # it is exact; without it the relaxation averages box positions that belong to different pushes.
    pin_cols: tuple[int, ...] = ()
    pin_S: np.ndarray | None = field(default=None, repr=False)


@dataclass
class Edge:
    u: int
    v: int
    Mu: np.ndarray = field(repr=False)  # Mu x_u + Mv x_v == h
    Mv: np.ndarray = field(repr=False)
    h: np.ndarray = field(repr=False)
    needs: tuple[int, int] | None = None  # (axis, sign) this edge's push requires, for pruning


@dataclass
class ModeGraph:
    scene: Scene
    vertices: list[Vertex]
    edges: list[Edge]
    source: int
    target: int

    def out_edges(self, v: int) -> list[int]:
        return [i for i, e in enumerate(self.edges) if e.u == v]

    def in_edges(self, v: int) -> list[int]:
        return [i for i, e in enumerate(self.edges) if e.v == v]

    def edge_allowed(self, delta: np.ndarray, tol: float) -> np.ndarray:
        """1.0 for edges whose push direction agrees with the goal offset `delta`, else 0.0."""
        allowed = np.ones(len(self.edges))
        for i, e in enumerate(self.edges):
            if e.needs is not None:
                axis, sign = e.needs
                allowed[i] = float(sign * delta[axis] > tol)
        return allowed

    def simple_paths(self) -> list[list[int]]:
        """Every simple source-target path, as edge lists (the brute-force oracle's search space)."""
        paths: list[list[int]] = []
        outs = {v: self.out_edges(v) for v in range(len(self.vertices))}

        def walk(v: int, visited: set[int], edges: list[int]) -> None:
            if v == self.target:
                paths.append(list(edges))
                return
            for ei in outs[v]:
                w = self.edges[ei].v
                if w not in visited:
                    visited.add(w)
                    edges.append(ei)
                    walk(w, visited, edges)
                    edges.pop()
                    visited.remove(w)

        walk(self.source, {self.source}, [])
        return paths


def _box_rows(dim: int, blocks: list[slice], limit: float) -> tuple[np.ndarray, np.ndarray]:
    """Rows of |x_i| <= limit for every coordinate i of the given positions."""
    A = []
    for block in blocks:
        for col in range(block.start, block.stop):
            for s in (1.0, -1.0):
                row = np.zeros(dim)
                row[col] = s
                A.append(row)
    return np.array(A), np.full(len(A), limit)


def _free_vertex(scene: Scene, name: str, face: Face, buffered_start: bool) -> Vertex:
    P = FreePoint
    n = face.normal
    d, da = scene.contact_distance, scene.approach_distance
    rows, rhs = [], []
    # n . (p - b) <= -d (or -(d + t)), n . (q - b) <= -(d + t): finger on this face's side of the box.
    for finger, dist in ((P.START, da if buffered_start else d), (P.END, da)):
        row = np.zeros(P.DIM)
        row[finger] = n
        row[P.BOX] = -n
        rows.append(row)
        rhs.append(-dist)
    Ab, cb = _box_rows(P.DIM, [P.BOX], scene.box_reach)
    Af, cf = _box_rows(P.DIM, [P.START, P.END], scene.finger_limit)
    A = np.vstack([np.array(rows), Ab, Af])
    c = np.concatenate([rhs, cb, cf])
    D = np.zeros((2, P.DIM))  # D x = end - start: the segment's length is the cost
    D[:, P.START] = -np.eye(2)
    D[:, P.END] = np.eye(2)
    return Vertex(name, VertexKind.FREE, P.DIM, A, c, face=face, D=D)


def _push_vertex(scene: Scene, name: str, face: Face) -> Vertex:
    P = PushPoint
    n = face.normal
    rows, rhs = [], []
    # Motion along the normal only: the tangential coordinate is unchanged (two inequalities)...
    tangential = 1 - face.axis
    for s in (1.0, -1.0):
        row = np.zeros(P.DIM)
        row[P.BEFORE][tangential], row[P.AFTER][tangential] = -s, s
        rows.append(row)
        rhs.append(0.0)
    # ...and the box moves away from the finger: n . (c - a) >= 0.
    row = np.zeros(P.DIM)
    row[P.BEFORE], row[P.AFTER] = n, -n
    rows.append(row)
    rhs.append(0.0)
    Ab, cb = _box_rows(P.DIM, [P.BEFORE, P.AFTER], scene.box_reach)
    A = np.vstack([np.array(rows), Ab])
    c = np.concatenate([rhs, cb])
    g = np.zeros(P.DIM)  # g . x = n . (c - a): the push length
    g[P.BEFORE], g[P.AFTER] = -n, n
    return Vertex(name, VertexKind.PUSH, P.DIM, A, c, face=face, g=g, k=2 * scene.transition_buffer)


def _point_vertex(name: str, kind: VertexKind, dim: int) -> Vertex:
    # The point itself is a parameter, supplied by each solver.
    return Vertex(name, kind, dim, np.zeros((0, dim)), np.zeros(0))


class _Builder:
    def __init__(self, scene: Scene):
        self.scene = scene
        self.vertices: list[Vertex] = []
        self.edges: list[Edge] = []

    def add(self, v: Vertex) -> int:
        self.vertices.append(v)
        return len(self.vertices) - 1

    def connect(self, u: int, v: int, pairs: list[tuple[slice, slice, object]], needs=None) -> None:
        """`pairs`: (position in u, position in v, offset): x_u[pos_u] - x_v[pos_v] == offset."""
        Iu, Iv = np.eye(self.vertices[u].dim), np.eye(self.vertices[v].dim)
        Mu = np.vstack([Iu[pu] for pu, _, _ in pairs])
        Mv = np.vstack([-Iv[pv] for _, pv, _ in pairs])
        h = np.concatenate([np.broadcast_to(np.asarray(off, float), (2,)) for _, _, off in pairs])
        self.edges.append(Edge(u, v, Mu, Mv, h, needs))

    def pin(self, v: int, position: slice, known: tuple[int, int]) -> None:
        """Pin a position of vertex v to the theta entries `known`."""
        vert = self.vertices[v]
        vert.pin_cols = vert.pin_cols + tuple(range(position.start, position.stop))
        S = np.eye(Theta.DIM)[list(known)]
        vert.pin_S = S if vert.pin_S is None else np.vstack([vert.pin_S, S])

    def free_layer(self, tag: str, buffered_start: bool, box=None) -> dict[Face, int]:
        layer = {f: self.add(_free_vertex(self.scene, f"{tag}:free:{f}", f, buffered_start)) for f in Face}
        if box is not None:
            for v in layer.values():
                self.pin(v, FreePoint.BOX, box)
        for f in Face:
            for g in f.adjacent:
                # Same box; the finger's segment end in f is its start in g.
                self.connect(
                    layer[f], layer[g], [(FreePoint.BOX, FreePoint.BOX, 0.0), (FreePoint.END, FreePoint.START, 0.0)]
                )
        return layer

    def push(self, tag: str, face: Face, before: int, box=None) -> int:
        """A push on `face` entered from free vertex `before`: its segment ends at the approach point.
        `box`: theta entries of the box before and after the push, when the query determines them."""
        p = self.add(_push_vertex(self.scene, f"{tag}:push:{face}", face))
        if box is not None:
            self.pin(p, PushPoint.BEFORE, box[0])
            self.pin(p, PushPoint.AFTER, box[1])
        approach = -self.scene.approach_distance * face.normal
        # free.box == push.before, free.end - push.before == approach offset
        self.connect(
            before,
            p,
            [(FreePoint.BOX, PushPoint.BEFORE, 0.0), (FreePoint.END, PushPoint.BEFORE, approach)],
            needs=(face.axis, int(face.normal[face.axis])),
        )
        return p

    def leave(self, push: int, after: int) -> None:
        """Leave a push into free vertex `after`: the finger starts at the retreat point."""
        retreat = -self.scene.approach_distance * self.vertices[push].face.normal
        # push.after == free.box, push.after - free.start == -retreat offset
        self.connect(push, after, [(PushPoint.AFTER, FreePoint.BOX, 0.0), (PushPoint.AFTER, FreePoint.START, -retreat)])

    def finish(self, push: int) -> None:
        self.connect(push, self.target, [(PushPoint.AFTER, TargetPoint.BOX, 0.0)])

    def start(self, free: int) -> None:
        self.connect(
            self.source, free, [(SourcePoint.BOX, FreePoint.BOX, 0.0), (SourcePoint.FINGER, FreePoint.START, 0.0)]
        )

    def begin(self) -> None:
        self.source = self.add(_point_vertex("source", VertexKind.SOURCE, SourcePoint.DIM))
        self.target = self.add(_point_vertex("target", VertexKind.TARGET, TargetPoint.DIM))

    def graph(self) -> ModeGraph:
        return ModeGraph(self.scene, self.vertices, self.edges, self.source, self.target)


def build_graph(scene: Scene, structure: str = "branches", num_pushes: int = 2) -> ModeGraph:
    """The mode graph. `branches` (default): x-then-y and y-then-x pushes. `layers`: `num_pushes`
    identical layers with any face per push (the general graph, for tests)."""
    b = _Builder(scene)
    b.begin()
    first = b.free_layer("0", buffered_start=False, box=BOX_START)
    for f in Face:
        b.start(first[f])
    if structure == "branches":
        for tag, faces0, faces1, mid in (
            ("x", (Face.L, Face.R), (Face.T, Face.B), BOX_AFTER_X),
            ("y", (Face.T, Face.B), (Face.L, Face.R), BOX_AFTER_Y),
        ):
            middle = b.free_layer(f"{tag}1", buffered_start=True, box=mid)
            for f in faces0:
                p0 = b.push(f"{tag}0", f, first[f], box=(BOX_START, mid))
                b.finish(p0)
                b.leave(p0, middle[f])
            for f in faces1:
                b.finish(b.push(f"{tag}1", f, middle[f], box=(mid, BOX_GOAL)))
    elif structure == "layers":
        if num_pushes < 1:
            raise ValueError(f"num_pushes must be >= 1, got {num_pushes}")
        layer = first
        for k in range(num_pushes):
            nxt = b.free_layer(str(k + 1), buffered_start=True) if k + 1 < num_pushes else None
            for f in Face:
                p = b.push(str(k), f, layer[f])
                b.finish(p)
                if nxt is not None:
                    b.leave(p, nxt[f])
            layer = nxt
    else:
        raise ValueError(f"unknown graph structure {structure!r}: choose 'branches' or 'layers'")
    return b.graph()
