"""A plan: the mode sequence, the finger and box paths, and its time parameterisation into commands."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from enum import StrEnum

import numpy as np

from lerobot_gcs_push.planner.graph import FreePoint, ModeGraph, PushPoint, VertexKind
from lerobot_gcs_push.scene import Scene


class SegmentKind(StrEnum):
    """What the finger does along a segment of a plan, in the order a push visits them."""

    FREE = "free"
    APPROACH = "approach"
    PUSH = "push"
    RETREAT = "retreat"
    DWELL = "dwell"  # holding a push's end point (in schedules only)


# Short names, as the package's users import them (in definition order).
FREE, APPROACH, PUSH, RETREAT, DWELL = SegmentKind


@dataclass(frozen=True)
class Speeds:
    """Maximum finger speed per segment kind (m/s).

    The PID finger lags its command by about v * box_damping / kp metres while pushing (1 s of motion at
    kp = 100 against the box's 100 N*s/m), and that lag drains into the box when the finger stops. Slow
    pushes keep the final box error small; free motion can be fast because nothing is in contact.
    """

    free: float = 1.0
    approach: float = 0.25
    push: float = 0.4
    retreat: float = 0.5
    push_dwell_s: float = 1.0  # hold the push's end point while the finger's remaining lag drains
    # Command pushes ahead of the plan by this fraction of the finger's steady-state lag (Scene.push_lag_s),
    # so that the box stops where the plan ends. Measured on a 3 m push at 0.4 m/s: final box error
    # -2.6 cm with no lead and a 2 s dwell, +0.4 cm with 0.85 and a 1 s dwell, +3 cm with 1.0.
    push_lead: float = 0.85

    def of(self, kind: SegmentKind) -> float:
        return getattr(self, kind)

    def __post_init__(self) -> None:
        for k, v in asdict(self).items():
            if not (v >= 0 if k in ("push_dwell_s", "push_lead") else v > 0):
                raise ValueError(f"Speeds.{k} must be positive, got {v}")


@dataclass
class Schedule:
    """Commands at t = 1/fps, 2/fps, ...; the segment kind active at each; where the box should rest."""

    commands: np.ndarray  # (N, 2)
    kinds: list[SegmentKind]  # (N,)
    box: np.ndarray  # (N, 2): planned box position (exact when the kind is not a push); a rotating slider's (N, 3) pose

    def __len__(self) -> int:
        return len(self.commands)


@dataclass
class Plan:
    method: str
    cost: float  # finger path length (m)
    lower_bound: float
    solve_time_s: float
    modes: list[str]
    finger_waypoints: np.ndarray  # (K+1, 2)
    box_waypoints: np.ndarray  # (K+1, 2): box position when the finger is at each waypoint
    segment_kinds: list[SegmentKind]  # (K,)
    goal: np.ndarray
    candidates: int = 1  # paths whose restriction was solved
    extra: dict = field(default_factory=dict)

    @property
    def box_final(self) -> np.ndarray:
        return self.box_waypoints[-1]

    @property
    def num_pushes(self) -> int:
        return sum(k == PUSH for k in self.segment_kinds)

    def _knots(self, speeds: Speeds):
        """Waypoints with a dwell after each push, their times and the kind of the segment ending there."""
        wp, bw, kinds, times = [self.finger_waypoints[0]], [self.box_waypoints[0]], [], [0.0]
        for i, kind in enumerate(self.segment_kinds):
            a, b = self.finger_waypoints[i], self.finger_waypoints[i + 1]
            times.append(times[-1] + float(np.linalg.norm(b - a)) / speeds.of(kind))
            wp.append(b)
            bw.append(self.box_waypoints[i + 1])
            kinds.append(kind)
            if kind == PUSH and speeds.push_dwell_s > 0:
                times.append(times[-1] + speeds.push_dwell_s)
                wp.append(b)
                bw.append(self.box_waypoints[i + 1])
                kinds.append(DWELL)
        return np.array(wp), np.array(bw), kinds, np.array(times)

    def duration(self, speeds: Speeds = Speeds()) -> float:
        """Commanded execution time (s), dwells included."""
        return float(self._knots(speeds)[3][-1])

    def schedule(self, fps: float, speeds: Speeds = Speeds(), lag_s: float = 0.0) -> Schedule:
        """Commands at the env's rate. `lag_s` (Scene.push_lag_s) turns on the push lead."""
        wp, bw, kinds, t_knots = self._knots(speeds)
        total = t_knots[-1]
        n = max(1, int(np.ceil(total * fps - 1e-9)))
        t = np.minimum(np.arange(1, n + 1) / fps, total)
        cmds = np.stack([np.interp(t, t_knots, wp[:, 0]), np.interp(t, t_knots, wp[:, 1])], axis=1)
        if len(kinds) == 0:
            return Schedule(cmds, [FREE] * n, np.repeat(bw[:1], n, axis=0))
        seg = np.clip(np.searchsorted(t_knots, t - 1e-12) - 1, 0, len(kinds) - 1)
        box = np.stack([np.interp(t, t_knots, bw[:, 0]), np.interp(t, t_knots, bw[:, 1])], axis=1)
        lead = speeds.push_lead * lag_s * speeds.push
        for j, i in enumerate(seg):
            if kinds[i] == PUSH and t[j] < t_knots[i + 1] - 1e-9 and lead > 0:
                step = wp[i + 1] - wp[i]
                cmds[j] += lead * step / np.linalg.norm(step)
        return Schedule(cmds, [kinds[i] for i in seg], box)

    def commands(self, fps: float, speeds: Speeds = Speeds()) -> np.ndarray:
        """Finger position commands at t = 1/fps, 2/fps, ... until the end of the path (last = final)."""
        return self.schedule(fps, speeds).commands

    def to_json(self) -> dict:
        return {
            "method": self.method,
            "cost": self.cost,
            "lower_bound": self.lower_bound,
            "solve_time_s": self.solve_time_s,
            "modes": self.modes,
            "num_pushes": self.num_pushes,
            "finger_waypoints": self.finger_waypoints.tolist(),
            "box_waypoints": self.box_waypoints.tolist(),
            "segment_kinds": [str(k) for k in self.segment_kinds],
            "box_final": self.box_final.tolist(),
            "goal": self.goal.tolist(),
            "candidates": self.candidates,
            **self.extra,
        }


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
