"""What every planner is to the rest of the package: a query in (the slider, the finger, optionally a goal),
one `Plan` out, one error when there is none. Which planner serves a scene is `factory.make_planner`'s choice."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

if TYPE_CHECKING:
    from lerobot_gcs_push.planning.plan import Plan


class PlanningError(RuntimeError):
    """No plan for this query: a solver failed (the message names it and its status), rounding found no
    feasible path, or the state lies where the planner cannot plan from."""


class Planner(Protocol):
    # The `scene.Scene` it plans in (not imported here: the scene's slider kinds import the planning layer).
    scene: Any

    def plan(self, slider, finger, goal=None, /) -> Plan:
        """The plan from the slider (the box's [x, y], or [x, y, heading]) and the finger to the scene's
        goal, or to `goal` (a waypoint of the same shape); raises PlanningError when there is none."""

    def plannable(self, slider, finger) -> tuple[np.ndarray, np.ndarray]:
        """The nearest state the planner accepts to a measured one (a finger pressed into the slider, a
        slider knocked past the planner's reach)."""

    def distance(self, a, b) -> float:
        """How far apart two slider states are (metres, plus radians times the radius of one that turns)."""

    def goal_of(self, slider) -> np.ndarray:
        """Where a plan from `slider` ends (a turning slider's goal copy nearest its heading)."""

    def warm_up(self) -> float:
        """Build what every plan needs now, so no query pays for it; the seconds it took."""


@dataclass(frozen=True)
class Correction:
    """What a `Corrects` planner proposes, one push: where the finger touches (slider frame), how far, and
    what the model predicts."""

    face: int
    lam: float
    direction: np.ndarray  # body-frame unit displacement of the slider per unit push
    amount: float  # slider travel (m)
    error: float  # what is left: `distance(predicted end, goal)`, m + rad x r_max
    poses: np.ndarray  # (PUSH_STEPS + 1, 3) the slider's poses along the push, world
    fingers: np.ndarray  # (PUSH_STEPS + 1, 2) the finger's centre along the push, world
    normal: np.ndarray  # the face's outward normal, slider frame

    def normal_world(self, heading: float) -> np.ndarray:
        c, s = math.cos(heading), math.sin(heading)
        return np.array([c * self.normal[0] - s * self.normal[1], s * self.normal[0] + c * self.normal[1]])


class Corrects(Planner, Protocol):
    """A planner that also proposes single corrective pushes (`contact.ContactPlanner`): what the expert
    asks of it within its `fine_within` of the goal (`search.fine_plan`). A planner without them is
    run with `fine_within` 0, as every slider kind's `fine_within` gives for the box."""

    def corrections(self, slider, goal=None, /) -> Sequence[Correction]:
        """Single pushes from `slider` towards the goal (or `goal`), the least error left first; each
        offers the finger's and the slider's path along it (`fingers`, `poses`), its face's outward normal
        (`normal_world(heading)`, `normal`, `face`, `lam`) and the error left (`error`)."""
