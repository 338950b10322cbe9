"""GCS experts that act in `GcsPushBox-v0`, the paper's open-loop policy and a closed-loop one, and the
GCS cost-to-go that scores any policy's chunks (regret).

The experts are plain policies (`rollout.Policy`) over the env's true state (`info["box"]`,
`info["finger"]`); the env knows nothing about them.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from lerobot_gcs_push.planner import GcsPlanner, Plan, SolverError, Speeds
from lerobot_gcs_push.planner.plan import DWELL, PUSH, Schedule

EXPERTS = ("open-loop", "closed-loop")
# gym-pusht's block is first order (it stops the moment the push does): no dwell. Its agent is steered onto
# the plan's points (pusht_agent.target_for), so no lead either. In m/s (60 px/m). Commanded with the plan's
# points at free 3, push 1.5 m/s, the lagging agent cut corners into the T: 4 of 6 starts (seed 77), one
# with 34 replans; at 1 / 0.5 m/s, seed 2026's first three took 10-27 s and the fourth over 6 min of
# replanning; steered, at 2 / 1 m/s, seed 77's two failures and one more succeeded in 4-9 s.
PUSHT_SPEEDS = Speeds(free=2.0, approach=1.0, push=1.0, retreat=2.0, push_dwell_s=0.0, push_lead=0.0)


def check_cost_to_go(env_id: str, needed_by: str = "") -> None:
    """Raise a ValueError unless `env_id` has the GCS cost-to-go of this module (regret, and active data,
    which labels states by it).

    It plans with the box that cannot turn. A rotating slider has experts (`make_expert`), but no cost-to-go
    yet: V at every chunk of every rollout means thousands of plans through contact, at 0.4-3 s each.
    Without this check the box planner would score a T as if it were a box that cannot turn, silently."""
    from lerobot_gcs_push.registration import SCENES

    if SCENES[env_id].rotates:
        raise ValueError(f"no GCS cost-to-go for {env_id} yet{f' ({needed_by})' if needed_by else ''}")


def make_expert(scene, fps: float, config: ExpertConfig | None = None, planner=None):
    """The scene's GCS expert: over the box's modes (`GcsExpert`) or, for a rotating slider, through contact
    (`contact.expert.ContactExpert`). `planner` shares one planner between experts (it is costly to build)."""
    config = config or ExpertConfig()
    if scene.rotates:
        from lerobot_gcs_push.contact import ContactPlanner
        from lerobot_gcs_push.contact.expert import ContactExpert

        if config.method != "relaxation":
            raise ValueError(f"a rotating slider plans with the relaxation only, not {config.method!r}")
        if scene.frame is not None:  # gym-pusht: pixels, its agent's dynamics inverted, speeds it can follow
            from lerobot_gcs_push.contact.expert import PixelActions
            from lerobot_gcs_push.pusht_agent import target_for

            expert = ContactExpert(planner or ContactPlanner(scene), fps, config, PUSHT_SPEEDS)
            return PixelActions(
                expert, scene.frame, lambda info, px: target_for(info["pos_agent"], info["vel_agent"], px)
            )
        return ContactExpert(planner or ContactPlanner(scene), fps, config)
    return GcsExpert(planner or GcsPlanner(scene, method=config.method), fps, config)


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
    def __init__(
        self, planner: GcsPlanner, fps: float, config: ExpertConfig | None = None, speeds: Speeds | None = None
    ):
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

    def reset(self, obs, info: dict, seed: int | None = None) -> None:
        """Plan from the episode's initial state (the seed is unused: the experts are deterministic)."""
        self.plans, self.plan_time_s, self._steps = [], 0.0, 0
        self._goal = info["goal"]
        self._replan(info["box"], info["finger"])
        self._initial_plan_time_s = self.plan_time_s

    def episode_summary(self) -> dict:
        # Paper IV-B: the plan made before execution is plan time; replanning during it is run time.
        return {"plan_time_s": self._initial_plan_time_s, "plan": self.plan, "replans": len(self.plans) - 1}

    def _replan(self, box, finger) -> Plan:
        box, finger = plannable(self.planner.scene, box, finger)
        t0 = time.perf_counter()
        plan = self.planner.plan(box, finger, self._goal, method=self.config.method)
        self.plan_time_s += time.perf_counter() - t0
        self.plans.append(plan)
        self._schedule, self._k = plan.schedule(self.fps, self.speeds, self.planner.scene.push_lag_s), 0
        return plan

    def act(self, obs, info: dict) -> np.ndarray:
        """The next finger command, given the measured box and finger positions."""
        box, finger = info["box"], info["finger"]
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


