"""GCS planning through contact for the finger-box pushing task (paper sections III-B, III-D).

    planner = GcsPlanner(Scene())                       # builds and compiles the graph once
    plan = planner.plan(box=[2, -1], finger=[-3, 0])    # a solver call per query
    plan.cost, plan.lower_bound, plan.modes, plan.commands(fps=10)      # a planning.Plan

Pure optimisation: no Drake, no env. The modules, from data to answer: `graph` (the mode graph as numpy
data), `transcription` (its vertices and edges as cvxpy constraints), `gcs` (the shortest-path program:
relaxation or MICP), `rounding` and `restriction` (from flows to a path, and the path's exact optimum),
`trace` (the plan's waypoints), `planner` (`GcsPlanner`, which runs them per query). Plans, their timing
and the error are the package's one planning interface (`lerobot_gcs_push.planning`).
"""

from lerobot_gcs_push.box_gcs.graph import build_graph
from lerobot_gcs_push.box_gcs.planner import METHODS, GcsPlanner, Query, check_method, plannable
from lerobot_gcs_push.box_gcs.restriction import brute_force

__all__ = [
    "METHODS",
    "GcsPlanner",
    "Query",
    "brute_force",
    "build_graph",
    "check_method",
    "plannable",
]
