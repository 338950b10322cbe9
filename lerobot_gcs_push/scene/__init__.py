"""The scene: one source of truth for dimensions, physics, camera, goal and disturbances.

Every other module (planner, sim, env, dataset, evaluation) reads these numbers from a `Scene`; none
repeats them as literals. Defaults follow the paper's original system: a 1 m cube of 5 kg on damped
prismatic joints (the quasistatic model: a pushed box moves, an unpushed box stops), a 0.3 m sphere
finger under a PID inverse-dynamics controller, a 0.01 s plant step, and a 500 s timeout.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np

from lerobot_gcs_push.scene.kinds import TASK, SliderKind, kind_of  # noqa: F401 (TASK: its users import it here)
from lerobot_gcs_push.shapes import PIVOTS, SliderShape, square, tee

if TYPE_CHECKING:
    from lerobot_gcs_push.pusht.frame import PixelFrame


@dataclass(frozen=True)
class Disturbances:
    """The paper's force-disturbance protocol (section IV-A)."""

    probability_per_tick: float = 0.005  # chance of a new disturbance at each tick
    tick_s: float = 0.01
    max_count: int = 3
    force_range_n: tuple[float, float] = (50.0, 300.0)
    duration_ticks: int = 5


@dataclass(frozen=True)
class Camera:
    """Top-down RGB camera; the view spans the finger's whole commandable region."""

    width: int = 96
    height: int = 96
    height_m: float = 20.0  # above the ground; orthographic-like with a narrow field of view
    box_rgba: tuple[float, float, float, float] = (0.85, 0.1, 0.1, 1.0)
    finger_rgba: tuple[float, float, float, float] = (0.05, 0.05, 0.05, 1.0)
    goal_rgba: tuple[float, float, float, float] = (0.1, 0.75, 0.2, 1.0)
    ground_rgba: tuple[float, float, float, float] = (0.93, 0.93, 0.93, 1.0)


