"""The graph's convex relaxation: one perspective copy per vertex, flow conservation, and conservation
of each interface (pose, its SO(2) second moments, the finger) across the edges.

Written once with cvxpy Parameters (start pose, start finger, goal pose, which free-space pieces hold
the start finger, each knot's arc of headings) and compiled to conic data on the planner's shared core
(the `conic` package), cached on disk: a query evaluates the data at its parameters and calls Clarabel.
The T's compile takes a minute or more; a fresh process (a CLI plan, a worker) reads it in 20 ms, after
the 2-3 s cvxpy spends building the program's expressions (whose variables receive each solution).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import cvxpy as cp
import numpy as np

from lerobot_gcs_push.conic import ParametricConic, cached
from lerobot_gcs_push.conic.certificate import solve_certified
from lerobot_gcs_push.conic.solve import STATUS
from lerobot_gcs_push.contact.face_contact import (
    MAX_STEP_ROTATION,
    ArcParameters,
    RelaxedFaceContact,
    step_forms,
)
from lerobot_gcs_push.contact.graph import ContactGraph
from lerobot_gcs_push.contact.model import PushModel, reachable_windows
from lerobot_gcs_push.contact.non_collision import RelaxedNonCollision, free_regions

# The modules that write the program (the planner's rounding and expert do not change it).
PROGRAM_SOURCES = [
    str(Path(__file__).with_name(f"{m}.py")) for m in ("relaxation", "face_contact", "non_collision", "model", "graph")
]


def pose_vector(pose) -> np.ndarray:
    x, y, th = (float(v) for v in pose)
    return np.array([x, y, np.cos(th), np.sin(th)])


def pose_moments(pose) -> np.ndarray:
    v = np.concatenate([[1.0], pose_vector(pose)[2:]])
    return np.outer(v, v)


@dataclass
class RelaxationResult:
    bound: float | None  # a certified lower bound on every plan's cost (`conic.certificate`), None: uncertified
    status: str
    solve_time_s: float
    contact_flow: np.ndarray
    free_flow: np.ndarray
    target_flow: np.ndarray
    relaxation: GraphRelaxation
    dual_residual: float = float("nan")  # |A'z + c|_inf / max(1, |c|_inf) at the projected dual point

    @property
    def certified(self) -> bool:
        return self.bound is not None

    def contact_guess(self, c: int, via: int | None = None) -> dict:
        """The contact vertex's values; for an edge-copied vertex, those of the copy entered from `via`."""
        copy = self.relaxation.copies.get(via)
        if copy is not None and self.relaxation.graph.successor(via) == c:
            return copy.values(self.free_flow[via])
        return self.relaxation.contacts[c].values(self.contact_flow[c])

    def free_guess(self, f: int) -> dict:
        return self.relaxation.frees[f].values(self.free_flow[f])


