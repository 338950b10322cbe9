"""Corrections near the goal: single pushes chosen on the quasi-static model, linearised about the slider's
pose, where the relaxation's plans serve badly.

Near the goal the rounding's plans cost 100 times their bound and take the slider away and back (on 56 of
gym-pusht's resets, all 9 plans made within 0.2 of the goal had gaps of 0.99-1.03). Here a push is
one column of a small matrix: from face f at lam, along a body-frame direction u into the slider, the slider
moves u per unit and turns kappa * (p x u) (`model.PushModel`). The push that leaves the least error, its
length by least squares and its path integrated through the turn, is what the expert runs next, closed loop.
No bound comes with it: the plan says "uncertified", as a plan whose bound failed its check does.
"""

from __future__ import annotations

import math

import numpy as np

from lerobot_gcs_push.contact.face_contact import finger_body
from lerobot_gcs_push.contact.model import PushModel, cross
from lerobot_gcs_push.planning.interface import Correction
from lerobot_gcs_push.scene import wrap_angle

# Contact points tried on each face, evenly over where the finger may touch it.
POINTS_PER_FACE = 9
# The longest push (m of slider travel): the linearisation is trusted over this much, the next push corrects
# the rest.
MAX_PUSH_M = 0.4
# Steps the push is integrated in, and knots of its plan.
PUSH_STEPS = 6


def corrections(model: PushModel, pose, goal, distance) -> list[Correction]:
    """Every single push the model offers from `pose` towards `goal`, the least error left first: only
    pushes that leave less error than there is now, by `distance(pose, goal)` (`ContactPlanner.distance`)."""
    pose, goal = np.asarray(pose, float), np.asarray(goal, float)
    c, s = math.cos(pose[2]), math.sin(pose[2])
    d = goal[:2] - pose[:2]
    need = np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1], wrap_angle(goal[2] - pose[2])])
    weight = np.array([1.0, 1.0, model.r_max])
    now = distance(pose, goal)
    out = []
    for face in model.faces:
        # Along the normal; with friction also at the cone's edges (sticking contact holds them).
        directions = [-face.n] + ([-face.n + model.mu * face.t, -face.n - model.mu * face.t] if model.mu > 0 else [])
        for lam in np.linspace(face.lam_lo, face.lam_hi, POINTS_PER_FACE):
            p = face.a + lam * face.e
            for u in directions:
                u = u / np.linalg.norm(u)
                twist = np.array([u[0], u[1], model.kappa * cross(p, u)])
                w = weight * twist
                amount = float(np.clip(w @ (weight * need) / (w @ w), 0.0, MAX_PUSH_M))
                if amount <= 1e-4:
                    continue
                poses, fingers = _integrate(model, face, lam, u, pose, amount)
                error = distance(poses[-1], goal)
                if error < now:
                    out.append(Correction(face.index, float(lam), u, amount, error, poses, fingers, face.n))
    return sorted(out, key=lambda k: k.error)


def _integrate(model: PushModel, face, lam: float, u: np.ndarray, pose: np.ndarray, amount: float):
    """The slider's poses and the finger's centre over a push of `amount` along body-frame `u`, the finger
    rolling on the face as the slider turns (as `face_contact` models a sticking step)."""
    poses, fingers = [pose.copy()], []
    roll = model.rolling_radius / float(np.linalg.norm(face.e))
    x = pose.copy()
    step = amount / PUSH_STEPS
    for k in range(PUSH_STEPS + 1):
        fingers.append(_world(x, finger_body(face, model, lam)))
        if k == PUSH_STEPS:
            break
        dtheta = math.asin(float(np.clip(model.kappa * cross(face.a + lam * face.e, u) * step, -1.0, 1.0)))
        mid = x[2] + dtheta / 2
        c, s = math.cos(mid), math.sin(mid)
        x = x + np.array([(c * u[0] - s * u[1]) * step, (s * u[0] + c * u[1]) * step, dtheta])
        lam -= roll * dtheta
        poses.append(x.copy())
    return np.array(poses), np.array(fingers)


def _world(pose, point) -> np.ndarray:
    c, s = math.cos(pose[2]), math.sin(pose[2])
    return np.array([pose[0] + c * point[0] - s * point[1], pose[1] + s * point[0] + c * point[1]])


__all__ = ["Correction", "corrections"]
