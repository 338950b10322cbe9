"""Non-collision modes: the finger moves around the resting slider through convex pieces of its free
space, written in the slider's frame (where they do not depend on the slider's pose, so the finger's
constraints stay linear however the slider is turned).

One piece per face: the half-plane beyond the face pushed out by the finger radius, cut by the same
half-plane of each neighbour that meets it at a concave corner. For a convex slider (and the T, whose
only concave corners are where the stem meets the bar) every part lies behind one of those lines, so a
segment inside a piece never touches the slider (tests/test_contact_graph.py samples this), and
neighbouring pieces overlap at the corner between them. A route is a chain of pieces.
"""

from __future__ import annotations

from dataclasses import dataclass

import cvxpy as cp
import numpy as np

from lerobot_gcs_push.contact.model import PushModel


@dataclass(frozen=True)
class Region:
    """{q : A q <= b}, in the slider's frame."""

    a: np.ndarray
    b: np.ndarray

    def contains(self, q, tol: float = 1e-9) -> bool:
        return bool(np.all(self.a @ np.asarray(q, float) <= self.b + tol))

    def project(self, q, margin: float = 0.0) -> np.ndarray:
        """The nearest point to `q` at least `margin` inside the piece. In the plane it is `q` itself, its
        projection onto one (shifted) boundary line, or a vertex where two meet: the nearest of those."""
        q = np.asarray(q, float)
        norms = np.linalg.norm(self.a, axis=1)
        b = self.b - margin * norms
        if np.all(self.a @ q <= b + 1e-12):
            return q.copy()
        candidates = [q - (a @ q - bi) / n**2 * a for a, bi, n in zip(self.a, b, norms)]
        for i in range(len(b)):
            for j in range(i + 1, len(b)):
                m = self.a[[i, j]]
                if abs(np.linalg.det(m)) > 1e-12:
                    candidates.append(np.linalg.solve(m, b[[i, j]]))
        inside = [c for c in candidates if np.all(self.a @ c <= b + 1e-9)]
        if not inside:
            raise ValueError(f"the piece has no point {margin} m inside it")
        return min(inside, key=lambda c: float(np.linalg.norm(c - q)))


def free_regions(model: PushModel) -> list[Region]:
    out = []
    bound, r = model.finger_reach, model.finger_radius
    faces = model.faces
    box_a = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]])
    for i, f in enumerate(faces):
        cuts = [f]
        if f.lam_lo > 0:
            cuts.append(faces[i - 1])
        if f.lam_hi < 1:
            cuts.append(faces[(i + 1) % len(faces)])
        a = np.vstack([-g.n[None, :] for g in cuts] + [box_a])
        b = np.concatenate([[-(g.offset + r) for g in cuts], np.full(4, bound)])
        out.append(Region(a, b))
    return out


def routes(n_faces: int, i: int, j: int) -> list[tuple[int, ...]]:
    """Chains of face regions from face i's to face j's: the same face, or either way round the slider
    when that way passes at most half the faces (the long way round an adjacent face never pays)."""
    if i == j:
        return [(i,)]
    out = []
    for step in (1, -1):
        chain = [i]
        while chain[-1] != j:
            chain.append((chain[-1] + step) % n_faces)
        if len(chain) - 1 <= n_faces // 2:
            out.append(tuple(chain))
    return out


def knots_of(route: tuple[int, ...], per_region: int) -> int:
    return len(route) * per_region + 1


def segment_region(route: tuple[int, ...], per_region: int, seg: int) -> int:
    return route[seg // per_region]


class RelaxedNonCollision:
    """A perspective copy of one non-collision mode: the slider's pose (carried, with its SO(2) moments
    [1, c, s] so that second moments flow from one contact mode to the next) and the finger's knots."""

    def __init__(self, model: PushModel, regions: list[Region], route, per_region: int, phi, arcs=()):
        self.route, self.per_region, self.phi = route, per_region, phi
        n = knots_of(route, per_region)
        self.q = cp.Variable((n, 2))
        self.pose = cp.Variable(4)  # x, y, c, s times phi
        self.moments = cp.Variable((3, 3), symmetric=True)
        cons = [
            self.moments >> 0,
            self.moments[0, 0] == phi,
            self.moments[1, 1] + self.moments[2, 2] == phi,
            self.moments[0, 1:] == self.pose[2:],
            cp.abs(self.pose[:2]) <= model.reach * phi,
        ]
        for arc in arcs:  # the chord cuts (ArcParameters) on the slider's heading, which stays put here
            cons.append(arc.of(self.pose[2:], phi) >= 0)
        for seg in range(n - 1):
            reg = regions[segment_region(route, per_region, seg)]
            for p in (self.q[seg], self.q[seg + 1]):
                cons.append(reg.a @ p <= reg.b * phi)
        self.constraints = cons
        self.cost = sum(cp.quad_over_lin(self.q[k + 1] - self.q[k], phi) for k in range(n - 1))

    def values(self, phi_value: float) -> dict:
        w = max(phi_value, 1e-9)
        return {"q": self.q.value / w, "pose": self.pose.value / w}


class NlpNonCollision:
    def __init__(self, prog, model: PushModel, regions: list[Region], route, per_region: int, tag: str):
        self.route, self.per_region = route, per_region
        n = knots_of(route, per_region)
        self.q = prog.NewContinuousVariables(n, 2, f"{tag}_q")
        for seg in range(n - 1):
            reg = regions[segment_region(route, per_region, seg)]
            for p in (self.q[seg], self.q[seg + 1]):
                prog.AddLinearConstraint(reg.a, np.full(len(reg.b), -np.inf), reg.b, p)
        d = self.q[1:] - self.q[:-1]
        self.cost = sum(d[k] @ d[k] for k in range(n - 1))
        prog.AddQuadraticCost(self.cost)

    def set_guess(self, prog, q) -> None:
        prog.SetInitialGuess(self.q, np.asarray(q, float))

    def read(self, result) -> np.ndarray:
        return result.GetSolution(self.q)
