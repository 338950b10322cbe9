"""The scene: one source of truth for dimensions, physics, camera, goal and disturbances.

Every other module (planner, sim, env, dataset, evaluation) reads these numbers from a `Scene`; none
repeats them as literals. Defaults follow the paper's original system: a 1 m cube of 5 kg on damped
prismatic joints (the quasistatic model: a pushed box moves, an unpushed box stops), a 0.3 m sphere
finger under a PID inverse-dynamics controller, a 0.01 s plant step, and a 500 s timeout.

Beside it: its slider's kind (`kinds`), what the consumers ask instead of testing which slider it is, and
where its episodes start (`starts`).
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
    is_finite_number,
    load_initial_conditions,
    sample_initial_conditions,
)
from lerobot_gcs_push.shapes import PIVOTS, SliderShape, square, tee

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
