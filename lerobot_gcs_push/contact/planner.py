"""ContactPlanner, a rotating slider's `planning.Planner`: plans through contact.

planner = ContactPlanner(SCENES[SE2_ENV_ID])                     # registration.SCENES: a slider that turns
plan = planner.plan(slider_pose=(x, y, heading), finger=(x, y))    # relaxation + rounding
plan.cost, plan.lower_bound, plan.gap, plan.slider_poses, plan.finger_path, plan.modes
planner.baseline(slider_pose, finger)                               # the NLP alone, heuristic guess
"""

from __future__ import annotations

import dataclasses
import math
import time

import cvxpy as cp
import numpy as np

from lerobot_gcs_push.contact.fine import Correction, corrections
from lerobot_gcs_push.contact.graph import build_graph
from lerobot_gcs_push.contact.model import HeadingWindow, PushModel
from lerobot_gcs_push.contact.non_collision import free_regions
from lerobot_gcs_push.contact.query import check_query, plannable_state
from lerobot_gcs_push.contact.relaxation import GraphRelaxation, contact_forms
from lerobot_gcs_push.contact.restrict import baseline_plan, plan_of, restrict, round_paths
from lerobot_gcs_push.contact.rounding import Path, Restriction
from lerobot_gcs_push.planning import Plan, PlanningError
from lerobot_gcs_push.scene import Scene, wrap_angle


