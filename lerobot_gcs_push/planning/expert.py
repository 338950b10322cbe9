"""The one expert: any `Planner`'s plans, open loop (the first plan, executed) or closed loop (replanned from
the measured state whenever the slider strays from the plan), as a `rollout.Policy` over the env's true
state in `info` (`slider_pose` and `finger`); the env knows nothing about it.

What differs between scenes is data the scene's slider kind chooses (`factory.make_expert`): the speeds, and the
`ReplanRule` that says how far the slider may stray where.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np

from lerobot_gcs_push.planning.interface import Planner, PlanningError
from lerobot_gcs_push.planning.plan import DWELL, FREE, PUSH, RETREAT, Plan, Schedule, Speeds
from lerobot_gcs_push.planning.rules import BOX_RULE, TURNING_RULE, ReplanRule  # noqa: F401 (their users import them here)
from lerobot_gcs_push.scene import wrap_angle

# Shares of the way from the slider to its goal where a plan is sought when none reaches the goal. A T by
# gym-pusht's wall, half a turn from its goal (seed 2027's sixth start), had no plan to the goal, one
# halfway in 15 s and one a quarter of the way in 10 s.
WAYPOINTS = (0.5, 0.25)
# A finger far from the slider. Where no plan was found on gym-pusht (seed 4700's 33rd start, seeds 9763 and
# 9777: fingers 2.2-3.6 m from the T), SNOPT found every sampled path's restriction infeasible; from 1.6 m
# off the T, on any of six sides, seed 9777's T planned, and seed 9763's (2.9 rad from its goal) planned a
# quarter of the way, which from the finger's own place it had not. So where no plan is found from a far
# finger, the finger first goes straight at the slider, to this far beyond the reach of both (the slider's
# radius about its pivot plus the finger's), and the plans, to the goal and then to the waypoints, start there.
# `stage_first` plans from there first: on gym-pusht, where the agent starts anywhere, the first plan from the
# agent's own place failed on 5 of 12 resets (seeds 10340-10351: every sampled restriction infeasible, 21-25
# tried); on 24 more (seeds 10500-10523), alternated with the agent's own place first, it took 20 % less CPU
# (173.8 against 216.3 s, 58 plans against 70) and 9 % fewer frames (88.8 against 98.0 a start), all 24 both ways.
STAGE_MARGIN_M = 0.1
# Where no plan is found from a far finger's staging point, nor from its own place, nor to a waypoint, the
# staging point turned about the slider by these angles (rad), in turn: from the staging circle's other side
# the rounding meets other restrictions. Seed 11340's sixth start on gym-pusht (the T 2.8 rad from its goal,
# the agent just beyond the circle) planned from none of those; from the points 60, 180, 240 and 300 degrees
# round, it planned (120 degrees: not), and the agent never moved for 30 s without them.
RING_TURNS = tuple(np.deg2rad([60.0, -60.0, 120.0, -120.0, 180.0]))
# A plan detours when its slider goes farther from the goal than DETOUR_RATIO times, and DETOUR_MARGIN (m +
# rad x r_max) beyond, where it is now. Near the goal the rounding's plans from the finger's own place do: the
# Drake T's four failures of seed 5155 came within 0.1-0.3 of the goal and were pushed up to 2.5 away (from
# 0.12 off, every restriction that solved took the T 0.25-0.76 away). From points round the staging circle
# the same states planned without a detour, and cheaper (0.40 against 0.80, 0.25 against 3.83, 0.35 against
# 3.32): so a detouring plan is replaced by the first that does not, from the circle at the finger's own
# bearing and then turned by RING_TURNS. Far from the goal, plans wind out and back by less than the margins.
DETOUR_RATIO, DETOUR_MARGIN = 1.5, 0.2
# The finger goes round the circle in steps of at most this (rad): each chord comes no nearer the pivot than
# cos(step / 2) = 0.991 of the circle's radius, so it keeps clear of the slider by STAGE_MARGIN_M less 0.9 %
# of that radius (0.086 m on gym-pusht's T).
RING_STEP = np.deg2rad(15.0)
# A correction's finger goes to this far off its contact point along the face's normal (m) before the
# approach, and backs off this far after its push, so that the next correction's way starts clear of the slider.
FINE_STANDOFF_M, FINE_RETREAT_M = 0.15, 0.1
# A correction's push lasts at least this many actions (`PlanExpert._fine_speeds`).
FINE_PUSH_ACTIONS = 4
# How close (m, rad) a state is to the last one planned from to count as the same query.
QUERY_ATOL = 1e-3


class PlanExpert:
    """`rollout.Policy` running `planner`'s plans at `fps`. `config` is a `factory.ExpertConfig` (mode,
    replan_every, replan_tolerance, max_replans)."""

    def __init__(
        self,
        planner: Planner,
        fps: float,
        config,
        speeds: Speeds | None = None,
        rule=BOX_RULE,
        stage_first=False,
        replace_detours=True,
        fine_within=0.0,
    ):
        self.planner, self.fps, self.config, self.rule = planner, fps, config, rule
        self.stage_first, self.replace_detours = stage_first, replace_detours
        # Within this distance of the goal (`Planner.distance`), a single push on the linearised model
        # (`ContactPlanner.corrections`) before any plan; 0: never.
        self.fine_within = fine_within
        self.speeds = speeds or Speeds()
        self.plans: list[Plan] = []
        self.plan_time_s = 0.0
        self.failed_replans = 0
        self._schedule: Schedule | None = None
        self._queried_at = None
        self._k = self._steps = 0

    @property
    def plan(self) -> Plan | None:
        """The first plan of the episode (the open-loop plan)."""
        return self.plans[0] if self.plans else None

    def reset(self, obs, info: dict, seed: int | None = None) -> None:
        """Plan from the episode's initial state (the seed is unused: a plan depends on its query only)."""
        self.plans, self.plan_time_s, self._steps, self.failed_replans = [], 0.0, 0, 0
        self._queried_at = None
        self.planner.warm_up()  # a one-time compile is not the episode's plan time
        try:
            self._replan(info)
        except PlanningError:  # no plan from here (1 start in 10 of the T's): the finger holds; a failed run
            self.failed_replans += 1
            finger = np.asarray(info["finger"], float)
            self._schedule, self._k = Schedule(finger[None], [FREE], self._slider(info)[None]), 0
        self._initial_plan_time_s = self.plan_time_s

    def _slider(self, info: dict) -> np.ndarray:
        """The planner's slider state in the env's `info`: the scene's slider kind reads it off the pose."""
        return self.planner.scene.kind.state(info["slider_pose"])

    def _state(self, info: dict) -> np.ndarray:
        return np.concatenate([self._slider(info), np.asarray(info["finger"], float)])

    def episode_summary(self) -> dict:
        # Paper IV-B: the plan made before execution is plan time; replanning during it is run time.
        return {
            "plan_time_s": self._initial_plan_time_s,
            "plan": self.plan,
            "replans": max(len(self.plans) - 1, 0),
            "failed_replans": self.failed_replans,
        }

    def act(self, obs, info: dict) -> np.ndarray:
        """The next finger command, given the measured slider and finger."""
        if self.config.mode == "closed-loop" and self._should_replan(info):
            try:
                self._replan(info)
            except PlanningError:  # a state the planner cannot plan from: keep to the old plan, try again later
                self.failed_replans += 1
        sched = self._schedule
        i = min(self._k, len(sched) - 1)
        cmd = sched.commands[i].copy()
        gain = self.speeds.push_lateral_gain
        if gain > 0 and 1 <= self._k < len(sched) and sched.kinds[i] == PUSH:
            sent = sched.commands[i - 1]
            cmd += gain * _sideways(sent - np.asarray(info["finger"], float), cmd - sent)
        self._k += 1
        self._steps += 1
        return cmd

    def ahead(self, n: int) -> np.ndarray:
        """The command the plan sends n - 1 actions after the one `act` just returned (where it wants the
        finger n actions on): the last one past the plan's end."""
        sched = self._schedule
        return sched.commands[min(max(self._k - 1, 0) + n - 1, len(sched) - 1)].copy()

    def _replan(self, info: dict) -> None:
        self._queried_at = self._state(info)
        slider, finger = self.planner.plannable(self._slider(info), info["finger"])
        t0 = time.perf_counter()
        try:
            plan = self._plan(slider, finger)
        finally:
            self.plan_time_s += time.perf_counter() - t0
        self.plans.append(plan)
        scene = self.planner.scene
        speeds = self._fine_speeds(plan) if plan.method == "fine" else self.speeds
        self._schedule = plan.schedule(self.fps, speeds, scene.push_lag_s, self.rule.approach_m, self._clear)
        self._k = 0

    def _plan(self, slider, finger) -> Plan:
        """A plan to the goal; where none is found, from the staging point the finger goes to first when it
        is far (`staging_point`), to the goal and then to waypoints part of the way there (the next replan
        goes on from one). With `stage_first`, a far finger's plan starts at the staging point first. Where
        none of those is found, from points round the staging circle (`RING_TURNS`), the finger going round.
        Within `fine_within` of the goal, a correction comes first (`_fine_plan`)."""
        goal = self.planner.goal_of(slider)
        if self.fine_within > 0 and self.planner.distance(slider, goal) < self.fine_within:
            plan = self._fine_plan(slider, finger)
            if plan is not None:
                return plan
        staged = self.staging_point(slider, finger)
        if staged is not None:  # inside a free piece, as any start the planner takes
            staged = self.planner.plannable(slider, staged)[1]
        waypoints = [slider + share * (goal - slider) for share in WAYPOINTS]
        to_goal = [finger] if staged is None else [staged, finger] if self.stage_first else [finger, staged]
        tries = [(start, None) for start in to_goal] + [(finger if staged is None else staged, w) for w in waypoints]
        failure = None
        for start, target in tries:
            try:
                plan = self.planner.plan(slider, start, target)
            except PlanningError as err:
                failure = err
                continue
            if self.replace_detours and start is finger and target is None and self.detours(slider, plan):
                # From the circle at the finger's own bearing (the finger going straight out), then round.
                centre = np.asarray(slider, float)[:2]
                out = centre + (finger - centre) * self._staging_radius() / max(np.linalg.norm(finger - centre), 1e-9)
                turns = (0.0, *RING_TURNS)
                plan = self._plan_round(slider, finger, out, turns, lambda p: not self.detours(slider, p)) or plan
            return plan if start is finger else plan.preceded_by(finger)
        plan = None if staged is None else self._plan_round(slider, finger, staged, RING_TURNS, accept=lambda p: True)
        if plan is None:
            raise failure
        return plan

    def _fine_plan(self, slider, finger) -> Plan | None:
        """The first of the planner's corrections whose way there is clear: the finger goes to its
        standoff (`_way`), in along the face's normal, pushes, and backs off. None where there is none.
        The planner is then an `interface.Corrects`: the slider kinds give a `fine_within` only to those."""
        slider, finger = np.asarray(slider, float), np.asarray(finger, float)
        t0 = time.perf_counter()
        for k in self.planner.corrections(slider):
            contact = k.fingers[0]
            out = k.normal_world(float(slider[2]))
            standoff = contact + FINE_STANDOFF_M * out
            way = self._way(slider, finger, standoff, out)
            if way is None or not self._segment_clear(slider, standoff, contact):
                continue
            end = k.fingers[-1] + FINE_RETREAT_M * k.normal_world(float(k.poses[-1][2]))
            fingers = np.vstack([way, contact, k.fingers[1:], end])
            rest = len(way) + 1
            poses = np.vstack([np.repeat(slider[None], rest, axis=0), k.poses[1:], k.poses[-1:]])
            kinds = [FREE] * len(way) + [PUSH] * (len(k.fingers) - 1) + [RETREAT]
            steps = np.diff(fingers, axis=0)
            return Plan(
                "fine",
                float(np.sum(steps * steps)),
                None,
                time.perf_counter() - t0,
                ["free", f"face_{k.face}", "free"],
                poses,
                fingers,
                kinds,
                self.planner.goal_of(slider),
                pushes=[{"face": k.face, "lam": k.lam, "normal": k.normal}],
                extra={"fine_error": k.error},
            )
        return None

    def _fine_speeds(self, plan: Plan) -> Speeds:
        """The speeds, the push slowed to last FINE_PUSH_ACTIONS actions: a correction's push of a few cm ran
        at the push speed within one action, which gym-pusht's steered agent never made (the T moved 3 mm
        a push where 7 cm were planned)."""
        push = [i for i, kind in enumerate(plan.segment_kinds) if kind == PUSH]
        length = float(np.sum(np.linalg.norm(np.diff(plan.finger_path[push[0] : push[-1] + 2], axis=0), axis=1)))
        return replace(self.speeds, push=min(self.speeds.push, max(length, 1e-3) * self.fps / FINE_PUSH_ACTIONS))

    def _way(self, slider, finger, target, out) -> np.ndarray | None:
        """A way for the finger from `finger` to `target` clear of the slider: straight where that is
        clear, else out to the staging circle, round it, and in along `out` (the target's outward normal,
        whose ray meets the circle); None where no such way is clear."""
        if self._segment_clear(slider, finger, target):
            return np.array([finger, target])
        centre, radius = slider[:2], self._staging_radius()
        # Where the ray target + t out (t >= 0) meets the circle |p - centre| = radius.
        rel = target - centre
        b = float(rel @ out)
        t = -b + math.sqrt(max(b * b - (rel @ rel - radius**2), 0.0))
        inward = target + t * out
        away = finger - centre
        outward = centre + away * radius / max(float(np.linalg.norm(away)), 1e-9)
        if not (self._segment_clear(slider, finger, outward) and self._segment_clear(slider, inward, target)):
            return None
        turn = wrap_angle(math.atan2(*(inward - centre)[::-1]) - math.atan2(*(outward - centre)[::-1]))
        return np.array([finger, *_arc(centre, outward, turn), target])

    def _segment_clear(self, slider, a, b) -> bool:
        return all(self._clear(slider, a + w * (b - a)) for w in np.linspace(0.0, 1.0, 25))

    def detours(self, slider, plan: Plan) -> bool:
        """Whether the plan takes the slider farther from its goal than DETOUR_RATIO and DETOUR_MARGIN allow."""
        near = self.planner.distance(slider, plan.goal)
        farthest = max(self.planner.distance(pose, plan.goal) for pose in plan.slider_poses)
        return farthest > max(DETOUR_RATIO * near, near + DETOUR_MARGIN)

    def _plan_round(self, slider, finger, on_circle, turns, accept) -> Plan | None:
        """The first plan `accept` takes from the staging circle: from the point `on_circle` turned by each of
        `turns` (rad) in turn, the finger going straight to `on_circle` (where that way is clear of the slider)
        and then round the circle; None if there is none."""
        finger = np.asarray(finger, float)
        if not all(self._clear(slider, finger + w * (on_circle - finger)) for w in np.linspace(0.0, 1.0, 25)):
            return None
        on_circle = self.planner.plannable(slider, on_circle)[1]
        for turn in turns:
            arc = self.ring_path(slider, on_circle, turn)
            try:
                plan = self.planner.plan(slider, arc[-1])
            except PlanningError:
                continue
            if accept(plan):
                return plan.preceded_by(finger, *arc[:-1])
        return None

    def ring_path(self, slider, staged, turn: float) -> list[np.ndarray]:
        """The finger's way from the staging point round the staging circle by `turn` (rad): the staging
        point, the points between at most RING_STEP apart, and the end (made plannable)."""
        arc = _arc(np.asarray(slider, float)[:2], np.asarray(staged, float), turn)
        arc[-1] = self.planner.plannable(slider, arc[-1])[1]
        return arc

    def staging_point(self, slider, finger) -> np.ndarray | None:
        """The point on the line from the finger to the slider's centre STAGE_MARGIN_M beyond the reach of
        both (the slider's radius about its pivot plus the finger's), when the finger is farther than that;
        else None. The way there stays outside that circle, so it cannot touch the slider."""
        centre, finger = np.asarray(slider, float)[:2], np.asarray(finger, float)
        radius = self._staging_radius()
        away = float(np.linalg.norm(finger - centre))
        return centre + (finger - centre) * (radius / away) if away > radius else None

    def _staging_radius(self) -> float:
        """The staging circle's radius: the slider's reach about its pivot, the finger's, and STAGE_MARGIN_M."""
        scene = self.planner.scene
        return scene.shape.r_max + scene.finger_radius + STAGE_MARGIN_M

    def _clear(self, pose, point) -> bool:
        scene = self.planner.scene
        return scene.shape.signed_distance(pose, point) >= scene.finger_radius - 1e-6

    def strayed_by(self, slider) -> float:
        """How far the slider is from where the plan has it now (`Planner.distance`)."""
        ref = self._schedule.slider[min(max(self._k - 1, 0), len(self._schedule) - 1)]
        return self.planner.distance(slider, ref)

    def _should_replan(self, info: dict) -> bool:
        cfg, sched, rule = self.config, self._schedule, self.rule
        if not self._steps or self._steps % cfg.replan_every:
            return False
        # Corrections take milliseconds: only plans count against max_replans (at 10 fps a 60 s episode
        # could run 60 corrections).
        if sum(p.method != "fine" for p in self.plans) + self.failed_replans > cfg.max_replans:
            return False
        # A plan depends on its query only: from the state where planning failed it fails again. In gym-pusht
        # a T no plan could move sat still for 30 s of 25 s replans (23 min of wall time, seed 4700's start 32).
        # And from the state a plan was made from, it makes the same plan: in gym-pusht a plan's first push of
        # one step went unrealised, the agent came back to where it had planned, and each replan repeated the
        # plan for 20 s (seed 10400's start 49, 43 replans). So no query twice: the plan moves on, and from
        # elsewhere a new one is sought.
        if self._queried_at is not None and np.allclose(self._state(info), self._queried_at, atol=QUERY_ATOL):
            return False
        if self._k >= len(sched):
            return True  # ran out without the env declaring success: start again from here
        i = min(self._k, len(sched) - 1) if rule.by_next_command else max(self._k - 1, 0)
        if sched.kinds[i] in (PUSH, DWELL):
            share = rule.during_push
        elif PUSH not in sched.kinds[:i]:
            share = rule.before_first_push
        else:
            share = rule.between_pushes
        return math.isfinite(share) and self.strayed_by(self._slider(info)) > cfg.replan_tolerance * share


def _arc(centre: np.ndarray, start: np.ndarray, turn: float) -> list[np.ndarray]:
    """Points from `start` round `centre` by `turn` (rad), at most RING_STEP apart, both ends included."""
    d = start - centre
    steps = max(1, int(np.ceil(abs(turn) / RING_STEP)))
    out = []
    for a in np.linspace(0.0, turn, steps + 1):
        c, s = math.cos(a), math.sin(a)
        out.append(centre + np.array([c * d[0] - s * d[1], s * d[0] + c * d[1]]))
    return out


def _sideways(miss: np.ndarray, along: np.ndarray) -> np.ndarray:
    """The part of `miss` across the direction `along` (all of it where `along` is nil)."""
    norm = float(np.linalg.norm(along))
    return miss if norm < 1e-12 else miss - (miss @ along) / norm**2 * along
