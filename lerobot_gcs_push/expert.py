"""GCS experts that act in `GcsPushBox-v0`: the paper's open-loop policy and a closed-loop one.

Both are plain policies over the env's true state (`info["box"]`, `info["finger"]`); the env knows
nothing about them.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from lerobot_gcs_push.planner import GcsPlanner, Plan, Speeds
from lerobot_gcs_push.planner.plan import DWELL, PUSH, Schedule

EXPERTS = ("open-loop", "closed-loop")


@dataclass
class ExpertConfig:
    mode: str = "open-loop"
    method: str = "relaxation"
    # Closed loop: every `replan_every` steps, outside pushes, replan if the box rests more than
    # `replan_tolerance` m from where the plan put it (a disturbance), or when the plan has run out.
    replan_every: int = 5
    replan_tolerance: float = 0.03
    max_replans: int = 50

    def __post_init__(self) -> None:
        if self.mode not in EXPERTS:
            raise ValueError(f"unknown expert {self.mode!r}: choose one of {EXPERTS}")
        if self.replan_every < 1:
            raise ValueError(f"replan_every must be >= 1, got {self.replan_every}")


class GcsExpert:
    def __init__(self, planner: GcsPlanner, fps: float, config: ExpertConfig | None = None,
                 speeds: Speeds | None = None):
        self.planner, self.fps = planner, fps
        self.config = config or ExpertConfig()
        self.speeds = speeds or Speeds()
        self.plans: list[Plan] = []
        self.plan_time_s = 0.0
        self._schedule: Schedule | None = None
        self._k = 0
        self._steps = 0

    @property
    def plan(self) -> Plan | None:
        """The first plan of the episode (the open-loop plan)."""
        return self.plans[0] if self.plans else None

    def reset(self, box, finger, goal=None) -> Plan:
        self.plans, self.plan_time_s, self._steps = [], 0.0, 0
        self._goal = goal
        return self._replan(box, finger)

    def _replan(self, box, finger) -> Plan:
        box, finger = self._plannable(np.asarray(box, float), np.asarray(finger, float))
        t0 = time.perf_counter()
        plan = self.planner.plan(box, finger, self._goal, method=self.config.method)
        self.plan_time_s += time.perf_counter() - t0
        self.plans.append(plan)
        self._schedule, self._k = plan.schedule(self.fps, self.speeds, self.planner.scene.push_lag_s), 0
        return plan

    def _plannable(self, box, finger):
        """A measured state the planner accepts: contact compliance lets the finger sink a millimetre into
        the box, and a disturbance may knock the box past the planner's reach."""
        scene = self.planner.scene
        box = np.clip(box, -scene.box_reach, scene.box_reach)
        gap = scene.finger_box_gap(box, finger)
        if gap < 0:
            r = finger - box
            axis = int(np.argmax(np.abs(r) - scene.box_half))
            finger = finger.copy()
            finger[axis] += np.sign(r[axis]) * (-gap + 1e-6)
        return box, finger

    def act(self, box, finger) -> np.ndarray:
        """The next finger command, given the measured box and finger positions."""
        if self.config.mode == "closed-loop" and self._should_replan(box):
            self._replan(box, finger)
        sched = self._schedule
        cmd = sched.commands[min(self._k, len(sched) - 1)]
        self._k += 1
        self._steps += 1
        return cmd.copy()

    def _should_replan(self, box) -> bool:
        cfg, sched = self.config, self._schedule
        if len(self.plans) > cfg.max_replans or self._steps % cfg.replan_every:
            return False
        if self._k >= len(sched):
            return True  # ran out without the env declaring success: start again from here
        i = max(self._k - 1, 0)
        if sched.kinds[i] in (PUSH, DWELL):
            return False  # the box moves with the finger's lag here; judge it once the push has ended
        return bool(np.linalg.norm(np.asarray(box) - sched.box[i]) > cfg.replan_tolerance)


def rollout(env, expert: GcsExpert, box=None, finger=None, seed: int | None = None, on_step=None) -> dict:
    """Run one episode of `expert` in `env` (a GcsPushBoxEnv, possibly wrapped). Returns a summary.

    `on_step(obs, action, info)` is called with the observation each action was chosen from."""
    options = None if box is None else {"box": list(box), "finger": list(finger)}
    obs, info = env.reset(seed=seed, options=options)
    plan = expert.reset(info["box"], info["finger"], goal=info["goal"])
    initial_plan_time = expert.plan_time_s
    t0 = time.perf_counter()
    terminated = truncated = False
    while not (terminated or truncated):
        action = expert.act(info["box"], info["finger"])
        if on_step is not None:
            on_step(obs, action, info)
        obs, _, terminated, truncated, info = env.step(action)
    return {
        "success": bool(info["is_success"]),
        "final_distance": float(info["box_goal_distance"]),
        "sim_time_s": float(info["sim_time_s"]),
        # Paper IV-B: the plan made before execution is plan time; replanning during it is run time.
        "run_time_s": time.perf_counter() - t0,
        "plan_time_s": initial_plan_time,
        "plan": plan,
        "replans": len(expert.plans) - 1,
        "box_final": np.asarray(info["box"]).tolist(),
        "finger_final": np.asarray(info["finger"]).tolist(),
        "disturbances": info.get("disturbances", []),
    }
