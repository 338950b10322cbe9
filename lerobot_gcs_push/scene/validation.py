"""The checks of a `Scene`: its own fields (`check_fields`, run as it is made) and the states and initial
conditions given to it (`validate_state`, `validate_start`). Each raises a ValueError that names the
violation. `scene` is a `Scene`, not imported here: this module imports nothing of the scene package, so
that every module of it may import this one."""

from __future__ import annotations

import math

import numpy as np

from lerobot_gcs_push.shapes import PIVOTS


def is_finite_number(value) -> bool:
    try:
        return math.isfinite(float(value))
    except (TypeError, ValueError):
        return False


def check_fields(scene) -> None:
    """`Scene.__post_init__`: the fields' own checks."""
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
        if not getattr(scene, name) > 0:
            raise ValueError(f"Scene.{name} must be positive, got {getattr(scene, name)!r}")
    if len(scene.goal) != 2 or not all(math.isfinite(g) for g in scene.goal):
        raise ValueError(f"Scene.goal must be two finite numbers, got {scene.goal!r}")
    if np.max(np.abs(scene.goal)) > scene.box_limit:
        raise ValueError(f"Scene.goal {scene.goal} lies outside the box's region |x|,|y| <= {scene.box_limit}")
    if not math.isfinite(scene.goal_heading):
        raise ValueError(f"Scene.goal_heading must be finite, got {scene.goal_heading!r}")
    if not 0 < scene.success_coverage <= 1:
        raise ValueError(f"Scene.success_coverage must be in (0, 1], got {scene.success_coverage!r}")
    if scene.slider_pivot not in PIVOTS:
        raise ValueError(f"Scene.slider_pivot must be one of {PIVOTS}, got {scene.slider_pivot!r}")
    if scene.limit_surface_radius is not None and not scene.limit_surface_radius > 0:
        raise ValueError(f"Scene.limit_surface_radius must be positive, got {scene.limit_surface_radius!r}")
    scene.shape  # noqa: B018  (an unknown slider fails here, not at the first use)
    if scene.slider != "box" and not scene.rotates:
        # Only the box has the paper's convex simplification (and its filled goal square).
        raise ValueError(f"Scene.slider {scene.slider!r} must rotate: set rotates=True")


def validate_state(
    scene,
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
    if scene.kind.refuses_heading(heading):
        raise ValueError(f"{what}: heading {heading} given, but this scene's slider cannot rotate")
    box_limit = scene.box_limit if box_limit is None else box_limit
    if np.max(np.abs(box)) > box_limit + 1e-9:
        raise ValueError(f"{what}: box {box.tolist()} lies outside the box workspace |x|,|y| <= {box_limit}")
    if np.max(np.abs(finger)) > scene.finger_limit + 1e-9:
        raise ValueError(
            f"{what}: finger {finger.tolist()} lies outside the finger workspace |x|,|y| <= {scene.finger_limit}"
        )
    gap = scene.finger_box_gap(box, finger, float(heading))
    # Touching counts as valid, whatever the rounding of box - contact distance.
    if gap < -1e-9 and not allow_overlap:
        raise ValueError(f"{what}: finger {finger.tolist()} overlaps the box {box.tolist()} (penetration {-gap:.3f} m)")
    return box, finger


def validate_start(scene, ic: dict, what: str) -> tuple[np.ndarray, np.ndarray]:
    """`validate_state` of an initial condition's entry (`load_initial_conditions`). gym-pusht's own
    resets may put the agent inside the T, so a scene with a pixel frame lets the finger overlap; its
    agent is checked in the px it was given."""
    if scene.kind.pixel_starts and "pusht_state" in ic:
        (u, v), limit = ic["pusht_state"][:2], scene.finger_limit
        lo, hi = scene.frame.to_px([-limit, limit]), scene.frame.to_px([limit, -limit])  # y flips
        if not (lo[0] <= u <= hi[0] and lo[1] <= v <= hi[1]):
            raise ValueError(
                f"{what}: pusht_state's agent ({u:g}, {v:g}) px lies outside the planner's workspace "
                f"[{lo[0]:.0f}, {hi[0]:.0f}] px on both axes"
            )
    return validate_state(
        scene, ic["box"], ic["finger"], heading=ic.get("heading", 0.0), what=what, allow_overlap=scene.kind.pixel_starts
    )


def _vector2(value, what: str) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    if arr.shape != (2,):
        raise ValueError(f"{what} must be a pair [x, y], got {value!r}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{what} must be finite, got {arr.tolist()}")
    return arr