class ContactPlanner:
    def __init__(
        self,
        scene: Scene,
        layers: int | None = None,
        knots: int | None = None,
        per_region: int = 2,
        rot_weight: float | None = None,
        rlt: bool = True,
        candidates: int = 5,
        seed: int = 0,
        window_margin: float | None = None,
        pieces: int = 1,
        fallback_paths: int = 20,
        line_guesses: int = 0,
        edge_copies: bool = False,
        max_step_rotation: float = 0.2,
        knot_windows: bool = True,
        rolling: bool = True,
    ):
        self.scene = scene
        self.model = PushModel.from_scene(scene)
        # The round finger's contact rolls along the face as the slider turns: modelled, a planned push
        # ends in the sim where the plan says (rolling=False holds it still, the model before 2026-12-03).
        if not rolling:
            self.model = dataclasses.replace(self.model, rolling_radius=0.0)
        # A rolling contact moves along the face during a push, so a graph whose pushes each stay inside one
        # piece of the face leaves out plans that cross a piece's end: its bound would not be certified.
        if pieces > 1 and self.model.rolling_radius > 0:
            raise ValueError(
                f"pieces={pieces} needs rolling=False: a rolling contact can cross from one piece of a face to "
                "the next within a push, so the split graph's bound is not a lower bound on every plan"
            )
        # Pushes: a rolling contact turns the slider less per push, and the T's goal may be pi away. With 2
        # the T rounded 2 of 4 bench starts; with 3, 10 of 10 at a 15 % median gap and plans a third
        # cheaper than 2 layers without rolling (experiments/rotation/README.md). The square turns pi/4.
        if layers is None:
            layers = 2 if self.model.symmetry > 1 else 3
        self.max_step = max_step_rotation
        # Enough knots that the layers can turn the slider to its farthest goal copy (the square: pi/4 off;
        # the T: pi), and never fewer than 6, the count the box's bench numbers were measured with.
        if knots is None:
            knots = max(6, math.ceil(math.pi / self.model.symmetry / (layers * max_step_rotation) - 1e-9) + 1)
        self.layers, self.knots, self.per_region, self.candidates = layers, knots, per_region, candidates
        # max_step_rotation 0.2 rad (not the module's 0.35): at 0.35 the re-integrated continuous model
        # ended 3-9 cm from 6 of 20 plans' ends (sin(dtheta) for dtheta, midpoint rotation); at 0.2 with
        # 6 knots all 20 ended within 3 cm / 0.03 rad, at the same relaxation time.
        # The finger sweeps about r_max per radian the slider turns: weight the rotation chord^2 alike.
        self.rot_weight = self.model.r_max**2 if rot_weight is None else rot_weight
        self.graph = build_graph(self.model, layers, pieces)
        self.regions = free_regions(self.model)
        self.forms = contact_forms(self.model, self.graph, self.rot_weight, rlt, self.max_step)
        # The baseline plans on the plain graph (one contact vertex per face, the whole face): it must not
        # inherit the relaxation's splits of the contact location.
        self.baseline_graph = build_graph(self.model, layers, 1)
        self.baseline_forms = contact_forms(self.model, self.baseline_graph, self.rot_weight, rlt, self.max_step)
        # Rounding keeps a path's faces but lets the finger anywhere on each: the pieces tighten the
        # bound, and a plan outside its piece is still a plan of the graph (the pieces cover the face).
        self.rounding_forms = {(f, k): self.baseline_forms[f, 0] for f, k in self.forms}
        # Each query samples from a generator of its own: a plan depends on its query, not on the ones before.
        self.seed = seed
        self._relaxation = None
        self._warm = False
        self._rlt = rlt
        # Headings stay within window_margin of the start-to-goal arc (None: unrestricted, no chord cut).
        self.window_margin = window_margin
        self.fallback_paths = fallback_paths
        self.line_guesses = line_guesses
        self.edge_copies = edge_copies
        # Each knot's reachable arc of headings as a chord cut (model.reachable_windows): valid for every plan,
        # it keeps the relaxation's headings from cutting across the unit circle during large turns.
        self.knot_windows = knot_windows

    @property
    def relaxation(self) -> GraphRelaxation:
        if self._relaxation is None:
            self._relaxation = GraphRelaxation(
                self.model,
                self.graph,
                self.knots,
                self.per_region,
                self.rot_weight,
                self._rlt,
                self.window_margin is not None,
                self.edge_copies,
                self.max_step,
                self.knot_windows,
            )
        return self._relaxation

    def warm_up(self) -> float:
        """Build the relaxation and solve it once (its conic data compiled, or read from the cache); its
        seconds, 0 once done."""
        if self._warm:
            return 0.0
        self._warm = True
        t0 = time.perf_counter()
        self.relaxation.solve(
            (2.0, 1.0, 0.3),
            (4.0, 1.0),
            (0.0, 0.0, 0.0),
            np.ones(len(self.regions)),
            HeadingWindow.around(0.3, 0.0, 0.5),
        )
        return time.perf_counter() - t0

    def query(self, slider_pose, finger, goal=None):
        """(start pose, finger in the slider frame, goal pose, which free pieces hold the finger). `goal`
        (x, y, heading) in the scene goal's place: a waypoint (its heading taken as given)."""
        pose, q, goal, allow = check_query(self.model, self.regions, slider_pose, finger, goal)
        return pose, q, self.goal_of(pose) if goal is None else goal, allow

    def goal_of(self, slider_pose) -> np.ndarray:
        """The goal pose a plan from `slider_pose` ends at: the shape's symmetric copy nearest its heading."""
        return np.array([*self.model.goal[:2], self.model.goal_heading_near(float(slider_pose[2]))])

    def plannable(self, slider_pose, finger, clearance: float = 1e-3) -> tuple[np.ndarray, np.ndarray]:
        """`query.plannable_state`: the nearest measured state the planner accepts, the finger `clearance` inside
        a free-space piece."""
        return plannable_state(self.model, self.regions, slider_pose, finger, clearance)

    def distance(self, a, b) -> float:
        """How far apart two slider poses are: metres plus radians times the slider's radius."""
        a, b = np.asarray(a, float), np.asarray(b, float)
        return float(np.linalg.norm(a[:2] - b[:2]) + self.model.r_max * abs(wrap_angle(a[2] - b[2])))

    def corrections(self, slider_pose, goal=None) -> list[Correction]:
        """Single pushes towards the goal (or `goal`) on the model linearised about `slider_pose`, the least
        error left first (`fine.corrections`): the expert's last corrections near the goal, uncertified."""
        pose = np.asarray(slider_pose, float)
        goal = self.goal_of(pose) if goal is None else np.asarray(goal, float)
        return corrections(self.model, pose, goal, self.distance)

    def window(self, pose, goal) -> HeadingWindow | None:
        if self.window_margin is None:
            return None
        return HeadingWindow.around(float(pose[2]), float(goal[2]), self.window_margin)

    def plan(self, slider_pose, finger, goal=None) -> Plan:
        """The plan from `slider_pose` and `finger` to the scene's goal (or to `goal`, a waypoint)."""
        pose, q, goal, allow = self.query(slider_pose, finger, goal)
        capacity = self.layers * (self.knots - 1) * self.max_step
        if abs(goal[2] - pose[2]) > capacity:
            raise PlanningError(
                f"turning {abs(goal[2] - pose[2]):.2f} rad exceeds the graph's {capacity:.2f} rad "
                f"({self.layers} layers x {self.knots - 1} steps x {self.max_step} rad): add knots or layers"
            )
        relaxation = self.relaxation  # built once (cvxpy's expressions, its conic data read or compiled)
        t0 = time.perf_counter()
        window = self.window(pose, goal)
        try:
            res = relaxation.solve(pose, q, goal, allow, window)
        except cp.error.SolverError as err:
            raise PlanningError(f"the relaxation failed: {err}") from None
        t1 = time.perf_counter()
        best, tried, fallback = round_paths(self, res, pose, q, goal, allow, window)
        t2 = time.perf_counter()
        if best is None:
            bound = "uncertified" if res.bound is None else f"{res.bound:.4f}"
            raise PlanningError(f"no sampled path's restriction solved ({tried} tried, bound {bound})")
        return plan_of(
            self,
            "relaxation",
            best,
            pose,
            goal,
            res.bound,
            t2 - t0,
            tried,
            {
                "relaxation_s": t1 - t0,
                "rounding_s": t2 - t1,
                "relaxation_status": res.status,
                "dual_residual": res.dual_residual,
                "fallback": fallback,
                "graph_path": {"frees": list(best.path.frees), "contacts": list(best.path.contacts)},
            },
        )

    def baseline(self, slider_pose, finger) -> Plan:
        """The same nonlinear program without the relaxation: one push per layer, each from the face that
        looks away from the goal, reached by the shortest route, SNOPT from a straight-line guess. (One
        push once sufficed; as the slider turns the round finger's contact rolls toward the face's middle,
        so one push rarely reaches the goal's heading.)"""
        return baseline_plan(self, slider_pose, finger)

    def _restrict(self, path: Path, pose, q, goal, window, graph=None, forms=None, guess=None) -> Restriction:
        """`restrict.restrict`: the path's restriction, SNOPT from `guess` (the straight-line guess by default)."""
        return restrict(self, path, pose, q, goal, window, graph, forms, guess)
