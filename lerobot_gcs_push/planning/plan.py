"""The one plan type every planner returns: the mode sequence, the finger's path and the slider's poses at
its knots, the cost and its certified bound, and the timing that turns it into commands at an env's rate."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from enum import StrEnum

import numpy as np

from lerobot_gcs_push.planning.timing import Timing


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
    # Over how much of a run of pushes (m) the lead builds up from nothing (0: at once). A finger at rest
    # has no lag to make up: the whole lead at a push's start throws it at the face.
    push_lead_ramp_m: float = 0.0
    # While pushing, this share of the finger's sideways miss of its last command is added to the next. A PD
    # finger gives way sideways to the face's force (the lead makes up the miss along the push only): the
    # Drake T's finger slid 0.15-0.2 m along the face off the planned contact and the T stayed behind.
    push_lateral_gain: float = 0.0
    # Bound on the finger's acceleration along its path (m/s^2; `planning.timing`): every plan starts and
    # ends at rest and slows for its corners. 0: none, the speed jumps at every knot.
    accel: float = 0.0
    # The last `arrive_m` of a plan's last push at `arrive` at most (m/s; 0: the push's speed). gym-pusht's T
    # stops when the push does, so a push that arrives fast leaves a policy one frame to stop in: the position
    # pool's T crossed the goal's band (about 2 px each way) at 3.3 px a frame, median, and the benchmark's
    # policies ended short of it or past it (experiments/pusht/README.md, "The T's arrival").
    arrive: float = 0.0
    arrive_m: float = 0.0

    def of(self, kind: SegmentKind) -> float:
        return getattr(self, kind)

    def __post_init__(self) -> None:
        may_be_nil = {"push_dwell_s", "push_lead", "push_lead_ramp_m", "push_lateral_gain"}
        may_be_nil |= {"accel", "arrive", "arrive_m"}  # 0: no bound, no slow arrival
        for k, v in asdict(self).items():
            if not (v >= 0 if k in may_be_nil else v > 0):
                raise ValueError(f"Speeds.{k} must be positive, got {v}")


@dataclass
class Schedule:
    """Commands at t = 1/fps, 2/fps, ...; the segment kind active at each; where the plan has the slider
    then ((N, 2) for the box, (N, 3) with the heading for a slider that turns): the closed-loop reference."""

    commands: np.ndarray  # (N, 2)
    kinds: list[SegmentKind]  # (N,)
    slider: np.ndarray

    def __len__(self) -> int:
        return len(self.commands)


@dataclass
class Plan:
    method: str
    # The objective: the box's finger path length (m); through contact, the sum of squared knot-to-knot
    # displacements (m^2), rotation as chord^2 r_max^2.
    cost: float
    # Certified: the box's relaxation or MICP, the graph relaxation's checked dual through contact. None:
    # uncertified (the baseline, or a solve whose dual residual was too large to vouch for its bound).
    lower_bound: float | None
    solve_time_s: float
    modes: list[str]
    slider_poses: np.ndarray  # (K, 2) box position, or (K, 3) x, y, heading, when the finger is at each knot
    finger_path: np.ndarray  # (K, 2): finger centre in the world at each knot
    segment_kinds: list[SegmentKind]  # (K - 1,)
    goal: np.ndarray  # where the plan ends: the box's goal, or the goal pose's nearest symmetric copy
    pushes: list[dict] = field(default_factory=list)  # through contact: face, lam, fn, ft, knot poses, normal
    free_knots: list[np.ndarray] = field(default_factory=list)  # through contact: slider-frame finger knots
    candidates: int = 1  # paths whose restriction was solved
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
    def num_pushes(self) -> int:
        return len(_push_runs(self.segment_kinds))

    @property
    def finger_length(self) -> float:
        return float(np.sum(np.linalg.norm(np.diff(self.finger_path, axis=0), axis=1)))

    def preceded_by(self, finger, *via) -> Plan:
        """This plan with the finger first moving straight (free) from `finger`, through the points `via` in
        turn, to where the plan starts, the slider at rest meanwhile. Cost and bound stay the plan's own,
        from its start; `extra` says so."""
        points = np.array([finger, *via], float).reshape(-1, 2)
        return replace(
            self,
            finger_path=np.vstack([points, self.finger_path]),
            slider_poses=np.vstack([np.repeat(self.slider_poses[:1], len(points), axis=0), self.slider_poses]),
            segment_kinds=[FREE] * len(points) + list(self.segment_kinds),
            extra={**self.extra, "staged_from": points[0].tolist()},
        )

    def with_approaches(self, distance: float, clear: Callable | None = None) -> tuple:
        """(finger path, slider poses, segment kinds) with each push after free motion reached along its
        face's normal: the free motion ends `distance` off the contact point, an APPROACH segment covers
        the rest. An approach point that is not `clear(pose, point)`, or not reached clear of the slider
        (sampled), is left out: that push is reached as planned. Only plans through contact carry their
        pushes' normals; the box's plans have their approaches already."""
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

    def _knots(self, speeds: Speeds, approach_m: float = 0.0, clear: Callable | None = None):
        """Knots (finger, slider, the kind of the segment ending at each) with a dwell after each run of
        pushes, and their `Timing`."""
        path, slider, kinds = self.with_approaches(approach_m, clear)
        fp, sp, ks, vmax, hold = [path[0]], [slider[0]], [], [], []
        for i, kind in enumerate(kinds):
            fp.append(path[i + 1])
            sp.append(slider[i + 1])
            ks.append(kind)
            vmax.append(speeds.of(kind))
            hold.append(0.0)
            ends_push = kind == PUSH and (i + 1 == len(kinds) or kinds[i + 1] != PUSH)
            if ends_push and speeds.push_dwell_s > 0:
                fp.append(path[i + 1])
                sp.append(slider[i + 1])
                ks.append(DWELL)
                vmax.append(speeds.push)
                hold.append(speeds.push_dwell_s)
        _slow_arrival(fp, sp, ks, vmax, hold, speeds)
        fp = np.array(fp)
        return fp, np.array(sp), ks, Timing(fp, np.array(vmax), np.array(hold), speeds.accel)

    def duration(self, speeds: Speeds | None = None) -> float:
        """Commanded execution time (s), dwells included."""
        return self._knots(speeds or Speeds())[3].duration

    def schedule(
        self,
        fps: float,
        speeds: Speeds | None = None,
        lag_s: float = 0.0,
        approach_m: float = 0.0,
        clear: Callable | None = None,
    ) -> Schedule:
        """Commands at t = 1/fps, 2/fps, ..., the segment kind at each, and where the plan has the slider then.

        `lag_s` (Scene.push_lag_s) turns on the push lead: the finger trails its command by about v * lag_s
        while pushing, so commands run `push_lead` of that ahead along each run of pushes. Past the run's
        end only where a dwell follows, in which the finger settles back onto the end point (the box: the
        box then stops where the plan ends); otherwise never past it (a short correction near the goal would
        overshoot by the whole lead). `approach_m` > 0 reaches each push through contact along its face's
        normal, the last `approach_m` at the approach speed (`with_approaches`; `clear(pose, point)` says
        where the finger may stand): arriving along its free path at free speed, the finger touched the T
        5-10 cm from the planned contact and near the goal the push turned it away (experiments/rotation/)."""
        speeds = speeds or Speeds()
        path, slider, kinds, timing = self._knots(speeds, approach_m, clear)
        t_knots = timing.times
        n = max(1, int(np.ceil(t_knots[-1] * fps - 1e-9)))
        t = np.minimum(np.arange(1, n + 1) / fps, t_knots[-1])
        if not kinds:
            return Schedule(np.repeat(path[:1], n, axis=0), [FREE] * n, np.repeat(slider[:1], n, axis=0))
        at, share = timing.where(t)
        cmds = path[at] + share[:, None] * (path[at + 1] - path[at])
        poses = slider[at] + share[:, None] * (slider[at + 1] - slider[at])
        seg = np.clip(np.searchsorted(t_knots, t - 1e-12) - 1, 0, len(kinds) - 1)  # a segment's kind: (start, end]
        lead = speeds.push_lead * lag_s * speeds.push
        if lead > 0:
            for a, b in _push_runs(kinds):
                run = path[a : b + 1]
                arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(run, axis=0), axis=1))])
                on = (t > t_knots[a] + 1e-12) & (t < t_knots[b] - 1e-9)  # as the segment kinds: (start, end]
                done = arc[at[on] - a] + share[on] * (arc[at[on] - a + 1] - arc[at[on] - a])
                ramp = np.clip(done / speeds.push_lead_ramp_m, 0.0, 1.0) if speeds.push_lead_ramp_m > 0 else 1.0
                ahead = done + lead * ramp
                if speeds.push_dwell_s <= 0:
                    ahead = np.minimum(ahead, arc[-1])
                cmd = np.stack([np.interp(ahead, arc, run[:, i]) for i in range(2)], axis=1)
                past = ahead > arc[-1]
                step = run[-1] - run[-2]
                if past.any() and np.linalg.norm(step) > 0:  # along the last push's direction
                    cmd[past] = run[-1] + (ahead[past] - arc[-1])[:, None] * step / np.linalg.norm(step)
                cmds[on] = cmd
        return Schedule(cmds, [kinds[i] for i in seg], poses)

    def commands(self, fps: float, speeds: Speeds | None = None) -> np.ndarray:
        """Finger position commands at t = 1/fps, 2/fps, ... along the plan (no push lead; last = final)."""
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
            "num_pushes": self.num_pushes,
            "finger_path": self.finger_path.tolist(),
            "slider_poses": self.slider_poses.tolist(),
            "slider_final": self.slider_final.tolist(),
            "segment_kinds": [str(k) for k in self.segment_kinds],
            "goal": self.goal.tolist(),
            "pushes": [{k: np.asarray(v).tolist() for k, v in p.items()} for p in self.pushes],
            "free_knots": [np.asarray(q).tolist() for q in self.free_knots],
            "candidates": self.candidates,
            **self.extra,
        }


def _slow_arrival(fp: list, sp: list, ks: list, vmax: list, hold: list, speeds: Speeds) -> None:
    """In place: the knots' last push split `speeds.arrive_m` before its end, the piece after at
    `speeds.arrive` at most (the whole push where it is shorter); the slider's pose at the new knot on the
    line between its two, as the schedule interpolates it."""
    if speeds.arrive <= 0 or speeds.arrive_m <= 0 or PUSH not in ks:
        return
    i = len(ks) - 1 - ks[::-1].index(PUSH)  # segment i runs from knot i to knot i + 1
    a, b = np.asarray(fp[i], float), np.asarray(fp[i + 1], float)
    length = float(np.linalg.norm(b - a))
    if length <= speeds.arrive_m:
        vmax[i] = min(vmax[i], speeds.arrive)
        return
    w = 1.0 - speeds.arrive_m / length
    fp.insert(i + 1, a + w * (b - a))
    sp.insert(i + 1, (1 - w) * np.asarray(sp[i], float) + w * np.asarray(sp[i + 1], float))
    ks.insert(i + 1, PUSH)
    vmax.insert(i + 1, min(vmax[i], speeds.arrive))
    hold.insert(i + 1, 0.0)


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
