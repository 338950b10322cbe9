"""A `ContactPlanner`'s queries: the checks a (slider pose, finger, goal) query must pass, and the nearest
measured state it accepts (`plannable_state`). The finger is taken into the slider's frame, where the free-space
pieces (`non_collision.free_regions`) are."""

from __future__ import annotations

import numpy as np

from lerobot_gcs_push.contact.model import PushModel
from lerobot_gcs_push.contact.non_collision import Region
from lerobot_gcs_push.planning import PlanningError


def check_query(model: PushModel, regions: list[Region], slider_pose, finger, goal=None):
    """(start pose, finger in the slider frame, goal pose or None, which free pieces hold the finger); a
    given `goal` (x, y, heading) is checked, None left for the caller (`ContactPlanner.goal_of`)."""
    pose, finger = np.asarray(slider_pose, float), np.asarray(finger, float)
    if pose.shape != (3,) or not np.all(np.isfinite(pose)):
        raise ValueError(f"slider pose must be three finite numbers [x, y, heading], got {pose.tolist()}")
    if finger.shape != (2,) or not np.all(np.isfinite(finger)):
        raise ValueError(f"finger must be two finite numbers [x, y], got {finger.tolist()}")
    if np.max(np.abs(pose[:2])) > model.reach + 1e-9:
        # A PlanningError, not a ValueError: a closed-loop expert meets sliders knocked out of reach.
        raise PlanningError(f"slider centre {pose[:2].tolist()} lies outside the workspace |x|,|y| <= {model.reach}")
    c, s = np.cos(pose[2]), np.sin(pose[2])
    d = finger - pose[:2]
    q = np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]])
    allow = np.array([reg.contains(q) for reg in regions], float)
    if not allow.any():
        raise ValueError(
            f"finger {finger.tolist()} lies in none of the free-space pieces around the slider at "
            f"{pose.tolist()} (too close to it, or beyond the finger's reach)"
        )
    if goal is not None:
        goal = np.asarray(goal, float)
        if goal.shape != (3,) or not np.all(np.isfinite(goal)) or np.max(np.abs(goal[:2])) > model.reach:
            raise ValueError(f"goal must be [x, y, heading] within the workspace, got {goal.tolist()}")
    return pose, q, goal, allow


def plannable_state(
    model: PushModel, regions: list[Region], slider_pose, finger, clearance: float
) -> tuple[np.ndarray, np.ndarray]:
    """A measured state the planner accepts: the slider's centre within its reach, the finger `clearance`
    inside the nearest free-space piece (in contact, or off a corner where no piece reaches, it is not)."""
    pose = np.asarray(slider_pose, float).copy()
    pose[:2] = np.clip(pose[:2], -model.reach, model.reach)
    c, s = np.cos(pose[2]), np.sin(pose[2])
    d = np.asarray(finger, float) - pose[:2]
    q = np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]])
    if any(r.contains(q) for r in regions):
        return pose, np.asarray(finger, float).copy()
    q = min((r.project(q, clearance) for r in regions), key=lambda p: float(np.linalg.norm(p - q)))
    return pose, pose[:2] + np.array([c * q[0] - s * q[1], s * q[0] + c * q[1]])
