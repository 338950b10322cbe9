"""`GcsPlanner`, the box's `planning.Planner`: one query in, one `Plan` out; the graph and its programs are
built once."""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from lerobot_gcs_push.box_gcs.conic_gcs import ConicGcs
from lerobot_gcs_push.box_gcs.gcs import GcsProgram
from lerobot_gcs_push.box_gcs.graph import ModeGraph, SourcePoint, build_graph
from lerobot_gcs_push.box_gcs.micp import ScipMicp
from lerobot_gcs_push.box_gcs.rounding import candidate_paths
from lerobot_gcs_push.box_gcs.trace import trace
from lerobot_gcs_push.planning import FREE, Plan, PlanningError
from lerobot_gcs_push.scene import Scene
from lerobot_gcs_push.settings import check_choice

METHODS = ("relaxation", "micp")


def check_method(method: str) -> str:
    return check_choice("method", method, METHODS)


@dataclass(frozen=True)
class Query:
    """The shortest-path problem that a plan request poses in the mode graph (and that the oracles in
    tests pose to other solvers): from `src` to `goal` through the `allowed` edges."""

    src: np.ndarray  # the source point: box, finger
    goal: np.ndarray  # offsets under the goal tolerance dropped, so that no push of zero length is planned
    allowed: np.ndarray  # per edge: 1.0 when its push agrees with the goal offset, else 0.0
    escape: float | None  # length of the straight move out of a corner nook that reaches src, if needed

    @property
    def extra_cost(self) -> float:
        return 0.0 if self.escape is None else self.escape


