"""The planner through contact as the rotating envs' expert, open-loop (one plan, executed) or closed-loop
(replanning from the measured pose whenever the slider strays from the plan).

A planned push, replayed in the sim, ends where the plan says (the contact modes model the round finger's
rolling contact); a whole plan executed open-loop still strays, by the finger's lag at each push's start
and end and by pushes at the friction cone's edge that slip: 1 of 20 bench starts of `GcsPushBoxSE2-v0`
reach coverage so, against 20 of 20 closed-loop (experiments/rotation/README.md has the rules tried on
the way). The expert reads the true state from `info`.
"""

from __future__ import annotations

import time

import numpy as np

from lerobot_gcs_push.contact.plan import ContactPlan
from lerobot_gcs_push.contact.planner import ContactPlanner, PlanningError
from lerobot_gcs_push.planner.plan import FREE, PUSH, Schedule, Speeds
from lerobot_gcs_push.scene import wrap_angle

PUSH_STRAY = 5.0
# Shares of the way from the slider to its goal where a plan is sought when none reaches the goal.
WAYPOINTS = (0.5, 0.25)
# The last metres before a push that follows free motion run along the face's normal at the approach
# speed. Arriving along its free path, the finger touched the T 5-10 cm from the planned contact and near
# the goal turned it away; 0.2 m (the box planner's transition buffer) doubled the T's episode time, since
# every replan backs the finger off its face. 16 sobol starts (experiments/rotation/README.md).
APPROACH_M = 0.05


def plannable(planner: ContactPlanner, pose, finger, clearance: float = 1e-3) -> tuple[np.ndarray, np.ndarray]:
    """A measured state the planner accepts: the slider's centre within its reach, the finger `clearance`
    inside the nearest free-space piece (in contact, or off a corner where no piece reaches, it is not)."""
    model = planner.model
    pose = np.asarray(pose, float).copy()
    pose[:2] = np.clip(pose[:2], -model.reach, model.reach)
    c, s = np.cos(pose[2]), np.sin(pose[2])
    d = np.asarray(finger, float) - pose[:2]
    q = np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]])
    if any(r.contains(q) for r in planner.regions):
        return pose, np.asarray(finger, float).copy()
    q = min((r.project(q, clearance) for r in planner.regions), key=lambda p: float(np.linalg.norm(p - q)))
    return pose, pose[:2] + np.array([c * q[0] - s * q[1], s * q[0] + c * q[1]])


