"""The expert's settings for each slider kind (`scene.kinds` chooses among them): where the closed-loop
expert judges the slider against its plan (`ReplanRule`), the finger's speeds, and how near its goal a T
is corrected by single pushes."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from lerobot_gcs_push.planning.plan import Speeds


@dataclass(frozen=True)
class ReplanRule:
    """Where the closed-loop expert judges the slider against its plan, and at what share of the config's
    `replan_tolerance` (every `replan_every` steps; a plan that has run out is always replanned)."""

    # While a push runs (or its dwell holds), the finger's lag moves the slider off the reference: judged
    # there only at this multiple of the tolerance (inf: never).
    during_push: float
    # Before the plan's first push, the last plan's push may still be draining into the slider.
    before_first_push: float
    # Which command's segment tells whether a push runs: the next one to be sent (True) or the last sent.
    by_next_command: bool
    approach_m: float = 0.0  # `Plan.schedule`'s approach along a push's face normal (plans through contact)
    # Elsewhere (after a push, outside it).
    between_pushes: float = 1.0


# The box: judged only between pushes, at the tolerance (a pushed box moves with the finger's lag and is
# judged once the push and its dwell have ended).
BOX_RULE = ReplanRule(during_push=math.inf, before_first_push=1.0, by_next_command=False)
# A slider that turns. Judged everywhere at the tolerance, a T replanned every second, each new plan backing
# the finger off the face it pushed on, and crept to the goal at a quarter of the push speed (5 of 10
# demonstrations failed so); within a push only a slider that has turned away (5 times the tolerance) is
# replanned. The last 5 cm before a push that follows free motion run along the face's normal: arriving
# along its free path the finger touched the T 5-10 cm from the planned contact, and near the goal turned
# it away; 0.2 m (the box planner's transition buffer) doubled the T's episode time, since every replan
# backs the finger off its face (16 sobol starts, experiments/rotation/README.md).
TURNING_RULE = ReplanRule(during_push=5.0, before_first_push=5.0, by_next_command=True, approach_m=0.05)
# A slider that turns in the Drake sim: the box's push speed and lead, no dwell: its plans chain pushes, and the
# closed-loop expert replans where a push ended elsewhere. The lead builds up over its own length (0.34 m),
# and the finger's sideways miss is steered out (experiments/rotation/README.md, "the finger gives way").
# Free motion at 3 m/s: every replan takes the finger round the slider again, and at the box's 1 m/s a T
# from the arena's edge spent half its 60 s in free motion (5 of the bench's 50 starts ran out of time);
# at 3 m/s all 5 succeeded, and the rotating box's episodes were 4.9 s shorter on average
# (experiments/rotation/README.md, "Free motion at 3 m/s").
TURNING_SPEEDS = Speeds(free=3.0, push_dwell_s=0.0, push_lead_ramp_m=0.34, push_lateral_gain=1.0)
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
# How near its goal a T is corrected by single pushes (`scene.kinds.TurningSlider.fine_within`).
TEE_FINE_WITHIN = 0.25
