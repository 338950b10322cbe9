"""What serves each scene: its planner (`make_planner`) and its GCS expert (`make_expert`: the one expert of
`planning.expert` with the scene's speeds and replan rule), the expert's settings (`ExpertConfig`), and the
box's GCS cost-to-go that scores any policy's chunks (regret).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from lerobot_gcs_push.planner import GcsPlanner, plannable
from lerobot_gcs_push.planning import Planner, PlanningError, Speeds
from lerobot_gcs_push.planning.expert import BOX_RULE, TURNING_RULE, PlanExpert
from lerobot_gcs_push.pusht.agent import COMMANDS

EXPERTS = ("open-loop", "closed-loop")
# gym-pusht's block is first order (it stops the moment the push does): no dwell. Its agent is steered onto
# the plan's points (pusht.agent.PixelActions), so no lead either. In m/s (60 px/m). Commanded with the plan's
# points at free 3, push 1.5 m/s, the lagging agent cut corners into the T: 4 of 6 starts (seed 77), one
# with 34 replans; at 1 / 0.5 m/s, seed 2026's first three took 10-27 s and the fourth over 6 min of
# replanning; steered, at 2 / 1 m/s, seed 77's two failures and one more succeeded in 4-9 s.
PUSHT_SPEEDS = Speeds(free=2.0, approach=1.0, push=1.0, retreat=2.0, push_dwell_s=0.0, push_lead=0.0)
# gym-pusht's position commands: the plan's path with its acceleration bounded (m/s^2, `planning.timing`), so
# that the commands a policy imitates have no kicks (experiments/pusht/README.md, "Imitable commands").
PUSHT_POSITION_SPEEDS = replace(PUSHT_SPEEDS, accel=4.0)
# And judged at twice the turning slider's shares: the agent rides the plan within an action but not on its
# points, and at the turning rule's tolerance the T strayed past it after pushes twice as often as when
# steered (22 replans against 11 on 10 starts), every replan a stop and a restart. On 20 tuning starts
# (seeds 11820-11839) position commands led 3 actions at 4 m/s^2: 20 / 20, 84 plans, commands' second
# difference 1.54-1.72x the agent's own (p90); judged at twice the shares: 20 / 20, 52 plans (the steered
# expert: 57), 1.37-1.47x (experiments/pusht/README.md, "Imitable commands").
PUSHT_POSITION_RULE = replace(TURNING_RULE, during_push=10.0, before_first_push=10.0, between_pushes=2.0)
# A slider that turns in the Drake sim: the box's push speed and lead, no dwell: its plans chain pushes, and the
# closed-loop expert replans where a push ended elsewhere. The lead builds up over its own length (0.34 m),
# and the finger's sideways miss is steered out (experiments/rotation/README.md, "the finger gives way").
# Free motion at 3 m/s: every replan takes the finger round the slider again, and at the box's 1 m/s a T
# from the arena's edge spent half its 60 s in free motion (5 of the bench's 50 starts ran out of time);
# at 3 m/s all 5 succeeded, and the rotating box's episodes were 4.9 s shorter on average
# (experiments/rotation/README.md, "Free motion at 3 m/s").
TURNING_SPEEDS = Speeds(free=3.0, push_dwell_s=0.0, push_lead_ramp_m=0.34, push_lateral_gain=1.0)
TEE_FINE_WITHIN = 0.25  # `fine_within_for`


def check_cost_to_go(env_id: str, needed_by: str = "") -> None:
    """Raise a ValueError unless `env_id` has the GCS cost-to-go of this module (regret, and active data,
    which labels states by it).

    It plans with the box that cannot turn. A rotating slider has experts (`make_expert`), but no cost-to-go
    yet: V at every chunk of every rollout means thousands of plans through contact, at 0.4-3 s each.
    Without this check the box planner would score a T as if it were a box that cannot turn, silently."""
    from lerobot_gcs_push.registration import SCENES

    if SCENES[env_id].rotates:
        raise ValueError(f"no GCS cost-to-go for {env_id} yet{f' ({needed_by})' if needed_by else ''}")


def make_planner(scene, method: str = "relaxation") -> Planner:
    """The planner that serves the scene: through contact for a slider that turns (`contact.ContactPlanner`,
    relaxation only), over its modes for the box (`planner.GcsPlanner`, relaxation or MICP)."""
    if scene.rotates:
        from lerobot_gcs_push.contact import ContactPlanner

        if method != "relaxation":
            raise ValueError(f"a rotating slider plans with the relaxation only, not {method!r}")
        return ContactPlanner(scene)
    return GcsPlanner(scene, method=method)


def make_expert(scene, fps: float, config: ExpertConfig | None = None, planner=None):
    """The scene's GCS expert: the planner that serves it (`make_planner`), with the speeds and the
    replan rule for its slider; in pixels, with its agent steered, for a scene with a frame (gym-pusht).
    `planner` shares one planner between experts (it is costly to build)."""
    config = config or ExpertConfig()
    planner = planner or make_planner(scene, config.method)
    rule = TURNING_RULE if scene.rotates else BOX_RULE
    if scene.frame is not None and config.commands == "position":
        rule = PUSHT_POSITION_RULE
    # gym-pusht's agent starts anywhere, far from the T: planned from near it first (`PlanExpert._plan`). Its
    # detouring replans are kept: replaced, they cost 10 % of its demonstrations an hour (`make bench`'s pusht
    # row, 837 against 929, run back to back) for no failure seen there; the Drake T's went 46 -> 49 of 50.
    pusht = scene.frame is not None
    expert = PlanExpert(
        planner,
        fps,
        config,
        speeds_for(scene, config.commands),
        rule,
        stage_first=pusht,
        replace_detours=not pusht,
        fine_within=fine_within_for(scene) if config.fine_within is None else config.fine_within,
    )
    if scene.frame is not None:
        from lerobot_gcs_push.pusht.agent import PixelActions

        return PixelActions(expert, scene.frame, config.commands, config.lead_actions)
    return expert


def fine_within_for(scene) -> float:
    """How near its goal the scene's expert corrects the slider by single pushes (`ExpertConfig.fine_within`).

    A slider of several convex parts (the T): 0.25. Near the goal the T's rounding returned plans at 100
    times their bound that took it away and back. With corrections, gym-pusht's episodes were 4 % shorter
    on 40 starts, and the Drake T went 50 / 50 on a fresh set. A convex one (the rotating box): none. Its
    plans there are good, and on 50 starts (seed 5160, side by side) corrections made its episodes 0.9 s
    longer on average, 50 / 50 either way."""
    return TEE_FINE_WITHIN if scene.rotates and len(scene.shape.parts) > 1 else 0.0


def speeds_for(scene, commands: str = "position") -> Speeds:
    """The finger speeds the scene's expert runs its plans at (gym-pusht's: with `commands`' timing)."""
    if scene.frame is not None:
        return PUSHT_POSITION_SPEEDS if commands == "position" else PUSHT_SPEEDS
    return TURNING_SPEEDS if scene.rotates else Speeds()


