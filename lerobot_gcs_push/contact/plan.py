"""A plan for a rotating slider: the mode sequence, slider poses and finger positions at every knot,
the pushes' contact points and displacements, the cost and the relaxation's certified lower bound."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from lerobot_gcs_push.contact.face_contact import finger_body
from lerobot_gcs_push.contact.graph import ContactGraph
from lerobot_gcs_push.contact.model import PushModel
from lerobot_gcs_push.contact.rounding import Restriction
from lerobot_gcs_push.planner.plan import APPROACH, FREE, PUSH, Schedule, SegmentKind, Speeds


@dataclass
class ContactPlan:
    method: str
    cost: float  # the objective: sum of squared knot-to-knot displacements (m^2), rotation as chord^2 r_max^2
    # Certified by the graph relaxation's checked dual (relaxation.certify); None: uncertified (the baseline,
    # which certifies nothing, or a solve whose dual residual was too large to vouch for its bound).
    lower_bound: float | None
    solve_time_s: float
    modes: list[str]
    slider_poses: np.ndarray  # (K, 3): x, y, heading at each knot
    finger_path: np.ndarray  # (K, 2): finger centre in the world at each knot
    segment_kinds: list[SegmentKind]  # (K - 1,): FREE or PUSH
    goal: np.ndarray  # (3,): the goal pose the plan ends at (the shape's nearest symmetric copy)
    pushes: list[dict] = field(default_factory=list)  # face, lam, fn, ft (and knot poses x, y, c, s) per contact
    free_knots: list[np.ndarray] = field(default_factory=list)  # finger knots in the slider frame per free mode
    candidates: int = 1
    extra: dict = field(default_factory=dict)

    @property
    def certified(self) -> bool:
        return self.lower_bound is not None

    @property
    def gap(self) -> float | None:
        """(cost - bound) / cost: how far from optimal the plan can be, at most; None when uncertified."""
        if self.lower_bound is None:
            return None
        return float((self.cost - self.lower_bound) / self.cost) if self.cost > 0 else 0.0

    def gap_text(self) -> str:
        """The gap in per cent, or 'uncertified'."""
        return "uncertified" if self.gap is None else f"{100 * self.gap:.1f} %"

    @property
    def slider_final(self) -> np.ndarray:
        return self.slider_poses[-1]

    @property
    def finger_length(self) -> float:
        return float(np.sum(np.linalg.norm(np.diff(self.finger_path, axis=0), axis=1)))

    def _times(self, speeds: Speeds, path=None, kinds=None) -> np.ndarray:
        path = self.finger_path if path is None else path
        seg = np.linalg.norm(np.diff(path, axis=0), axis=1)
        v = np.array([speeds.of(k) for k in (self.segment_kinds if kinds is None else kinds)])
        return np.concatenate([[0.0], np.cumsum(seg / v)])

    def duration(self, speeds: Speeds | None = None) -> float:
        return float(self._times(speeds or Speeds())[-1])

    def with_approaches(self, distance: float, clear: Callable | None = None) -> tuple:
        """(finger path, slider poses, segment kinds) with each push after free motion reached along its
        face's normal: the free motion ends `distance` off the contact point, an APPROACH segment covers
        the rest. An approach point that is not `clear(pose, point)`, or not reached clear of the slider
        (sampled), is left out: that push is reached as planned."""
        path, poses, kinds = [self.finger_path[0]], [self.slider_poses[0]], []
        run = 0
        for i, kind in enumerate(self.segment_kinds):
            starts_push = kind == PUSH and i > 0 and self.segment_kinds[i - 1] != PUSH
            if starts_push and distance > 0 and run < len(self.pushes) and "normal" in self.pushes[run]:
                pose, contact = self.slider_poses[i], self.finger_path[i]
                c, s = np.cos(pose[2]), np.sin(pose[2])
                n = np.asarray(self.pushes[run]["normal"], float)
                pre = contact + distance * np.array([c * n[0] - s * n[1], s * n[0] + c * n[1]])
                ok = clear is None or all(
                    clear(pose, (1 - w) * self.finger_path[i - 1] + w * pre) for w in np.linspace(0, 1, 15)
                )
                if ok:  # path[-1] is the contact point: replace the free segment's end by the approach point
                    path[-1], kinds[-1] = pre, FREE
                    path.append(contact)
                    poses.append(pose)
                    kinds.append(APPROACH)
            if starts_push or (kind == PUSH and i == 0):
                run += 1
            path.append(self.finger_path[i + 1])
            poses.append(self.slider_poses[i + 1])
            kinds.append(kind)
        return np.array(path), np.array(poses), kinds

    def schedule(
        self,
        fps: float,
        speeds: Speeds | None = None,
        lag_s: float = 0.0,
        approach_m: float = 0.0,
        clear: Callable | None = None,
    ) -> Schedule:
        """Commands at t = 1/fps, 2/fps, ..., the segment kind at each, and where the plan has the slider
        then (x, y, heading: the closed-loop expert's reference). `lag_s` (Scene.push_lag_s) turns on the
        box planner's push lead: the finger trails its command by v * lag_s while pushing, so commands run
        that far ahead along the push, but never past the push's end (a short correction near the goal
        would overshoot by the whole lead). `approach_m` > 0 reaches each push along its face's normal,
        the last `approach_m` at the approach speed (`with_approaches`; `clear(pose, point)` says where the
        finger may stand): arriving along its free path at free speed, the finger touched the T 5-10 cm
        from the planned contact and near the goal the push turned it away (experiments/rotation/).
        No dwell: the rotating slider's plans chain pushes (its closed-loop expert replans where a push
        ended elsewhere)."""
        speeds = speeds or Speeds()
        path, slider, kinds = self.with_approaches(approach_m, clear)
        t_knots = self._times(speeds, path, kinds)
        n = max(1, int(np.ceil(t_knots[-1] * fps - 1e-9)))
        t = np.minimum(np.arange(1, n + 1) / fps, t_knots[-1])
        cmds = np.stack([np.interp(t, t_knots, path[:, i]) for i in range(2)], axis=1)
        poses = np.stack([np.interp(t, t_knots, slider[:, i]) for i in range(3)], axis=1)
        if not kinds:
            return Schedule(cmds, [FREE] * n, poses)
        seg = np.clip(np.searchsorted(t_knots, t - 1e-12) - 1, 0, len(kinds) - 1)
        lead = speeds.push_lead * lag_s * speeds.push
        if lead > 0:
            for a, b in _push_runs(kinds):
                run = path[a : b + 1]
                arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(run, axis=0), axis=1))])
                on = (t > t_knots[a] + 1e-12) & (t < t_knots[b] - 1e-9)  # as the segment kinds: (start, end]
                ahead = np.minimum(np.interp(t[on], t_knots[a : b + 1], arc) + lead, arc[-1])
                cmds[on] = np.stack([np.interp(ahead, arc, run[:, i]) for i in range(2)], axis=1)
        return Schedule(cmds, [kinds[i] for i in seg], poses)

    def commands(self, fps: float, speeds: Speeds | None = None) -> np.ndarray:
        """Finger position commands at t = 1/fps, 2/fps, ... along the plan (no push lead)."""
        return self.schedule(fps, speeds).commands

    def to_json(self) -> dict:
        return {
            "method": self.method,
            "cost": self.cost,
            "lower_bound": self.lower_bound,
            "certified": self.certified,
            "gap": self.gap,
            "solve_time_s": self.solve_time_s,
            "modes": self.modes,
            "slider_poses": self.slider_poses.tolist(),
            "finger_path": self.finger_path.tolist(),
            "segment_kinds": [str(k) for k in self.segment_kinds],
            "goal": self.goal.tolist(),
            "pushes": [{k: np.asarray(v).tolist() for k, v in p.items()} for p in self.pushes],
            "free_knots": [np.asarray(q).tolist() for q in self.free_knots],
            "candidates": self.candidates,
            **self.extra,
        }


def _push_runs(kinds) -> list[tuple[int, int]]:
    """(first knot, last knot) of each run of consecutive push segments."""
    runs, start = [], None
    for i, kind in enumerate([*kinds, FREE]):
        if kind == PUSH and start is None:
            start = i
        elif kind != PUSH and start is not None:
            runs.append((start, i))
            start = None
    return runs


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
