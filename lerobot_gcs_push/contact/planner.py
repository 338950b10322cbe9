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

from lerobot_gcs_push.contact.face_contact import finger_body
from lerobot_gcs_push.contact.fine import Correction, corrections
from lerobot_gcs_push.contact.graph import START, build_graph
from lerobot_gcs_push.contact.model import HeadingWindow, PushModel
from lerobot_gcs_push.contact.non_collision import free_regions, knots_of
from lerobot_gcs_push.contact.relaxation import GraphRelaxation, contact_forms
from lerobot_gcs_push.contact.rounding import Path, ranked_paths, round_relaxation, solve_restriction
from lerobot_gcs_push.contact.trace import trace
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
        pose, finger = np.asarray(slider_pose, float), np.asarray(finger, float)
        if pose.shape != (3,) or not np.all(np.isfinite(pose)):
            raise ValueError(f"slider pose must be three finite numbers [x, y, heading], got {pose.tolist()}")
        if finger.shape != (2,) or not np.all(np.isfinite(finger)):
            raise ValueError(f"finger must be two finite numbers [x, y], got {finger.tolist()}")
        if np.max(np.abs(pose[:2])) > self.model.reach + 1e-9:
            # A PlanningError, not a ValueError: a closed-loop expert meets sliders knocked out of reach.
            raise PlanningError(
                f"slider centre {pose[:2].tolist()} lies outside the workspace |x|,|y| <= {self.model.reach}"
            )
        c, s = np.cos(pose[2]), np.sin(pose[2])
        d = finger - pose[:2]
        q = np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]])
        allow = np.array([reg.contains(q) for reg in self.regions], float)
        if not allow.any():
            raise ValueError(
                f"finger {finger.tolist()} lies in none of the free-space pieces around the slider at "
                f"{pose.tolist()} (too close to it, or beyond the finger's reach)"
            )
        if goal is None:
            goal = self.goal_of(pose)
        else:
            goal = np.asarray(goal, float)
            if goal.shape != (3,) or not np.all(np.isfinite(goal)) or np.max(np.abs(goal[:2])) > self.model.reach:
                raise ValueError(f"goal must be [x, y, heading] within the workspace, got {goal.tolist()}")
        return pose, q, goal, allow

    def goal_of(self, slider_pose) -> np.ndarray:
        """The goal pose a plan from `slider_pose` ends at: the shape's symmetric copy nearest its heading."""
        return np.array([*self.model.goal[:2], self.model.goal_heading_near(float(slider_pose[2]))])

    def plannable(self, slider_pose, finger, clearance: float = 1e-3) -> tuple[np.ndarray, np.ndarray]:
        """A measured state the planner accepts: the slider's centre within its reach, the finger `clearance`
        inside the nearest free-space piece (in contact, or off a corner where no piece reaches, it is not)."""
        model = self.model
        pose = np.asarray(slider_pose, float).copy()
        pose[:2] = np.clip(pose[:2], -model.reach, model.reach)
        c, s = np.cos(pose[2]), np.sin(pose[2])
        d = np.asarray(finger, float) - pose[:2]
        q = np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]])
        if any(r.contains(q) for r in self.regions):
            return pose, np.asarray(finger, float).copy()
        q = min((r.project(q, clearance) for r in self.regions), key=lambda p: float(np.linalg.norm(p - q)))
        return pose, pose[:2] + np.array([c * q[0] - s * q[1], s * q[0] + c * q[1]])

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
        best, tried = round_relaxation(
            self.model,
            self.graph,
            self.regions,
            self.rounding_forms,
            res,
            self.knots,
            self.per_region,
            pose,
            q,
            goal,
            self.candidates,
            np.random.default_rng(self.seed),
            window,
        )
        fallback = best is None
        # SNOPT from the straight-line guess finds another local optimum of the same path: tried on the best
        # sampled path (then on the paths of most flow) when line_guesses > 0. Off by default: on the bench's
        # 20 rotating-box starts, run side by side twice, it lowered the median gap 0.0874 -> 0.0851 for 55-65
        # ms of rounding (+20-28 % a plan). If every sampled path failed (the relaxation's values can mislead
        # SNOPT at the motion cone's edge), the paths of most flow from that guess, until one solves.
        if fallback:
            retry = ranked_paths(self.graph, res, allow)[: self.fallback_paths]
        elif self.line_guesses > 1:  # every path enumerated only when more than the best is asked for
            ranked = ranked_paths(self.graph, res, allow)
            retry = ([best.path] + [p for p in ranked if p != best.path])[: self.line_guesses]
        else:
            retry = [best.path][: self.line_guesses]  # [] when off
        for path in retry:
            r = self._restrict(path, pose, q, goal, window)
            tried += 1
            if r.success and (best is None or r.cost < best.cost):
                best = r
            if fallback and best is not None:
                break
        t2 = time.perf_counter()
        if best is None:
            bound = "uncertified" if res.bound is None else f"{res.bound:.4f}"
            raise PlanningError(f"no sampled path's restriction solved ({tried} tried, bound {bound})")
        return self._plan(
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
        pose, q, goal, allow = self.query(slider_pose, finger)
        t0 = time.perf_counter()
        c, s = np.cos(pose[2]), np.sin(pose[2])
        u = goal[:2] - pose[:2]
        u = np.array([c * u[0] + s * u[1], -s * u[0] + c * u[1]])
        face = int(np.argmax([-(f.n @ u) for f in self.model.faces]))
        graph = self.baseline_graph
        options = [k for k, v in enumerate(graph.frees) if v.layer == START and allow[v.source] and v.target == face]
        start_free = min(options, key=lambda k: len(graph.frees[k].route))
        again = [
            min(
                (k for k, v in enumerate(graph.frees) if v.layer == layer and v.source == face and v.target == face),
                key=lambda k: len(graph.frees[k].route),
            )
            for layer in range(self.layers - 1)
        ]
        path = Path((start_free, *again), tuple(graph.contact_index(layer, face) for layer in range(self.layers)))
        r = self._restrict(path, pose, q, goal, self.window(pose, goal), graph, self.baseline_forms)
        dt = time.perf_counter() - t0
        if not r.success:
            raise PlanningError("the baseline's SNOPT run found no feasible plan")
        return self._plan("baseline", r, pose, goal, None, dt, 1, {}, graph)

    def _restrict(self, path: Path, pose, q, goal, window, graph=None, forms=None, guess=None):
        """The path's restriction, SNOPT from `guess` (contact modes' values, free modes' points: the
        straight-line guess by default), on the planner's graph by default."""
        graph = graph or self.graph
        guess_c, guess_q = guess or self._straight_line_guess(graph, path, pose, q, goal)
        return solve_restriction(
            self.model,
            graph,
            self.regions,
            forms or self.rounding_forms,
            path,
            self.knots,
            self.per_region,
            pose,
            q,
            goal,
            guess_c,
            guess_q,
            window,
        )

    def _straight_line_guess(self, graph, path: Path, pose, q, goal):
        """Poses interpolated from start to goal over the path's contact knots, each push mid-face, the
        finger straight from where it is to the next contact point (penetrating, if it must: SNOPT fixes it)."""
        n_c = len(path.contacts)
        w = np.linspace(0.0, 1.0, n_c * (self.knots - 1) + 1)
        traj = np.array([pose[i] + w * (goal[i] - pose[i]) for i in range(3)]).T
        contacts, frees, finger = [], [], np.asarray(q, float)
        for m, (fi, ci) in enumerate(zip(path.frees, path.contacts)):
            face = self.model.faces[graph.contacts[ci].face]
            seg = traj[m * (self.knots - 1) : (m + 1) * (self.knots - 1) + 1]
            fn, ft = [], []
            for k in range(self.knots - 1):
                dw = seg[k + 1, :2] - seg[k, :2]
                ck, sk = np.cos(seg[k, 2]), np.sin(seg[k, 2])
                db = np.array([ck * dw[0] + sk * dw[1], -sk * dw[0] + ck * dw[1]])
                fn.append(-(face.n @ db))
                ft.append(face.t @ db)
            contacts.append(
                {
                    "lam": 0.5,
                    "c": np.cos(seg[:, 2]),
                    "s": np.sin(seg[:, 2]),
                    "fn": np.array(fn),
                    "ft": np.array(ft),
                    "x": seg[:, 0],
                    "y": seg[:, 1],
                }
            )
            n_q = knots_of(graph.frees[fi].route, self.per_region)
            end = finger_body(face, self.model, 0.5)
            frees.append(finger[None, :] + np.linspace(0, 1, n_q)[:, None] * (end - finger)[None, :])
            finger = end
        return contacts, frees

    def _plan(self, method, r, pose, goal, bound, dt, tried, extra, graph=None) -> Plan:
        poses, fingers, kinds, modes, pushes = trace(self.model, graph or self.graph, r, pose)
        return Plan(
            method=method,
            cost=r.cost,
            lower_bound=bound,
            solve_time_s=dt,
            modes=modes,
            slider_poses=poses,
            finger_path=fingers,
            segment_kinds=kinds,
            goal=goal,
            pushes=pushes,
            free_knots=list(r.frees),
            candidates=tried,
            extra=extra,
        )
