"""The scene: one source of truth for dimensions, physics, camera, goal and disturbances.

Every other module (planner, sim, env, dataset, evaluation) reads these numbers from a `Scene`; none
repeats them as literals. Defaults follow the paper's original system: a 1 m cube of 5 kg on damped
prismatic joints (the quasistatic model: a pushed box moves, an unpushed box stops), a 0.3 m sphere
finger under a PID inverse-dynamics controller, a 0.01 s plant step, and a 500 s timeout.

Beside it: its slider's kind (`kinds`), what the consumers ask instead of testing which slider it is; where
its episodes start (`starts`); and the checks of its fields and of the states given to it (`validation`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np

from lerobot_gcs_push.scene.kinds import TASK, SliderKind, kind_of
from lerobot_gcs_push.scene.starts import (
    FAR_FINGER_M,
    HARD_KINDS,
    HARD_SAMPLERS,
    HARD_V2_KINDS,
    SAMPLERS,
    InitialCondition,
    check_sampler,
    check_seed,
    episode_seed,
    load_initial_conditions,
    sample_initial_conditions,
)
from lerobot_gcs_push.scene.validation import check_fields, is_finite_number, validate_start, validate_state
from lerobot_gcs_push.shapes import SliderShape, square, tee

if TYPE_CHECKING:
    from lerobot_gcs_push.pusht.frame import PixelFrame

__all__ = [
    "FAR_FINGER_M",
    "HARD_KINDS",
    "HARD_SAMPLERS",
    "HARD_V2_KINDS",
    "SAMPLERS",
    "TASK",
    "Camera",
    "Disturbances",
    "InitialCondition",
    "Scene",
    "SliderKind",
    "check_sampler",
    "check_seed",
    "episode_seed",
    "is_finite_number",
    "load_initial_conditions",
    "sample_initial_conditions",
    "wrap_angle",
]


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
        check_fields(self)

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

    def validate_state(self, box, finger, **options) -> tuple[np.ndarray, np.ndarray]:
        """`validation.validate_state` (its keyword options: heading, what, box_limit, allow_overlap): (box,
        finger) as arrays, or a ValueError that names the violation."""
        return validate_state(self, box, finger, **options)

    def validate_start(self, ic: dict, what: str) -> tuple[np.ndarray, np.ndarray]:
        """`validation.validate_start`: `validate_state` of an initial condition's entry."""
        return validate_start(self, ic, what)

    def box_goal_distance(self, box) -> float:
        return float(np.linalg.norm(np.asarray(box, float) - self.goal_array))


def wrap_angle(angle: float) -> float:
    """The angle in [-pi, pi)."""
    return float((angle + math.pi) % (2 * math.pi) - math.pi)