def plannable(scene, box, finger, clearance: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
    """A measured state the planner accepts: contact compliance lets the finger sink a millimetre into
    the box, and a disturbance may knock the box past the planner's reach."""
    box = np.clip(np.asarray(box, float), -scene.box_reach, scene.box_reach)
    finger = np.asarray(finger, float).copy()
    if scene.finger_box_gap(box, finger) >= clearance:
        return box, finger
    # Move the centre straight away from the nearest point of the box (off a corner, that is diagonal).
    nearest = box + np.clip(finger - box, -scene.box_half, scene.box_half)
    away = finger - nearest
    if np.linalg.norm(away) < 1e-9:  # the centre is inside the box: leave by the nearest face
        r = finger - box
        axis = int(np.argmax(np.abs(r)))
        away = np.zeros(2)
        away[axis] = np.sign(r[axis]) or 1.0
        nearest = box.copy()
        nearest[axis] += away[axis] * scene.box_half
    return box, nearest + away / np.linalg.norm(away) * (scene.finger_radius + clearance)


class CostToGo:
    """V(state): the finger path length still needed to bring the box within the success threshold.

    Its own planner stops a push short on an axis whose offset is under threshold / sqrt(2) (so both
    offsets under it are a success), since the episode ends there: planning to the exact goal would
    count a last push around the box that no run ever makes. Relaxation and rounding, not the MICP: with
    this tolerance the rounded cost equalled SCIP's optimum on 40 of 40 random states (the relaxation's
    bound is loose there, so the bound cannot certify it; the MICP costs ten times as long).
    """

    def __init__(self, scene):
        self.scene = scene
        self.planner = GcsPlanner(scene, goal_tolerance=scene.success_threshold / np.sqrt(2))

    def __call__(self, box, finger) -> float:
        """NaN where the planner fails (reported, never silently zero)."""
        scene = self.scene
        if scene.box_goal_distance(box) <= scene.success_threshold:
            return 0.0
        box, finger = plannable(scene, box, finger)
        try:
            return float(self.planner.plan(box, finger).cost)
        except (SolverError, ValueError):
            return float("nan")


def chunk_regret(value: CostToGo, boxes, fingers, every: int) -> list[dict]:
    """Regret of each executed chunk of `every` steps along a rollout's states (`boxes`, `fingers`: one
    row per step, the final state included): the finger's path length over the chunk plus V(after) minus
    V(before). The optimal plan scores zero; a chunk that drives the box the wrong way scores what it
    cost plus what it added to the remaining work. Negative only within the tracking tolerance, or where
    a disturbance helped."""
    boxes, fingers = np.asarray(boxes, float), np.asarray(fingers, float)
    last = len(boxes) - 1
    bounds = list(range(0, last, every)) + [last]
    values = [value(boxes[k], fingers[k]) for k in bounds]
    steps = np.linalg.norm(np.diff(fingers, axis=0), axis=1)
    out = []
    for (k0, k1), v0, v1 in zip(zip(bounds, bounds[1:]), values, values[1:]):
        path = float(steps[k0:k1].sum())
        out.append(
            {
                "step": k0,
                "steps": k1 - k0,
                "path": path,
                "v_before": v0,
                "v_after": v1,
                "regret": path + v1 - v0,
                "box": boxes[k0].tolist(),
                "finger": fingers[k0].tolist(),
            }
        )
    return out
