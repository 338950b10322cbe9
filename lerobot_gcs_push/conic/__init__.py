"""Conic programs solved by Clarabel, shared by both planners (the box's mode graph, `box_gcs/`, and the
contact graph of a slider that turns, `contact/`): conic data as Clarabel reads it and the same program
with variables fixed (`program`), taken once from a DPP cvxpy program and evaluated per query
(`parametric`), kept on disk (`cache`), the cones and residuals (`cones`), Clarabel's call and which of
its answers count as solved (`solve`), and the one lower bound either planner reports (`certificate`)."""

from lerobot_gcs_push.conic.cache import CACHE_ENV, cached
from lerobot_gcs_push.conic.certificate import Certificate, certify, of_solution, solve_certified
from lerobot_gcs_push.conic.parametric import ParametricConic
from lerobot_gcs_push.conic.program import Conic, Fixing, Infeasible
from lerobot_gcs_push.conic.solve import ConicSolution

__all__ = [
    "CACHE_ENV",
    "Certificate",
    "Conic",
    "ConicSolution",
    "Fixing",
    "Infeasible",
    "ParametricConic",
    "cached",
    "certify",
    "of_solution",
    "solve_certified",
]