@dataclass(frozen=True)
class Scene:
    # Box: a cube that slides on x/y prismatic joints and cannot rotate.
    box_size: float = 1.0
    box_mass: float = 5.0
    box_damping: float = 100.0  # N*s/m on each joint: the quasistatic "ground friction"
    # Finger: a sphere on actuated x/y prismatic joints at the box's mid-height.
    finger_radius: float = 0.3
    finger_mass: float = 1.0
    finger_box_friction: float = 0.1
    kp: float = 100.0
    ki: float = 1.0
    kd: float = 10.0
    time_step: float = 0.01
    # Task.
    goal: tuple[float, float] = (0.0, 0.0)
    success_threshold: float = 0.1
    timeout_s: float = 500.0  # simulated seconds before an episode counts as failed (paper IV-B)
    fps: int = 10  # env steps (policy decisions) per simulated second
    # Initial-condition distribution (paper III-E) and the finger's commandable region.
    box_init_half_width: float = 4.5
    finger_init_half_width: float = 4.7
    finger_margin: float = 0.4  # beyond box half-size + finger diameter, so any sampled box can be pushed from any face
    # Planner geometry: the buffer that keeps the finger clear of the box while it moves around it,
    # and the perpendicular approach/retreat through which every push starts and ends.
    transition_buffer: float = 0.2
    # Slider: which shape is pushed (shapes.py) and whether it may turn. GcsPushBox-v0 is the box with
    # its yaw locked (the paper's convex simplification); the rotating envs set `rotates`.
    slider: str = "box"  # "box" (a square of box_size) or "tee" (gym-pusht's T, bar tee_bar_length)
    rotates: bool = False
    tee_bar_length: float = 2.0
    goal_heading: float = 0.0  # radians, the goal pose's heading (a rotating slider only)
    # The limit surface's torque scale, tau_max = f_max * c * r_max (the reference uses c = 0.3-0.6).
    limit_surface_c: float = 0.6
    # A slider whose mass is known: sqrt(I / m) about its centre of mass (m), in limit_surface_c * r_max's
    # place (a first-order body under frictionless contact moves as M^-1 wrench: gym-pusht's T).
    limit_surface_radius: float | None = None
    # Where the slider's frame (and so its limit surface) is centred: shapes.PIVOTS.
    slider_pivot: str = "centroid"
    # A target env that speaks pixels (gym-pusht): where these metres sit on its screen.
    frame: PixelFrame | None = None
    success_coverage: float = 0.95  # a rotating slider succeeds when it covers this share of the goal outline
    camera: Camera = field(default_factory=Camera)
    disturbances: Disturbances = field(default_factory=Disturbances)

    def __post_init__(self) -> None:
        for name in (
            "box_size",
            "box_mass",
            "box_damping",
            "finger_radius",
            "finger_mass",
            "time_step",
            "success_threshold",
            "box_init_half_width",
            "finger_init_half_width",
        ):
            if not getattr(self, name) > 0:
                raise ValueError(f"Scene.{name} must be positive, got {getattr(self, name)!r}")
        if len(self.goal) != 2 or not all(math.isfinite(g) for g in self.goal):
            raise ValueError(f"Scene.goal must be two finite numbers, got {self.goal!r}")
        if np.max(np.abs(self.goal)) > self.box_limit:
            raise ValueError(f"Scene.goal {self.goal} lies outside the box's region |x|,|y| <= {self.box_limit}")
        if not math.isfinite(self.goal_heading):
            raise ValueError(f"Scene.goal_heading must be finite, got {self.goal_heading!r}")
        if not 0 < self.success_coverage <= 1:
            raise ValueError(f"Scene.success_coverage must be in (0, 1], got {self.success_coverage!r}")
        if self.slider_pivot not in PIVOTS:
            raise ValueError(f"Scene.slider_pivot must be one of {PIVOTS}, got {self.slider_pivot!r}")
        if self.limit_surface_radius is not None and not self.limit_surface_radius > 0:
            raise ValueError(f"Scene.limit_surface_radius must be positive, got {self.limit_surface_radius!r}")
        self.shape  # noqa: B018  (an unknown slider fails here, not at the first use)
        if self.slider != "box" and not self.rotates:
            # Only the box has the paper's convex simplification (and its filled goal square).
            raise ValueError(f"Scene.slider {self.slider!r} must rotate: set rotates=True")

    # Derived quantities: computed here once so that no module re-derives them differently.
    @property
    def kind(self) -> SliderKind:
        """What the consumers ask of the slider (`scene.kinds`): they do not test which slider it is."""
        return kind_of(self)

    @cached_property
    def shape(self) -> SliderShape:
        if self.slider == "box":
            return square(self.box_size)
        if self.slider == "tee":
            return tee(self.tee_bar_length, self.slider_pivot)
        raise ValueError(f"unknown slider {self.slider!r}: choose 'box' or 'tee'")

    @property
    def rot_damping(self) -> float:
        """N*m*s/rad on the yaw joint. Quasi-statically v = f / b and omega = tau / b_theta: an ellipsoidal
        limit surface with tau_max / f_max = sqrt(b_theta / b) = c * r_max (or limit_surface_radius), the
        planner's own model."""
        radius = self.limit_surface_radius or self.limit_surface_c * self.shape.r_max
        return self.box_damping * radius**2

    @property
    def box_half(self) -> float:
        return self.box_size / 2

    @property
    def contact_distance(self) -> float:
        """Centre-to-centre distance along a face normal when finger and box touch."""
        return self.box_half + self.finger_radius

    @property
    def approach_distance(self) -> float:
        """Centre-to-centre distance of the approach point from which a push starts."""
        return self.contact_distance + self.transition_buffer

    @property
    def box_limit(self) -> float:
        """Box centres stay within [-box_limit, box_limit]^2 (initial states, goals, pushes)."""
        return self.box_init_half_width

    @property
    def push_lag_s(self) -> float:
        """Seconds of motion the PID finger trails its command by while pushing at constant speed: the
        box's damping force v * c must come from the proportional term m * kp * lag."""
        return self.box_damping / (self.finger_mass * self.kp)

    @property
    def box_reach(self) -> float:
        """Box centres the finger can still push from every face: a replanning expert may meet a box that
        a disturbance knocked past the sampling region, and the planner accepts it up to here."""
        return self.finger_limit - (self.slider_extent + self.finger_radius + self.transition_buffer)

    @property
    def finger_limit(self) -> float:
        """Finger commands are clipped to [-finger_limit, finger_limit]^2."""
        return self.box_limit + self.slider_extent + 2 * self.finger_radius + self.finger_margin

    @property
    def slider_extent(self) -> float:
        """How far the slider reaches from its centre towards a wall of the workspace.

        The box that cannot turn reaches half its side (the paper's workspace, unchanged). A slider that
        turns may point its farthest outline point (r_max) at any wall, so the workspace grows with it: the
        slider's sampling region stays `box_init_half_width` and the finger's region grows around it, so
        that the finger can still pass around a slider at the region's edge at any heading. The other way
        (shrinking the sampling region to keep the view) would give the T less room than the box to move.
        """
        return self.kind.extent(self)

    @property
    def view_half_width(self) -> float:
        """Half the side of the square the camera sees: the commandable region plus the finger."""
        return self.finger_limit + self.finger_radius

    @property
    def goal_array(self) -> np.ndarray:
        return np.asarray(self.goal, dtype=float)

    @property
    def goal_pose(self) -> np.ndarray:
        """The goal as (x, y, heading)."""
        return np.array([*self.goal, self.goal_heading], dtype=float)

    @property
    def task(self) -> str:
        """The language instruction stored with every frame."""
        return self.kind.task(self)

    def with_goal(self, goal) -> Scene:
        """The scene with goal (x, y), or (x, y, heading) for a rotating slider."""
        if len(goal) == 3:
            if self.kind.pose_size != 3:
                raise ValueError(f"a goal heading needs a rotating slider, got goal {list(goal)}")
            return dataclasses.replace(self, goal=(float(goal[0]), float(goal[1])), goal_heading=float(goal[2]))
        return dataclasses.replace(self, goal=(float(goal[0]), float(goal[1])))

    # Geometry shared by the planner, the env's input checks and the tests.
    def finger_box_gap(self, box, finger, heading: float = 0.0) -> float:
        """Signed distance between the finger sphere and the slider at (box, heading) (negative when they
        overlap)."""
        if self.slider != "box" or heading != 0.0:
            return self.shape.signed_distance((box[0], box[1], heading), finger) - self.finger_radius
        d = np.abs(np.asarray(finger, float) - np.asarray(box, float)) - self.box_half
        outside = np.linalg.norm(np.maximum(d, 0.0))
        inside = min(max(d[0], d[1]), 0.0)
        return float(outside + inside - self.finger_radius)

    def coverage(self, pose) -> float:
        """Share of the goal outline's area the slider at pose (x, y, heading) covers."""
        return self.shape.coverage(pose, self.goal_pose)

    def heading_error(self, heading: float) -> float:
        """heading - goal_heading, wrapped to [-pi, pi)."""
        return wrap_angle(heading - self.goal_heading)

    def validate_state(
        self,
        box,
        finger,
        *,
        heading: float = 0.0,
        what: str = "initial condition",
        box_limit: float | None = None,
        allow_overlap: bool = False,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Return (box, finger) as arrays, or raise a ValueError that names the violation. `heading` is the
        slider's (radians; only a rotating slider may have one other than 0). `allow_overlap`: a finger
        inside the slider is a valid start (gym-pusht's resets draw such starts)."""
        box = _vector2(box, f"{what}: box")
        finger = _vector2(finger, f"{what}: finger")
        if not is_finite_number(heading):
            raise ValueError(f"{what}: heading must be a finite number of radians, got {heading!r}")
        if self.kind.refuses_heading(heading):
            raise ValueError(f"{what}: heading {heading} given, but this scene's slider cannot rotate")
        box_limit = self.box_limit if box_limit is None else box_limit
        if np.max(np.abs(box)) > box_limit + 1e-9:
            raise ValueError(f"{what}: box {box.tolist()} lies outside the box workspace |x|,|y| <= {box_limit}")
        if np.max(np.abs(finger)) > self.finger_limit + 1e-9:
            raise ValueError(
                f"{what}: finger {finger.tolist()} lies outside the finger workspace |x|,|y| <= {self.finger_limit}"
            )
        gap = self.finger_box_gap(box, finger, float(heading))
        # Touching counts as valid, whatever the rounding of box - contact distance.
        if gap < -1e-9 and not allow_overlap:
            raise ValueError(
                f"{what}: finger {finger.tolist()} overlaps the box {box.tolist()} (penetration {-gap:.3f} m)"
            )
        return box, finger

    def validate_start(self, ic: dict, what: str) -> tuple[np.ndarray, np.ndarray]:
        """`validate_state` of an initial condition's entry (`load_initial_conditions`). gym-pusht's own
        resets may put the agent inside the T, so a scene with a pixel frame lets the finger overlap; its
        agent is checked in the px it was given."""
        if self.kind.pixel_starts and "pusht_state" in ic:
            (u, v), limit = ic["pusht_state"][:2], self.finger_limit
            lo, hi = self.frame.to_px([-limit, limit]), self.frame.to_px([limit, -limit])  # y flips
            if not (lo[0] <= u <= hi[0] and lo[1] <= v <= hi[1]):
                raise ValueError(
                    f"{what}: pusht_state's agent ({u:g}, {v:g}) px lies outside the planner's workspace "
                    f"[{lo[0]:.0f}, {hi[0]:.0f}] px on both axes"
                )
        return self.validate_state(
            ic["box"], ic["finger"], heading=ic.get("heading", 0.0), what=what, allow_overlap=self.kind.pixel_starts
        )

    def box_goal_distance(self, box) -> float:
        return float(np.linalg.norm(np.asarray(box, float) - self.goal_array))


def is_finite_number(value) -> bool:
    try:
        return math.isfinite(float(value))
    except (TypeError, ValueError):
        return False


def wrap_angle(angle: float) -> float:
    """The angle in [-pi, pi)."""
    return float((angle + math.pi) % (2 * math.pi) - math.pi)


def _vector2(value, what: str) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    if arr.shape != (2,):
        raise ValueError(f"{what} must be a pair [x, y], got {value!r}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{what} must be finite, got {arr.tolist()}")
    return arr


SAMPLERS = ("sobol", "uniform", "hard", "hard_v2")
HARD_KINDS = ("goal_side", "corner", "tiny_push", "edge")
# `hard` stays as it was (its seeded sets are the test and validation sets on record); `hard_v2` adds the
# family the unseen sets of session 20 found (box and finger in opposite corners: 1 success in 3) and
# fingers far from the box in general, and draws its six families in turn.
HARD_V2_KINDS = (*HARD_KINDS, "opposite_corners", "far_finger")
HARD_SAMPLERS = {"hard": HARD_KINDS, "hard_v2": HARD_V2_KINDS}


def check_sampler(sampler: str) -> str:
    if sampler not in SAMPLERS:
        raise ValueError(f"unknown sampler {sampler!r}: choose one of {SAMPLERS}")
    return sampler


@dataclass(frozen=True)
class InitialCondition:
    box: tuple[float, float]
    finger: tuple[float, float]
    kind: str = ""  # which family of the hard sampler drew it ("" for the space-filling samplers)
    heading: float | None = None  # the slider's, radians; None for a slider that cannot rotate
    pusht_state: tuple[float, ...] | None = None  # gym-pusht's own state vector of the same start (px)

    def to_json(self) -> dict:
        out = {"box": list(self.box), "finger": list(self.finger)}
        if self.heading is not None:
            out["heading"] = self.heading
        if self.pusht_state is not None:
            out["pusht_state"] = list(self.pusht_state)
        if self.kind:
            out["kind"] = self.kind
        return out


def sample_initial_conditions(
    scene: Scene,
    n: int,
    seed: int = 0,
    sampler: str = "sobol",
    collides: Callable[[np.ndarray, np.ndarray], bool] | None = None,
) -> list[InitialCondition]:
    """The first `n` collision-free initial conditions of a seeded stream.

    `sobol` (default) is a scrambled Sobol sequence over (box x, box y, finger x, finger y): it covers the
    corners the paper's uniform samples left sparse (its Figs. 4 and 6). `uniform` reproduces the paper.
    `hard` draws, in turn, the configurations a behaviour-cloned policy gets wrong (see `_hard_point`);
    `hard_v2` the same families and two with the finger far from the box.
    `collides(box, finger)` defaults to the exact sphere-box distance; the env passes Drake's query.
    The i-th condition depends only on the seed and i, so a prefix of a longer list is the shorter list.

    A target with its own resets (gym-pusht) draws them instead: `registration.sample_starts`.

    A rotating slider (its kind's `pose_size` 3) adds a fifth coordinate, its heading, uniform in [-pi, pi) (from
    the same Sobol or uniform stream), and `collides(box, finger, heading)` gets it. The hard families
    are the box's (they align the finger with axis-aligned faces) and refuse a rotating slider.
    """
    if n < 0:
        raise ValueError(f"number of initial conditions must be >= 0, got {n}")
    check_sampler(sampler)
    if collides is None:
        collides = lambda b, f, h=0.0: scene.finger_box_gap(b, f, h) < 0  # noqa: E731
    out: list[InitialCondition] = []
    if sampler in HARD_SAMPLERS and not scene.kind.hard_starts:
        raise ValueError(
            f"the {sampler!r} sampler's families are for the box that cannot rotate: choose 'sobol' or 'uniform'"
        )
    if sampler in HARD_SAMPLERS:
        kinds = HARD_SAMPLERS[sampler]
        for i in range(n):
            rng = np.random.default_rng([seed, i])
            kind = kinds[i % len(kinds)]
            while True:  # redraws come from the same stream, so the i-th condition still depends on (seed, i)
                box, finger = _hard_point(scene, kind, rng)
                if not collides(box, finger):
                    break
            out.append(InitialCondition(tuple(map(float, box)), tuple(map(float, finger)), kind))
        return out
    for point in _unit_points(sampler, seed, 2 + scene.kind.pose_size):
        box = (2 * point[:2] - 1) * scene.box_init_half_width
        finger = (2 * point[2:4] - 1) * scene.finger_init_half_width
        turn = [float(2 * math.pi * point[4] - math.pi)] if len(point) == 5 else []  # a turning slider's heading
        if collides(box, finger, *turn):
            continue
        heading = turn[0] if turn else None
        out.append(InitialCondition(tuple(map(float, box)), tuple(map(float, finger)), heading=heading))
        if len(out) == n:
            break
    return out


# The far_finger family's least finger-to-box distance: half the workspace's diagonal (4.5 m of box region).
FAR_FINGER_M = 6.0


def _hard_point(scene: Scene, kind: str, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """One (box, finger) of a family that uniform sampling rarely draws but a policy must handle:

    - goal_side: the box out along an axis from the goal, the finger between box and goal, aligned with
      the goal-facing face: the plan must go around the box; the nearest face pushes it the wrong way.
    - corner: the box near a corner, the finger just off one of its two goal-facing faces.
    - tiny_push: the box a few decimetres from the goal, the finger far away.
    - edge: the box along an edge of its region, the finger anywhere.
    - opposite_corners: the box near a corner, the finger near the diagonally opposite one (hard_v2).
    - far_finger: the box anywhere, the finger at least `FAR_FINGER_M` from it (hard_v2).
    """
    g, lim = scene.goal_array, scene.box_limit
    near = scene.contact_distance + 0.05  # finger centre just clear of a face
    lateral = scene.box_half - 0.1  # within the face's span
    if kind == "goal_side":
        axis, sign = rng.integers(2), rng.choice([-1.0, 1.0])
        box = g.copy()
        box[axis] += sign * rng.uniform(1.5, lim - abs(g[axis]))
        box[1 - axis] += rng.uniform(-0.5, 0.5)
        finger = box.copy()
        finger[axis] -= sign * rng.uniform(near, near + 0.7)
        finger[1 - axis] += rng.uniform(-lateral, lateral)
    elif kind == "corner":
        signs = rng.choice([-1.0, 1.0], size=2)
        box = signs * rng.uniform(lim - 1.5, lim, size=2)
        axis = rng.integers(2)
        finger = box.copy()
        finger[axis] -= signs[axis] * rng.uniform(near, near + 0.7)  # off the face that looks toward the goal
        finger[1 - axis] += rng.uniform(-lateral, lateral)
    elif kind == "tiny_push":
        angle = rng.uniform(0, 2 * np.pi)
        box = g + rng.uniform(0.15, 0.9) * np.array([np.cos(angle), np.sin(angle)])
        finger = rng.uniform(-scene.finger_init_half_width, scene.finger_init_half_width, size=2)
        axis = rng.integers(2)
        finger[axis] = rng.choice([-1.0, 1.0]) * rng.uniform(3.5, scene.finger_init_half_width)
    elif kind == "edge":
        axis = rng.integers(2)
        box = rng.uniform(-lim, lim, size=2)
        box[axis] = rng.choice([-1.0, 1.0]) * rng.uniform(lim - 1.0, lim)
        finger = rng.uniform(-scene.finger_init_half_width, scene.finger_init_half_width, size=2)
    elif kind == "opposite_corners":
        signs = rng.choice([-1.0, 1.0], size=2)
        box = signs * rng.uniform(lim - 1.5, lim, size=2)
        fl = scene.finger_init_half_width
        finger = -signs * rng.uniform(fl - 1.5, fl, size=2)
    elif kind == "far_finger":
        box = rng.uniform(-lim, lim, size=2)
        fl = scene.finger_init_half_width
        while True:  # rejection from the same stream: a box near the centre has no finger this far in some draws
            finger = rng.uniform(-fl, fl, size=2)
            if np.linalg.norm(finger - box) >= FAR_FINGER_M:
                break
    else:
        raise ValueError(f"unknown hard kind {kind!r}: choose one of {HARD_V2_KINDS}")
    return np.clip(box, -lim, lim), np.clip(finger, -scene.finger_limit, scene.finger_limit)


def check_seed(seed, name: str = "seed") -> int:
    """`seed` if it is a whole number >= 0 (numpy's seeding refuses others with a message that names no field)."""
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ValueError(f"{name} must be a whole number >= 0, got {seed!r}")
    return seed


def episode_seed(seed: int, index: int) -> int:
    """The env seed of episode `index` of a run seeded `seed`: independent of worker count and order."""
    return int(np.random.SeedSequence([seed, index]).generate_state(1)[0])


def load_initial_conditions(path, scene: Scene | None = None) -> list[dict]:
    """A JSON list of {"box": [x, y], "finger": [x, y]} and, for a rotating slider, "heading" (radians; a
    file without it means heading 0), other keys kept, with errors that name the entry. For gym-pusht
    (a `scene` with a pixel frame), an entry may be {"pusht_state": [ax, ay, bx, by, angle]} instead, as
    its `obs_type="state"` reports it (px, radians); box, finger and heading are filled in from it."""
    import json

    try:
        with open(path) as f:
            data = json.load(f)
    except FileNotFoundError:
        raise FileNotFoundError(f"initial-conditions file {str(path)!r} does not exist") from None
    except OSError as err:  # a directory, no permission: the same one-line message, not a traceback
        raise ValueError(f"cannot read initial-conditions file {str(path)!r}: {err.strerror}") from None
    except json.JSONDecodeError as err:
        raise ValueError(f"initial-conditions file {str(path)!r} is not valid JSON: {err}") from None
    if not isinstance(data, list):
        raise ValueError(f'{str(path)!r} must hold a JSON list of {{"box": [x, y], "finger": [x, y]}}')
    out = []
    for i, item in enumerate(data):
        if isinstance(item, dict) and "pusht_state" in item:
            out.append(_pusht_entry(path, i, item, scene))
            continue
        try:
            box, finger = [float(v) for v in item["box"]], [float(v) for v in item["finger"]]
            if len(box) != 2 or len(finger) != 2:
                raise ValueError
        except (KeyError, TypeError, ValueError):
            raise ValueError(
                f'{str(path)!r} entry {i} must be {{"box": [x, y], "finger": [x, y]}}, got {item!r}'
            ) from None
        entry = {**item, "box": box, "finger": finger}
        if "heading" in item:
            if isinstance(item["heading"], bool) or not is_finite_number(item["heading"]):
                raise ValueError(
                    f'{str(path)!r} entry {i}: "heading" must be a finite number of radians, got {item["heading"]!r}'
                )
            entry["heading"] = float(item["heading"])
        out.append(entry)
    return out


def _pusht_entry(path, i: int, item: dict, scene: Scene | None) -> dict:
    from lerobot_gcs_push.pusht.frame import check_pusht_state

    if scene is None or not scene.kind.pixel_starts:
        raise ValueError(f"{str(path)!r} entry {i}: a pusht_state is gym-pusht's: use --env_id=gym_pusht/PushT-v0")
    try:
        state = check_pusht_state(item["pusht_state"])
    except ValueError as err:
        raise ValueError(f"{str(path)!r} entry {i}: {err}") from None
    pose, finger = scene.frame.pose_finger_of(state)
    return {
        **item,
        "pusht_state": state.tolist(),
        "box": pose[:2].tolist(),
        "finger": finger.tolist(),
        "heading": float(pose[2]),
    }


def _unit_points(sampler: str, seed: int, dims: int) -> Iterator[np.ndarray]:
    if sampler == "uniform":
        rng = np.random.default_rng(seed)
        while True:
            yield rng.random(dims)
    else:
        from scipy.stats import qmc

        engine = qmc.Sobol(d=dims, scramble=True, rng=np.random.default_rng(seed))
        while True:
            yield from engine.random(64)