class GraphRelaxation:
    def __init__(
        self,
        model: PushModel,
        graph: ContactGraph,
        knots: int,
        per_region: int,
        rot_weight: float,
        rlt: bool = True,
        window: bool = True,
        edge_copies: bool = False,
        max_step: float = MAX_STEP_ROTATION,
        knot_windows: bool = True,
    ):
        self.model, self.graph, self.knots, self.max_step = model, graph, knots, max_step
        self.regions = free_regions(model)
        self.start = cp.Parameter(4)
        self.start_moments = cp.Parameter((3, 3))
        self.start_q = cp.Parameter(2)
        self.allow = cp.Parameter(len(self.regions), nonneg=True)
        self.goal = cp.Parameter(4)
        self.goal_moments = cp.Parameter((3, 3))
        self.arc = ArcParameters() if window else None
        # Knot j of a plan (counted over the layers) is at most j steps from the start heading and
        # layers x (knots - 1) - j from the goal's; a plan ending early ends at the goal, inside every later
        # knot's arc too. So each knot has its arc of headings, valid for every plan (no restriction).
        steps = graph.layers * (knots - 1)
        self.knot_arcs = [ArcParameters() for _ in range(steps + 1)] if knot_windows else []
        self.phi_c = cp.Variable(len(graph.contacts), nonneg=True)
        self.phi_f = cp.Variable(len(graph.frees), nonneg=True)
        self.phi_t = cp.Variable(len(graph.contacts), nonneg=True)
        forms = contact_forms(model, graph, rot_weight, rlt, max_step)
        # edge_copies: a last-layer contact vertex gets one copy per entering free vertex (the standard
        # GCS edge copy) instead of one aggregate, so flows entering from different poses cannot trade
        # their trajectories inside it.
        copied = {c for c in range(len(graph.contacts)) if edge_copies and graph.into(c) and not graph.out_of(c)}
        self.contacts = [
            None
            if k in copied
            else RelaxedFaceContact(
                model.faces[v.face], model, forms[v.face, v.piece], knots, self.phi_c[k], self.step_cuts(v.layer)
            )
            for k, v in enumerate(graph.contacts)
        ]
        self.copies = {}
        for c in copied:
            v = graph.contacts[c]
            for f in graph.into(c):
                self.copies[f] = RelaxedFaceContact(
                    model.faces[v.face], model, forms[v.face, v.piece], knots, self.phi_f[f], self.step_cuts(v.layer)
                )
        self.frees = [
            RelaxedNonCollision(model, self.regions, v.route, per_region, self.phi_f[k], self.pose_cuts(v.layer))
            for k, v in enumerate(graph.frees)
        ]
        cons = [cp.sum(self.phi_f[graph.starts()]) == 1]
        r = model.finger_radius
        for k, (v, fr) in enumerate(zip(graph.frees, self.frees)):
            cons += fr.constraints
            phi = self.phi_f[k]
            if v.layer < 0:
                cons += [
                    phi <= self.allow[v.source],
                    fr.pose == phi * self.start,
                    fr.moments == phi * self.start_moments,
                    fr.q[0] == phi * self.start_q,
                ]
            else:
                src = model.faces[v.source]
                cons += _on_face(src, r, fr.q[0], phi, piece_range(graph, v.source_piece, src))
            dst = model.faces[v.target]
            cons += _on_face(dst, r, fr.q[-1], phi, piece_range(graph, v.target_piece, dst))
        for f, cc in self.copies.items():
            fr = self.frees[f]
            cons += cc.constraints
            cons += [
                cc.pose(False) == fr.pose,
                cc.pose_moments(False) == fr.moments,
                cc.finger(False) == fr.q[-1],
                cc.pose(True) == self.phi_f[f] * self.goal,
                cc.pose_moments(True) == self.phi_f[f] * self.goal_moments,
            ]
        for c in copied:
            ins = graph.into(c)
            cons += [self.phi_c[c] == cp.sum(self.phi_f[ins]), self.phi_t[c] == self.phi_c[c]]
        for c, rc in enumerate(self.contacts):
            if rc is None:
                continue
            cons += rc.constraints
            ins, outs = graph.into(c), graph.out_of(c)
            phi = self.phi_c[c]
            if not ins:
                cons.append(phi == 0)
                continue
            cons += [
                phi == cp.sum(self.phi_f[ins]),
                phi == cp.sum(self.phi_f[outs]) + self.phi_t[c] if outs else phi == self.phi_t[c],
                rc.pose(False) == sum(self.frees[f].pose for f in ins),
                rc.pose_moments(False) == sum(self.frees[f].moments for f in ins),
                rc.finger(False) == sum(self.frees[f].q[-1] for f in ins),
                rc.pose(True) == sum((self.frees[f].pose for f in outs), self.phi_t[c] * self.goal),
                rc.pose_moments(True) == sum((self.frees[f].moments for f in outs), self.phi_t[c] * self.goal_moments),
            ]
            if outs:
                cons.append(rc.finger(True) == sum(self.frees[f].q[0] for f in outs))
        self.cost = sum(rc.cost for rc in self.contacts if rc is not None) + sum(fr.cost for fr in self.frees)
        self.cost = self.cost + sum(cc.cost for cc in self.copies.values())
        self.problem = cp.Problem(cp.Minimize(self.cost), cons)
        self.params, self.variables = self.problem.parameters(), self.problem.variables()
        settings = (model, graph, knots, per_region, rot_weight, rlt, window, edge_copies, max_step, knot_windows)
        key = _key(settings)
        self.data = cached("contact-relaxation", key, PROGRAM_SOURCES, self._compile, self._fits)

    def _fits(self, data: ParametricConic) -> bool:
        return data.sizes == [p.size for p in self.params] and [u.shape for u in data.unpacked] == [
            v.shape for v in self.variables
        ]

    def _compile(self) -> ParametricConic:
        return ParametricConic(self.problem, self.params, {}, cp.CLARABEL, unpack=self.variables)

    def step_cuts(self, layer: int) -> list[list[tuple]]:
        """The chord cuts of each step of a contact vertex in `layer`: the window's and the knots' own."""
        out = []
        for k in range(self.knots - 1):
            j = layer * (self.knots - 1) + k
            cuts = [(self.arc, self.arc)] if self.arc is not None else []
            if self.knot_arcs:
                cuts.append((self.knot_arcs[j], self.knot_arcs[j + 1]))
            out.append(cuts)
        return out

    def pose_cuts(self, layer: int) -> list[ArcParameters]:
        """The cuts on a free vertex's heading: the slider rests at the last knot of the contact it leaves."""
        cuts = [self.arc] if self.arc is not None else []
        if self.knot_arcs and layer >= 0:
            cuts.append(self.knot_arcs[(layer + 1) * (self.knots - 1)])
        return cuts

    def set_query(self, start_pose, start_q, goal_pose, allow, window=None) -> None:
        if self.arc is not None:
            self.arc.set(window)
        if self.knot_arcs:
            windows = reachable_windows(
                float(start_pose[2]), float(goal_pose[2]), len(self.knot_arcs) - 1, self.max_step
            )
            for arc, w in zip(self.knot_arcs, windows):
                arc.set(w)
        self.start.value = pose_vector(start_pose)
        self.start_moments.value = pose_moments(start_pose)
        self.start_q.value = np.asarray(start_q, float)
        self.allow.value = np.asarray(allow, float)
        self.goal.value = pose_vector(goal_pose)
        self.goal_moments.value = pose_moments(goal_pose)

    def solve(self, start_pose, start_q, goal_pose, allow, window=None) -> RelaxationResult:
        self.set_query(start_pose, start_q, goal_pose, allow, window)
        t0 = time.perf_counter()
        theta = np.concatenate([np.ravel(np.asarray(p.value, float), order="F") for p in self.params])
        conic = self.data.at(theta)
        try:
            status, x, z, bound, residual = solve_certified(conic)
        except ValueError as err:
            raise cp.error.SolverError(f"{err} on the contact relaxation") from None
        for v, value in zip(self.variables, self.data.values(x), strict=True):
            v.value = v.project(value)
        dt = time.perf_counter() - t0
        return RelaxationResult(
            bound=bound,
            status=STATUS[status],
            solve_time_s=dt,
            contact_flow=np.clip(self.phi_c.value, 0, 1),
            free_flow=np.clip(self.phi_f.value, 0, 1),
            target_flow=np.clip(self.phi_t.value, 0, 1),
            relaxation=self,
            dual_residual=residual,
        )


