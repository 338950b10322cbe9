"""The finger-box mode graph, as plain numpy data.

One description serves three solvers: the cvxpy GCS program (`gcs.py`), the brute-force oracle that
solves the convex restriction of every path (`restriction.py`), and Drake's `GraphOfConvexSets`
(`drake_oracle.py`). Nothing here knows about a solver.

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

import numpy as np

from lerobot_gcs_push.scene import Scene

FACES = ("L", "R", "T", "B")
# Push direction when the finger is on that face (it pushes the box away from itself).
NORMALS = {"L": np.array([1.0, 0.0]), "R": np.array([-1.0, 0.0]),
           "T": np.array([0.0, -1.0]), "B": np.array([0.0, 1.0])}
AXIS = {"L": 0, "R": 0, "T": 1, "B": 1}
ADJACENT = {"L": ("T", "B"), "R": ("T", "B"), "T": ("L", "R"), "B": ("L", "R")}

# Variable layouts.
FREE_DIM = 6  # box (2), finger start (2), finger end (2)
PUSH_DIM = 4  # box before (2), box after (2)
SOURCE_DIM = 4  # box, finger (fixed by parameters)
TARGET_DIM = 2  # box (fixed to the goal)
THETA_DIM = 6  # the query: initial box, initial finger, goal


def _theta_rows(*cols: int) -> np.ndarray:
    """Selection of theta entries: e.g. (4, 1) is the box after an x-push, (goal x, initial box y)."""
    return _sel(THETA_DIM, cols)


BOX0, GOAL = (0, 1), (4, 5)
AFTER_X, AFTER_Y = (4, 1), (0, 5)  # box after pushing along x first, along y first


@dataclass
class Vertex:
    name: str
    kind: str  # "source", "free", "push", "target"
    dim: int
    A: np.ndarray = field(repr=False)  # set: A x <= c
    c: np.ndarray = field(repr=False)
    face: str | None = None
    # Cost: ||D x||_2 + g . x + k (k counts once per visit).
    D: np.ndarray | None = field(default=None, repr=False)
    g: np.ndarray | None = field(default=None, repr=False)
    k: float = 0.0
    # Pinned coordinates: x[pin_cols] == pin_S @ theta, theta = [box0 (2), finger0 (2), goal (2)].
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


def _box_rows(dim: int, cols: list[int], limit: float) -> tuple[np.ndarray, np.ndarray]:
    """Rows of |x_col| <= limit for the given columns."""
    A = []
    for col in cols:
        for s in (1.0, -1.0):
            row = np.zeros(dim)
            row[col] = s
            A.append(row)
    return np.array(A), np.full(len(A), limit)


def _free_vertex(scene: Scene, name: str, face: str, buffered_start: bool) -> Vertex:
    n = NORMALS[face]
    d, da = scene.contact_distance, scene.approach_distance
    rows, rhs = [], []
    # n . (p - b) <= -d (or -(d + t)), n . (q - b) <= -(d + t): finger on this face's side of the box.
    for point_cols, dist in (((2, 3), da if buffered_start else d), ((4, 5), da)):
        row = np.zeros(FREE_DIM)
        row[list(point_cols)] = n
        row[[0, 1]] = -n
        rows.append(row)
        rhs.append(-dist)
    Ab, cb = _box_rows(FREE_DIM, [0, 1], scene.box_reach)
    Af, cf = _box_rows(FREE_DIM, [2, 3, 4, 5], scene.finger_limit)
    A = np.vstack([np.array(rows), Ab, Af])
    c = np.concatenate([rhs, cb, cf])
    D = np.zeros((2, FREE_DIM))
    D[:, 2:4] = -np.eye(2)
    D[:, 4:6] = np.eye(2)
    return Vertex(name, "free", FREE_DIM, A, c, face=face, D=D)


def _push_vertex(scene: Scene, name: str, face: str) -> Vertex:
    n = NORMALS[face]
    axis = AXIS[face]
    other = 1 - axis
    rows, rhs = [], []
    # Motion along the normal only: the tangential coordinate is unchanged (two inequalities)...
    for s in (1.0, -1.0):
        row = np.zeros(PUSH_DIM)
        row[other], row[2 + other] = -s, s
        rows.append(row)
        rhs.append(0.0)
    # ...and the box moves away from the finger: n . (c - a) >= 0.
    row = np.zeros(PUSH_DIM)
    row[0:2], row[2:4] = n, -n
    rows.append(row)
    rhs.append(0.0)
    Ab, cb = _box_rows(PUSH_DIM, [0, 1, 2, 3], scene.box_reach)
    A = np.vstack([np.array(rows), Ab])
    c = np.concatenate([rhs, cb])
    g = np.concatenate([-n, n])  # n . (c - a): the push length
    return Vertex(name, "push", PUSH_DIM, A, c, face=face, g=g, k=2 * scene.transition_buffer)


def _point_vertex(name: str, kind: str, dim: int) -> Vertex:
    # The point itself is a parameter, supplied by each solver.
    return Vertex(name, kind, dim, np.zeros((0, dim)), np.zeros(0))


def _sel(dim: int, cols) -> np.ndarray:
    M = np.zeros((len(cols), dim))
    M[np.arange(len(cols)), list(cols)] = 1.0
    return M


class _Builder:
    def __init__(self, scene: Scene):
        self.scene = scene
        self.vertices: list[Vertex] = []
        self.edges: list[Edge] = []

    def add(self, v: Vertex) -> int:
        self.vertices.append(v)
        return len(self.vertices) - 1

    def connect(self, u: int, v: int, pairs, needs=None) -> None:
        """`pairs`: (cols of u, cols of v, offset): x_u[cols_u] - x_v[cols_v] == offset."""
        du, dv = self.vertices[u].dim, self.vertices[v].dim
        Mu = np.vstack([_sel(du, cu) for cu, _, _ in pairs])
        Mv = np.vstack([-_sel(dv, cv) for _, cv, _ in pairs])
        h = np.concatenate([np.broadcast_to(np.asarray(off, float), (len(cu),)) for cu, _, off in pairs])
        self.edges.append(Edge(u, v, Mu, Mv, h, needs))

    def pin(self, v: int, cols: tuple[int, ...], theta_cols: tuple[int, ...]) -> None:
        vert = self.vertices[v]
        vert.pin_cols = vert.pin_cols + tuple(cols)
        S = _theta_rows(*theta_cols)
        vert.pin_S = S if vert.pin_S is None else np.vstack([vert.pin_S, S])

    def free_layer(self, tag: str, buffered_start: bool, box=None) -> dict[str, int]:
        layer = {f: self.add(_free_vertex(self.scene, f"{tag}:free:{f}", f, buffered_start)) for f in FACES}
        if box is not None:
            for v in layer.values():
                self.pin(v, (0, 1), box)
        for f in FACES:
            for g in ADJACENT[f]:
                # Same box; the finger's segment end in f is its start in g.
                self.connect(layer[f], layer[g], [((0, 1), (0, 1), 0.0), ((4, 5), (2, 3), 0.0)])
        return layer

    def push(self, tag: str, face: str, before: int, box=None) -> int:
        """A push on `face` entered from free vertex `before`: its segment ends at the approach point.
        `box`: theta columns of the box before and after the push, when the query determines them."""
        p = self.add(_push_vertex(self.scene, f"{tag}:push:{face}", face))
        if box is not None:
            self.pin(p, (0, 1, 2, 3), box[0] + box[1])
        approach = -self.scene.approach_distance * NORMALS[face]
        axis = AXIS[face]
        # free.b == push.a, free.q - push.a == approach offset
        self.connect(before, p, [((0, 1), (0, 1), 0.0), ((4, 5), (0, 1), approach)],
                     needs=(axis, int(NORMALS[face][axis])))
        return p

    def leave(self, push: int, after: int) -> None:
        """Leave a push into free vertex `after`: the finger starts at the retreat point."""
        face = self.vertices[push].face
        retreat = -self.scene.approach_distance * NORMALS[face]
        # push.c == free.b, push.c - free.p == -retreat offset
        self.connect(push, after, [((2, 3), (0, 1), 0.0), ((2, 3), (2, 3), -retreat)])

    def finish(self, push: int) -> None:
        self.connect(push, self.target, [((2, 3), (0, 1), 0.0)])

    def start(self, free: int) -> None:
        self.connect(self.source, free, [((0, 1), (0, 1), 0.0), ((2, 3), (2, 3), 0.0)])

    def begin(self) -> None:
        self.source = self.add(_point_vertex("source", "source", SOURCE_DIM))
        self.target = self.add(_point_vertex("target", "target", TARGET_DIM))

    def graph(self) -> "ModeGraph":
        return ModeGraph(self.scene, self.vertices, self.edges, self.source, self.target)


def build_graph(scene: Scene, structure: str = "branches", num_pushes: int = 2) -> ModeGraph:
    """The mode graph. `branches` (default): x-then-y and y-then-x pushes. `layers`: `num_pushes`
    identical layers with any face per push (the general graph, for tests)."""
    b = _Builder(scene)
    b.begin()
    first = b.free_layer("0", buffered_start=False, box=BOX0)
    for f in FACES:
        b.start(first[f])
    if structure == "branches":
        for tag, faces0, faces1, mid in (("x", ("L", "R"), ("T", "B"), AFTER_X),
                                         ("y", ("T", "B"), ("L", "R"), AFTER_Y)):
            middle = b.free_layer(f"{tag}1", buffered_start=True, box=mid)
            for f in faces0:
                p0 = b.push(f"{tag}0", f, first[f], box=(BOX0, mid))
                b.finish(p0)
                b.leave(p0, middle[f])
            for f in faces1:
                b.finish(b.push(f"{tag}1", f, middle[f], box=(mid, GOAL)))
    elif structure == "layers":
        if num_pushes < 1:
            raise ValueError(f"num_pushes must be >= 1, got {num_pushes}")
        layer = first
        for k in range(num_pushes):
            nxt = b.free_layer(str(k + 1), buffered_start=True) if k + 1 < num_pushes else None
            for f in FACES:
                p = b.push(str(k), f, layer[f])
                b.finish(p)
                if nxt is not None:
                    b.leave(p, nxt[f])
            layer = nxt
    else:
        raise ValueError(f"unknown graph structure {structure!r}: choose 'branches' or 'layers'")
    return b.graph()