class ContactExpert:
    """`rollout.Policy` over a rotating slider's true pose (`info["slider_pose"]`) and finger.

    `config` is the box experts' `ExpertConfig`: closed loop, every `replan_every` steps, the expert
    replans when the slider's pose is more than `replan_tolerance` from the plan's pose at that step
    (distance in m plus heading error times the slider's radius), or when the plan has run out."""

    def __init__(self, planner: ContactPlanner, fps: float, config, speeds: Speeds | None = None):
        self.planner, self.fps = planner, fps
        self.config = config  # an expert.ExpertConfig, made by expert.make_expert (which imports this module)
        self.speeds = speeds or Speeds()
        self.plans: list[ContactPlan] = []
        self.plan_time_s = 0.0
        self.failed_replans = 0
        self._schedule: Schedule | None = None
        self._k = self._steps = 0

    @property
    def plan(self) -> ContactPlan | None:
        return self.plans[0] if self.plans else None

    def reset(self, obs, info: dict, seed: int | None = None) -> None:
        """Plan from the episode's initial state (the seed is unused: plans depend on their query only)."""
        self.plans, self.plan_time_s, self._steps, self.failed_replans = [], 0.0, 0, 0
        self._failed_at = None
        self.planner.warm_up()  # the relaxation's one-time compile is not the episode's plan time
        try:
            self._replan(info)
        except PlanningError:  # no plan from here (1 start in 10 of the T's): the finger holds; a failed run
            self._failed(info)
            finger = np.asarray(info["finger"], float)
            self._schedule, self._k = Schedule(finger[None], [FREE], np.asarray(info["slider_pose"], float)[None]), 0
        self._initial_plan_time_s = self.plan_time_s

    def episode_summary(self) -> dict:
        return {
            "plan_time_s": self._initial_plan_time_s,
            "plan": self.plan,
            "replans": max(len(self.plans) - 1, 0),
            "failed_replans": self.failed_replans,
        }

    def _replan(self, info: dict) -> None:
        pose, finger = plannable(self.planner, info["slider_pose"], info["finger"])
        t0 = time.perf_counter()
        try:
            plan = self._plan(pose, finger)
        finally:
            self.plan_time_s += time.perf_counter() - t0
        self.plans.append(plan)
        self._schedule = plan.schedule(self.fps, self.speeds, self.planner.scene.push_lag_s, APPROACH_M, self._clear)
        self._k = 0

    def _plan(self, pose, finger) -> ContactPlan:
        """A plan to the goal or, where rounding finds none, to a waypoint part of the way there (the next
        replan goes on from it). A T by gym-pusht's wall, half a turn from its goal (seed 2027's sixth
        start), had no plan to the goal, one halfway in 15 s and one a quarter of the way in 10 s."""
        try:
            return self.planner.plan(pose, finger)
        except PlanningError:
            if not WAYPOINTS:
                raise
            goal = self.planner.query(pose, finger)[2]
        for i, share in enumerate(WAYPOINTS):
            try:
                return self.planner.plan(pose, finger, pose + share * (goal - pose))
            except PlanningError:
                if i == len(WAYPOINTS) - 1:
                    raise

    def _clear(self, pose, point) -> bool:
        scene = self.planner.scene
        return scene.shape.signed_distance(pose, point) >= scene.finger_radius - 1e-6

    def act(self, obs, info: dict) -> np.ndarray:
        if self.config.mode == "closed-loop" and self._should_replan(info):
            try:
                self._replan(info)
            except PlanningError:  # a state the planner cannot plan from: keep to the old plan, try again later
                self._failed(info)
        sched = self._schedule
        cmd = sched.commands[min(self._k, len(sched) - 1)]
        self._k += 1
        self._steps += 1
        return cmd.copy()

    def strayed_by(self, pose) -> float:
        """How far the slider is from where the plan has it now: metres plus radians times r_max."""
        ref = self._schedule.box[min(max(self._k - 1, 0), len(self._schedule) - 1)]
        pose = np.asarray(pose, float)
        return float(np.linalg.norm(pose[:2] - ref[:2]) + self.planner.model.r_max * abs(wrap_angle(pose[2] - ref[2])))

    def _failed(self, info: dict) -> None:
        self.failed_replans += 1
        self._failed_at = _state(info)

    def _should_replan(self, info: dict) -> bool:
        cfg, sched = self.config, self._schedule
        if not self._steps or self._steps % cfg.replan_every or len(self.plans) + self.failed_replans > cfg.max_replans:
            return False
        # A plan depends on its query only: from the state where planning failed it fails again. In gym-pusht
        # a T no plan could move sat still for 30 s of 25 s replans (23 min of wall time, seed 4700's start 32).
        if self._failed_at is not None and np.allclose(_state(info), self._failed_at, atol=1e-6):
            return False
        if self._k >= len(sched):
            return True  # ran out without the env declaring success: start again from here
        # Judged at the tolerance where the plan has the slider at rest after one of its pushes: within a
        # push the finger's lag moves it off the reference, and before the first the last plan's push is
        # still draining into it. Judged so everywhere, a T replanned every second, each new plan backing
        # the finger off the face it pushed on, and crept to the goal at a quarter of the push speed (5 of
        # 10 demonstrations failed so).
        # Within a push, only a slider that has turned away (PUSH_STRAY times the tolerance) is replanned.
        i = min(self._k, len(sched) - 1)
        at_rest = sched.kinds[i] != PUSH and PUSH in sched.kinds[:i]
        return self.strayed_by(info["slider_pose"]) > cfg.replan_tolerance * (1.0 if at_rest else PUSH_STRAY)


def _state(info: dict) -> np.ndarray:
    return np.concatenate([np.asarray(info["slider_pose"], float), np.asarray(info["finger"], float)])


class PixelActions:
    """An expert in metres acting in a target that takes pixel actions (`scene.frame`): its commands are
    mapped to pixels, everything else (its state from `info`, plans, summaries) is the expert's own.
    `track(info, point)`, if given, turns the point where the expert wants the finger one action later into
    the action that puts it there (`pusht_agent.target_for` for gym-pusht's PD agent)."""

    def __init__(self, expert, frame, track=None):
        self.expert, self.frame, self.track = expert, frame, track

    def __getattr__(self, name):
        return getattr(self.expert, name)

    def reset(self, obs, info: dict, seed: int | None = None) -> None:
        self.expert.reset(obs, info, seed)

    def act(self, obs, info: dict) -> np.ndarray:
        point = self.frame.to_px(self.expert.act(obs, info))
        return point if self.track is None else self.track(info, point)