@dataclass
class ExpertConfig:
    mode: str = "open-loop"
    method: str = "relaxation"
    # Closed loop: every `replan_every` steps, outside pushes, replan if the box rests more than
    # `replan_tolerance` m from where the plan put it (a disturbance), or when the plan has run out.
    replan_every: int = 5
    replan_tolerance: float = 0.03
    max_replans: int = 50
    # gym-pusht only: what an action is (pusht.agent.PixelActions). "position": the plan's own point
    # `lead_actions` on (None: 3), along a path of bounded acceleration (`PUSHT_POSITION_SPEEDS`); the
    # agent, trailing its command by about 1.5 actions, then rides the plan. "steer": the target that, held
    # `lead_actions` actions (None: 2), lands the PD agent on that point; it inverts the PD, the commands
    # until 2026-12-07 (over 2 rather than 1 its targets jumped a third to a quarter as far). Position
    # commands are what a policy can imitate (experiments/pusht/README.md, "Imitable commands").
    commands: str = "position"
    lead_actions: int | None = None
    # A slider that turns, within this distance of its goal (m + rad x r_max): the closed-loop expert corrects
    # it by single pushes chosen on the linearised model (`contact.fine`), not by plans through the
    # relaxation; 0 turns that off; none: the scene's (`fine_within_for`).
    fine_within: float | None = None

    def __post_init__(self) -> None:
        if self.mode not in EXPERTS:
            raise ValueError(f"unknown expert {self.mode!r}: choose one of {EXPERTS}")
        if self.replan_every < 1:
            raise ValueError(f"replan_every must be >= 1, got {self.replan_every}")
        if not self.replan_tolerance > 0:  # also refuses NaN, which would never replan
            raise ValueError(f"replan_tolerance must be > 0 (m), got {self.replan_tolerance}")
        if self.max_replans < 0:
            raise ValueError(f"max_replans must be >= 0, got {self.max_replans}")
        if self.fine_within is not None and not self.fine_within >= 0:  # also refuses NaN
            raise ValueError(f"fine_within must be >= 0 (m + rad x the slider's radius), got {self.fine_within}")
        if self.commands not in COMMANDS:
            raise ValueError(f"unknown commands {self.commands!r}: choose one of {COMMANDS}")
        if self.lead_actions is None:
            self.lead_actions = 3 if self.commands == "position" else 2
        if self.lead_actions < 1:
            raise ValueError(f"lead_actions must be >= 1, got {self.lead_actions}")


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
        except (PlanningError, ValueError):
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
