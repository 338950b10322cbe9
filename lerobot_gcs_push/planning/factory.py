"""What serves each scene: its planner (`make_planner`) and its GCS expert (`make_expert`: the one expert of
`planning.expert` with the scene's speeds and replan rule), the expert's settings (`ExpertConfig`), and the
box's GCS cost-to-go that scores any policy's chunks (regret).
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
from typing import ClassVar

import numpy as np

from lerobot_gcs_push.box_gcs import GcsPlanner, plannable
from lerobot_gcs_push.planning import Planner, PlanningError, Speeds
from lerobot_gcs_push.planning.expert import PlanExpert
from lerobot_gcs_push.pusht.agent import COMMANDS
from lerobot_gcs_push.settings import Shared

EXPERTS = ("open-loop", "closed-loop")
REPLAY = "replay"  # generate's: no planning, a list's recorded actions run again


def check_cost_to_go(env_id: str, needed_by: str = "") -> None:
    """Raise a ValueError unless `env_id` has the GCS cost-to-go of this module (regret, and active data,
    which labels states by it): its slider kind's `cost_to_go`. Without this check the box planner would
    score a T as if it were a box that cannot turn, silently."""
    from lerobot_gcs_push.registration import SCENES

    if not SCENES[env_id].kind.cost_to_go:
        raise ValueError(f"no GCS cost-to-go for {env_id} yet{f' ({needed_by})' if needed_by else ''}")


def _contact_planner(scene, method: str) -> Planner:
    from lerobot_gcs_push.contact import ContactPlanner

    return ContactPlanner(scene)


# Each slider kind names its planner (`SliderKind.planner`); built here, above the planners, which read the
# scene: over the box's modes (`box_gcs.GcsPlanner`, relaxation or MICP), or through contact for a slider that
# turns (`contact.ContactPlanner`, the relaxation only).
PLANNERS = {
    "box_gcs": lambda scene, method: GcsPlanner(scene, method=method),
    "contact": _contact_planner,
}


def make_planner(scene, method: str = "relaxation") -> Planner:
    """The planner that serves the scene: its slider kind's, with `method` if the kind accepts it."""
    kind = scene.kind
    if method not in kind.methods:
        raise ValueError(f"a {kind.name} slider plans with the {' or '.join(kind.methods)} only, not {method!r}")
    return PLANNERS[kind.planner](scene, method)


def make_expert(scene, fps: float, config: ExpertConfig | None = None, planner=None):
    """The scene's GCS expert: the planner that serves it (`make_planner`), with the speeds, the replan rule
    and the habits of its slider kind; in pixels, with its agent steered, for gym-pusht.
    `planner` shares one planner between experts (it is costly to build)."""
    config = config or ExpertConfig()
    if config.mode == REPLAY:
        raise ValueError("the replay expert runs recorded actions and plans nothing: it is generate's")
    kind = scene.kind
    planner = planner or make_planner(scene, config.method)
    speeds = kind.speeds(config.commands)
    if config.arrive > 0:
        speeds = replace(speeds, arrive=config.arrive, arrive_m=config.arrive_m)
    expert = PlanExpert(
        planner,
        fps,
        config,
        speeds,
        kind.replan_rule(config.commands),
        stage_first=kind.stage_first,
        replace_detours=kind.replace_detours,
        fine_within=kind.fine_within(scene) if config.fine_within is None else config.fine_within,
    )
    return kind.wrap_expert(expert, scene, config)


def fine_within_for(scene) -> float:
    """How near its goal the scene's expert corrects the slider by single pushes (`ExpertConfig.fine_within`):
    its slider kind's (`scene.kinds.TurningSlider.fine_within` says why)."""
    return scene.kind.fine_within(scene)


def speeds_for(scene, commands: str = "position") -> Speeds:
    """The finger speeds the scene's expert runs its plans at (gym-pusht's: with `commands`' timing)."""
    return scene.kind.speeds(commands)


