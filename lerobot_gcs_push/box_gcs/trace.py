"""The box's plan from a solved path through its mode graph: finger and box waypoints and segment kinds."""

from __future__ import annotations

import numpy as np

from lerobot_gcs_push.box_gcs.graph import FreePoint, ModeGraph, PushPoint, VertexKind
from lerobot_gcs_push.planning.plan import APPROACH, FREE, PUSH, RETREAT, SegmentKind
from lerobot_gcs_push.scene import Scene


def trace(
    scene: Scene, graph: ModeGraph, vertices, points: dict[int, np.ndarray], box0: np.ndarray, finger0: np.ndarray
):
    """Finger and box waypoints and segment kinds along a solved path through the mode graph."""
    d, da = scene.contact_distance, scene.approach_distance
    finger, box = [np.array(finger0, float)], [np.array(box0, float)]
    kinds: list[SegmentKind] = []
    modes: list[str] = []

    def go(f, b, kind):
        finger.append(np.asarray(f, float))
        box.append(np.asarray(b, float))
        kinds.append(kind)

    for v in vertices:
        vert = graph.vertices[v]
        if vert.kind == VertexKind.FREE:
            end = points[v][FreePoint.END]
            if np.linalg.norm(end - finger[-1]) > 1e-9:  # a region passed through at a single point
                modes.append(f"{vert.kind}:{vert.face}")
            go(end, box[-1], FREE)
        elif vert.kind == VertexKind.PUSH:
            x = points[v]
            a, c, n = x[PushPoint.BEFORE], x[PushPoint.AFTER], vert.face.normal
            modes.append(f"{vert.kind}:{vert.face}")
            go(a - d * n, a, APPROACH)
            go(c - d * n, c, PUSH)
            go(c - da * n, c, RETREAT)
    fw, bw = np.array(finger), np.array(box)
    # Drop zero-length segments (a free segment that starts where the previous one ended).
    keep = [0] + [i + 1 for i in range(len(kinds)) if np.linalg.norm(fw[i + 1] - fw[i]) > 1e-9]
    kinds = [kinds[i - 1] for i in keep[1:]]
    return modes, fw[keep], bw[keep], kinds