def plannable(scene: Scene, box, finger, clearance: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
    """A measured state the planner accepts: contact compliance lets the finger sink a millimetre into
    the box, and a disturbance may knock the box past the planner's reach."""
    box = np.clip(np.asarray(box, float), -scene.box_reach, scene.box_reach)
    finger = np.asarray(finger, float).copy()
    if scene.finger_box_gap(box, finger) >= clearance:
        return box, finger
    # Move the centre straight away from the nearest point of the box (off a corner, that is diagonal).
    nearest = box + np.clip(finger - box, -scene.box_half, scene.box_half)
    away = finger - nearest
    if np.linalg.norm(away) < 1e-9:  # the centre is inside the box: leave by the nearest face
        r = finger - box
        axis = int(np.argmax(np.abs(r)))
        away = np.zeros(2)
        away[axis] = np.sign(r[axis]) or 1.0
        nearest = box.copy()
        nearest[axis] += away[axis] * scene.box_half
    return box, nearest + away / np.linalg.norm(away) * (scene.finger_radius + clearance)


class GcsPlanner:
    def __init__(
        self,
        scene: Scene | None = None,
        method: str = "relaxation",
        structure: str = "branches",
        num_pushes: int = 2,
        # Flow walks per plan (the greedy one first), beside two flow-decomposition paths (rounding.py):
        # the greedy walk alone lost nothing against 8 walks on 900 sampled queries and 260 reference
        # ones, at 23 % less time per plan; more walks are there for graphs whose flows split further.
        rounding_trials: int = 1,
        seed: int = 0,
        goal_tolerance: float = 1e-6,
        compile_now: bool = True,
    ):
        check_method(method)
        self.scene = scene or Scene()
        self.method = method
        self.graph: ModeGraph = build_graph(self.scene, structure, num_pushes)
        self.rounding_trials = rounding_trials
        self.goal_tolerance = goal_tolerance
        self.seed = seed
        self._programs: dict[str, GcsProgram] = {}
        self.compile_time_s: dict[str, float] = {}
        self._conic: ConicGcs | None = None
        self._micp: ScipMicp | None = None
        if compile_now:
            self.warm_up()

    @property
    def conic(self) -> ConicGcs:
        """The relaxation's conic data, which plans read (built on first use; see conic_gcs.py)."""
        if self._conic is None:
            t0 = time.perf_counter()
            self._conic = ConicGcs(self.graph)
            self.compile_time_s["conic"] = time.perf_counter() - t0
        return self._conic

    @property
    def micp(self) -> ScipMicp:
        """The MICP's conic data for SCIP (built on first use; see micp.py)."""
        if self._micp is None:
            t0 = time.perf_counter()
            self._micp = ScipMicp(self.graph)
            self.compile_time_s["micp_conic"] = time.perf_counter() - t0
        return self._micp

    def program(self, method: str) -> GcsProgram:
        """The cvxpy program for `method`, compiled on first use (the time is kept). Plans solve its conic
        form (`conic`, `micp`); the program itself is the reference that tests solve through cvxpy."""
        check_method(method)
        if method not in self._programs:
            t0 = time.perf_counter()
            micp = method == "micp"
            prog = GcsProgram(self.graph, integer=micp, two_cycles=micp)  # cuts pay off only in SCIP (gcs.py)
            prog.compile()
            self.compile_time_s[method] = time.perf_counter() - t0
            self._programs[method] = prog
        return self._programs[method]

    def query(self, box, finger, goal=None) -> Query | None:
        """The shortest-path problem that `plan` solves; None when the box is already at the goal."""
        return self._query(*self._validate(box, finger, goal))

    def plan(self, box, finger, goal=None, method: str | None = None) -> Plan:
        method = method or self.method
        box, finger, goal = self._validate(box, finger, goal)
        t0 = time.perf_counter()
        q = self._query(box, finger, goal)
        if q is None:
            return self._plan_without_push(method, box, finger, goal, t0)
        if method == "micp":
            flows = self.micp.solve(q.src, q.goal, q.allowed)
            # SCIP's optimum comes with SCIP's word only: the bound is the relaxation's, checked.
            relaxed = self._relaxation_or_none(q)
            conic = self.conic.at(q.src, q.goal, q.allowed) if relaxed is None else relaxed.conic
            paths = candidate_paths(self.graph, flows.flows, None, 1, min_flow=0.5)
        else:
            relaxed = self.conic.relax(q.src, q.goal, q.allowed)
            conic, flows = relaxed.conic, relaxed.flows
            # Seeded by the query, so a plan never depends on what this planner solved before.
            rng = np.random.default_rng([self.seed, *np.frombuffer(np.r_[q.src, q.goal].tobytes(), np.uint32)])
            paths = candidate_paths(self.graph, flows.flows, rng, self.rounding_trials)
        best = None
        for p in paths:
            sol = self.conic.restrict(conic, p, q.src, q.goal)
            if best is None or sol.rank() < best.rank():
                best = sol
        if best is None or not np.isfinite(best.cost):
            raise PlanningError(
                f"rounding found no feasible path among {len(paths)} candidates "
                f"(relaxation status {flows.status!r}, value {flows.value:.4f})"
            )
        modes, fw, bw, kinds = trace(self.scene, self.graph, best.vertices, best.points, box, q.src[SourcePoint.FINGER])
        if q.escape is not None:
            fw = np.vstack([finger, fw])
            bw = np.vstack([box, bw])
            kinds = [FREE, *kinds]
            modes = ["escape", *modes]
        # The relaxation's certified bound (conic.certificate), the plan's point inside the region it assumes
        # the optimum in; lowered to the plan's cost where the two meet within the solver's tolerance.
        bound = None if relaxed is None else relaxed.certificate(best).bound
        lower = None if bound is None else min(bound, best.cost) + q.extra_cost
        return Plan(
            method=method,
            cost=best.cost + q.extra_cost,
            lower_bound=lower,
            solve_time_s=time.perf_counter() - t0,
            modes=modes,
            finger_path=fw,
            slider_poses=bw,
            segment_kinds=kinds,
            goal=goal,
            candidates=len(paths),
            extra={"relaxation_time_s": flows.solve_time_s},
        )

    def _relaxation_or_none(self, q: Query):
        try:
            return self.conic.relax(q.src, q.goal, q.allowed)
        except PlanningError:  # no certificate, but SCIP's plan stands
            return None

    def goal_of(self, box) -> np.ndarray:
        return self.scene.goal_array

    def plannable(self, box, finger) -> tuple[np.ndarray, np.ndarray]:
        return plannable(self.scene, box, finger)

    def distance(self, a, b) -> float:
        """How far apart two box positions are (m)."""
        return float(np.linalg.norm(np.asarray(a, float) - np.asarray(b, float)))

    def _validate(self, box, finger, goal):
        scene = self.scene
        box, finger = scene.validate_state(box, finger, what="plan", box_limit=scene.box_reach)
        goal = scene.goal_array if goal is None else np.asarray(goal, float)
        if goal.shape != (2,) or not np.all(np.isfinite(goal)):
            raise ValueError(f"goal must be a finite pair [x, y], got {goal!r}")
        if np.max(np.abs(goal)) > scene.box_limit:
            raise ValueError(f"goal {goal.tolist()} lies outside the box workspace |x|,|y| <= {scene.box_limit}")
        return box, finger, goal

    def _query(self, box, finger, goal) -> Query | None:
        delta = np.where(np.abs(goal - box) > self.goal_tolerance, goal - box, 0.0)
        if not np.any(delta):
            return None
        start, escape = self._escape(box, finger)
        return Query(np.concatenate([box, start]), box + delta, self.graph.edge_allowed(delta, 0.0), escape)

    def _plan_without_push(self, method, box, finger, goal, t0) -> Plan:
        return Plan(
            method=method,
            cost=0.0,
            lower_bound=0.0,
            solve_time_s=time.perf_counter() - t0,
            modes=[],
            finger_path=finger[None].copy(),
            slider_poses=box[None].copy(),
            segment_kinds=[],
            goal=goal,
            candidates=0,
        )

    def _escape(self, box, finger):
        """Move a finger that sits diagonally off a box corner, inside the square |r|_inf < d where no
        free region reaches, straight away from that corner until it is in a free region."""
        d = self.scene.contact_distance
        r = finger - box
        if np.max(np.abs(r)) >= d:
            return finger, None
        corner = np.sign(r) * self.scene.box_half
        u = (r - corner) / np.linalg.norm(r - corner)
        # Smallest t with max(|corner + t u|) = d, along the outward diagonal-ish direction.
        t = min((d - np.abs(corner[i])) / abs(u[i]) for i in range(2) if abs(u[i]) > 1e-12)
        t_from_r = t - np.linalg.norm(r - corner)
        start = finger + u * max(t_from_r, 0.0)
        return start, float(np.linalg.norm(start - finger))

    def warm_up(self) -> float:
        """Build what plans need now, so that no query pays for it; returns the time taken."""
        t0 = time.perf_counter()
        self.conic  # noqa: B018 - built on first access
        if self.method == "micp":
            self.micp  # noqa: B018
        return time.perf_counter() - t0