@dataclass
class ExpertConfig(Shared):
    """The GCS expert's settings: the one definition of them, nested as `expert` in `generate` and `evaluate`
    (`--expert.commands=steer`); their flat names work too (`--expert=closed-loop`, `--method=micp`)."""

    flat_value: ClassVar[str] = "mode"
    # open-loop (plan once, the paper's) or closed-loop (replans after disturbances); generate also takes
    # replay (runs the "actions" of each --initial_conditions entry: a dataset's meta/gcs_push_replay.json
    # rebuilds it, see generate/replay.py). Default: generate's is replay for a list whose entries all carry
    # actions, else the slider kind's (open-loop for the box that cannot turn, closed-loop for a rotating
    # slider, which strays from any plan pushed open-loop); evaluate's policies name theirs (gcs-open-loop);
    # `make_expert` given none plans open-loop.
    mode: str | None = None
    # relaxation (convex relaxation + rounding) or micp (exact, SCIP; the box only).
    method: str = "relaxation"
    # Closed loop: every `replan_every` steps, outside pushes, replan if the box rests more than
    # `replan_tolerance` m from where the plan put it (a disturbance), or when the plan has run out.
    replan_every: int = 5
    # How far the slider may rest from the plan's pose before a closed-loop expert replans (m; see above).
    replan_tolerance: float = 0.03
    # Replans at most in an episode (single-push corrections not counted); then the last plan runs out.
    max_replans: int = 50
    # gym-pusht only: what an action is (pusht.agent.PixelActions). "position": the plan's own point
    # `lead_actions` on (None: 3), along a path of bounded acceleration (`rules.PUSHT_POSITION_SPEEDS`); the
    # agent, trailing its command by about 1.5 actions, then rides the plan. "steer": the target that, held
    # `lead_actions` actions (None: 2), lands the PD agent on that point; it inverts the PD, the commands
    # until 2026-12-07 (over 2 rather than 1 its targets jumped a third to a quarter as far). Position
    # commands are what a policy can imitate (experiments/pusht/README.md, "Imitable commands").
    commands: str = "position"
    # gym-pusht only: how many actions on a command leads (see `commands`); none: the commands' own.
    lead_actions: int | None = None
    # A slider that turns, within this distance of its goal (m + rad x r_max): the closed-loop expert corrects
    # it by single pushes chosen on the linearised model (`contact.fine`), not by plans through the
    # relaxation; 0 turns that off; none: the scene's (`fine_within_for`).
    fine_within: float | None = None
    # The last `arrive_m` m of each plan's last push at `arrive` m/s at most (`planning.plan.Speeds.arrive`);
    # 0: at the push's speed.
    arrive: float = 0.0
    arrive_m: float = 0.1

    def __post_init__(self) -> None:
        from lerobot_gcs_push.box_gcs import check_method

        if self.mode not in (None, *EXPERTS, REPLAY):
            raise ValueError(f"unknown expert {self.mode!r}: choose one of {(*EXPERTS, REPLAY)}")
        check_method(self.method)
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
        if self.lead_actions is not None and self.lead_actions < 1:
            raise ValueError(f"lead_actions must be >= 1, got {self.lead_actions}")
        for name in ("arrive", "arrive_m"):
            if not getattr(self, name) >= 0:  # also refuses NaN
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}")

    def lead(self) -> int:
        """`lead_actions`, or its default for the commands. Resolved here, never stored: draccus builds a nested
        config from the class's defaults, so a value filled in for "position" would outlive a later
        --expert.commands=steer."""
        if self.lead_actions is not None:
            return self.lead_actions
        return 3 if self.commands == "position" else 2

    def check_env(self, env_id: str) -> None:
        """For a command's validation: what the env's slider kind cannot do is refused before any work."""
        from lerobot_gcs_push.registration import SCENES

        kind = SCENES[env_id].kind
        if self.method not in kind.methods:
            raise ValueError(f"{env_id} plans with the relaxation only: drop --method={self.method}")
        if (self.commands != "position" or self.lead_actions is not None) and not kind.lerobot_pusht_data:
            raise ValueError(f"expert.commands and expert.lead_actions are gym-pusht's; {env_id} takes neither")

    def non_defaults(self, always: tuple[str, ...] = ("mode", "method")) -> dict:
        """The settings that differ from the defaults, by flat name, but those a record `always` holds (its
        own way): what a record adds, so that one made without them reads as it always did."""
        default = ExpertConfig()
        return {
            f.name: getattr(self, f.name)
            for f in fields(self)
            if f.name not in always and getattr(self, f.name) != getattr(default, f.name)
        }


# What a record made before the expert's settings were reachable (or without them) was made with.
EXPERT_DEFAULTS = {f.name: f.default for f in fields(ExpertConfig) if f.name not in ("mode", "method")}


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
