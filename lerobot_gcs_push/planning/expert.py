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
from lerobot_gcs_push.planning.plan import DWELL, FREE, PUSH, Plan, Schedule, Speeds
from lerobot_gcs_push.planning.rules import BOX_RULE, TURNING_RULE, ReplanRule  # noqa: F401 (their users import them here)
from lerobot_gcs_push.planning.search import (  # noqa: F401 (the constants' users import them here)
    RING_TURNS,
    STAGE_MARGIN_M,
    clear,
    detours,
    find_plan,
    ring_path,
    staging_point,
)

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
        """`search.find_plan` with this expert's options: to the goal, from the staging point, to waypoints,
        from round the staging circle; within `fine_within` of the goal, a correction first."""
        return find_plan(
            self.planner,
            slider,
            finger,
            stage_first=self.stage_first,
            replace_detours=self.replace_detours,
            fine_within=self.fine_within,
        )

    def _fine_speeds(self, plan: Plan) -> Speeds:
        """The speeds, the push slowed to last FINE_PUSH_ACTIONS actions: a correction's push of a few cm ran
        at the push speed within one action, which gym-pusht's steered agent never made (the T moved 3 mm
        a push where 7 cm were planned)."""
        push = [i for i, kind in enumerate(plan.segment_kinds) if kind == PUSH]
        length = float(np.sum(np.linalg.norm(np.diff(plan.finger_path[push[0] : push[-1] + 2], axis=0), axis=1)))
        return replace(self.speeds, push=min(self.speeds.push, max(length, 1e-3) * self.fps / FINE_PUSH_ACTIONS))

    def detours(self, slider, plan: Plan) -> bool:
        """`search.detours`: whether the plan takes the slider too far from its goal on the way."""
        return detours(self.planner, slider, plan)

    def ring_path(self, slider, staged, turn: float) -> list[np.ndarray]:
        """`search.ring_path`: the finger's way round the staging circle by `turn` (rad)."""
        return ring_path(self.planner, slider, staged, turn)

    def staging_point(self, slider, finger) -> np.ndarray | None:
        """`search.staging_point`: where a far finger goes first, or None."""
        return staging_point(self.planner.scene, slider, finger)

    def _clear(self, pose, point) -> bool:
        return clear(self.planner.scene, pose, point)

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


def _sideways(miss: np.ndarray, along: np.ndarray) -> np.ndarray:
    """The part of `miss` across the direction `along` (all of it where `along` is nil)."""
    norm = float(np.linalg.norm(along))
    return miss if norm < 1e-12 else miss - (miss @ along) / norm**2 * along
