"""Where the closed-loop expert judges the slider against its plan (`ReplanRule`), and the two rules the
slider kinds start from (`scene.kinds`)."""

from __future__ import annotations

import math
from dataclasses import dataclass


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
