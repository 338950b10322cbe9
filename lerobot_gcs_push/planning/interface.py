"""What every planner is to the rest of the package: a query in (the slider, the finger, optionally a goal),
one `Plan` out, one error when there is none. Which planner serves a scene is `factory.make_planner`'s choice."""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol

import numpy as np

if TYPE_CHECKING:
    from lerobot_gcs_push.planning.plan import Plan
    from lerobot_gcs_push.scene import Scene


class PlanningError(RuntimeError):
    """No plan for this query: a solver failed (the message names it and its status), rounding found no
    feasible path, or the state lies where the planner cannot plan from."""


class Planner(Protocol):
    scene: Scene

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
