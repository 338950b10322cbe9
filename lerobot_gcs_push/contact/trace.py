"""A plan through contact from a solved restriction: slider poses, world finger positions, kinds, modes and
the pushes' contact data at every knot."""

from __future__ import annotations

import numpy as np

from lerobot_gcs_push.contact.face_contact import finger_body
from lerobot_gcs_push.contact.graph import ContactGraph
from lerobot_gcs_push.contact.model import PushModel
from lerobot_gcs_push.contact.rounding import Restriction
from lerobot_gcs_push.planning.plan import FREE, PUSH


def trace(model: PushModel, graph: ContactGraph, r: Restriction, start_pose) -> tuple:
    """Knots of a solved restriction: slider poses, world finger positions, kinds, modes, pushes."""
    poses, fingers, kinds, modes, pushes = [], [], [], [], []
    pose = np.asarray(start_pose, float)

    def world(p, q):
        c, s = np.cos(p[2]), np.sin(p[2])
        return p[:2] + np.array([c * q[0] - s * q[1], s * q[0] + c * q[1]])

    for f, q, c, sol in zip(r.path.frees, r.frees, r.path.contacts, r.contacts):
        modes.append(graph.frees[f].name)
        for k, qk in enumerate(q):
            if poses and k == 0:
                continue  # the previous contact's last knot
            poses.append(pose.copy())
            fingers.append(world(pose, qk))
            if len(poses) > 1:
                kinds.append(FREE)
        face = model.faces[graph.contacts[c].face]
        modes.append(graph.contacts[c].name)
        th = np.unwrap(np.arctan2(sol["s"], sol["c"]))
        th += 2 * np.pi * np.round((pose[2] - th[0]) / (2 * np.pi))
        for k in range(len(th)):
            p = np.array([sol["x"][k], sol["y"][k], th[k]])
            if k:
                poses.append(p)
                fingers.append(world(p, finger_body(face, model, sol["lam"][k])))
                kinds.append(PUSH)
        pose = poses[-1]
        pushes.append({k: sol[k] for k in ("face", "lam", "fn", "ft", "x", "y", "c", "s")} | {"normal": face.n})
    return np.array(poses), np.array(fingers), kinds, modes, pushes
