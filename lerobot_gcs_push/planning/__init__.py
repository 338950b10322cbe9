"""The one planning interface (`interface.Planner`): a query in, one `Plan` out, one `PlanningError`; the one
rounding walk over relaxed flows (`flow_walk`); the one expert that runs any plan closed loop (`expert`) and
where it seeks a plan from a state (`search`);
what serves each scene: its planner and its expert, with their settings (`factory`).
The planners behind it: `box_gcs/` (the box, over its modes) and `contact/` (a slider that turns)."""

from lerobot_gcs_push.planning.interface import Corrects, Planner, PlanningError
from lerobot_gcs_push.planning.plan import (
    APPROACH,
    DWELL,
    FREE,
    PUSH,
    RETREAT,
    Plan,
    Schedule,
    SegmentKind,
    Speeds,
)

__all__ = [
    "APPROACH",
    "Corrects",
    "DWELL",
    "FREE",
    "PUSH",
    "RETREAT",
    "Plan",
    "Planner",
    "PlanningError",
    "Schedule",
    "SegmentKind",
    "Speeds",
]