def _key(settings: tuple) -> bytes:
    """The program's settings, the model's geometry and physics among them, every float as it is."""
    with np.printoptions(floatmode="unique", threshold=10**9):
        return repr(settings).encode()


def piece_range(graph: ContactGraph, piece: int, face) -> tuple[float, float]:
    """The piece's interval of lam, within where the finger may touch the face."""
    w = face.lam_hi - face.lam_lo
    return face.lam_lo + w * piece / graph.pieces, face.lam_lo + w * (piece + 1) / graph.pieces


def contact_forms(
    model: PushModel, graph: ContactGraph, rot_weight: float, rlt: bool, max_step: float = MAX_STEP_ROTATION
) -> dict:
    """The step forms of every (face, lam piece)."""
    return {
        (f.index, k): step_forms(f, model, rot_weight, rlt, piece_range(graph, k, f), max_step)
        for f in model.faces
        for k in range(graph.pieces)
    }


def _on_face(face, r, q, phi, lam_range) -> list:
    """q / phi touches the face (its finger line, within the piece's span of lam)."""
    tq = face.t @ q
    t0, length = float(face.t @ face.a), float(np.linalg.norm(face.e))
    lo, hi = (t0 + lam * length for lam in lam_range)
    return [face.n @ q == phi * (face.offset + r), tq >= phi * lo, tq <= phi * hi]
