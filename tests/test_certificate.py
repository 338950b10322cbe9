"""The one certificate (`conic.certificate`) both planners take their bound from, against independent
evidence: the box's global optimum (SCIP on the MICP, and brute force over its mode sequences), the T's
(SCIP's spatial branch and bound on every path of a small graph, written from the planner's constraint
forms, not through the relaxation); dual points it must refuse; the assumption it states, checked at the
box's global optimum."""

from __future__ import annotations

import numpy as np
import pytest

from lerobot_gcs_push.box_gcs import GcsPlanner, brute_force
from lerobot_gcs_push.box_gcs.restriction import RestrictionCache
from lerobot_gcs_push.conic.certificate import CERTIFY_TOL, MARGIN, check_dual, of_solution
from lerobot_gcs_push.conic.solve import near_solution
from lerobot_gcs_push.scene import Scene, sample_initial_conditions

BOX = Scene()


@pytest.fixture(scope="module")
def box():
    return GcsPlanner(BOX)


@pytest.fixture(scope="module")
def box_queries(box):
    """Six sampled starts, each with its relaxation solved and its rounded plan's restriction."""
    out = []
    for ic in sample_initial_conditions(BOX, 6, seed=31):
        q = box.query(ic.box, ic.finger)
        relaxed = box.conic.relax(q.src, q.goal, q.allowed)
        out.append((ic, q, relaxed))
    return out


def test_the_box_bound_is_below_the_global_optimum(box, box_queries):
    """The plan's bound against the MICP's optimum (SCIP) and brute force over every mode sequence: at or
    below both, finite, and near them (measured gaps: 2-7 %); the MICP's own plan carries the same
    checked bound, not SCIP's value."""
    cache = RestrictionCache(box.graph)
    for ic, _, _ in box_queries:
        plan = box.plan(ic.box, ic.finger)
        micp = box.plan(ic.box, ic.finger, method="micp")
        exact = brute_force(box.graph, np.r_[ic.box, ic.finger], BOX.goal_array, cache).cost
        assert micp.cost == pytest.approx(exact, rel=1e-5, abs=1e-5)
        assert plan.certified and np.isfinite(plan.lower_bound)
        assert plan.lower_bound <= exact + 1e-9 and plan.lower_bound <= micp.cost + 1e-9, ic
        assert (exact - plan.lower_bound) / exact < 0.15, (ic, plan.lower_bound, exact)
        # The same query's certificate (its region widened by another plan's point: the same to 1e-6).
        assert micp.lower_bound == pytest.approx(plan.lower_bound, rel=1e-6)
        assert micp.lower_bound < micp.cost  # not SCIP's value taken on its word (the relaxation is not tight)


def test_a_tampered_box_dual_is_refused(box_queries):
    """Clarabel's own dual point certifies; the same point with 1e-3 added to the equality rows' duals (free
    in sign, so the projection cannot repair them) leaves a dual residual far above the tolerance, and is
    refused: no bound, rather than the tampered dual objective d - b.z."""
    for _, _, relaxed in box_queries:
        conic, sol = relaxed.relaxed, relaxed.solution
        own = of_solution(conic, sol)
        assert own.bound is not None and own.residual <= CERTIFY_TOL and own.bound <= sol.value + 1e-9
        z = sol.z.copy()
        z[: conic.zero] += 1e-3 * np.sign(np.random.default_rng(1).standard_normal(conic.zero))
        tampered = check_dual(conic, sol.x[conic.free], z)
        assert tampered.bound is None and tampered.residual > 100 * CERTIFY_TOL, tampered
        assert "dual residual" in tampered.reason


def test_the_assumption_holds_at_the_global_optimum(box, box_queries):
    """The certificate assumes the optimum within R = max(|x*|, |plan's point|) + MARGIN, entrywise. The
    global optimum's point (the MICP's path, SCIP, restricted in the same program) lies inside R on every
    start, and the term the bound spends on the assumption is small beside the bound. Without the plan's
    point, R = |x*| + MARGIN would not hold it: the relaxation's split flows shrink its copies."""
    from lerobot_gcs_push.box_gcs.rounding import candidate_paths

    outside_without_plan = 0
    for _, q, relaxed in box_queries:
        conic = relaxed.conic
        paths = candidate_paths(box.graph, relaxed.flows.flows, np.random.default_rng(0), 1)
        plan = min((box.conic.restrict(conic, p, q.src, q.goal) for p in paths), key=lambda s: s.rank())
        cert = relaxed.certificate(plan)
        assert cert.bound is not None and 0 <= cert.assumed < 1e-4 * abs(cert.bound), cert
        flows = box.micp.solve(q.src, q.goal, q.allowed)
        (path,) = candidate_paths(box.graph, flows.flows, None, 1, min_flow=0.5)
        optimum = box.conic.restrict(conic, path, q.src, q.goal)
        assert optimum.cost == pytest.approx(flows.value, rel=1e-4) and optimum.cost >= cert.bound  # SCIP: gap 1e-4
        x_opt = optimum.x[relaxed.relaxed.free]
        assert np.all(np.abs(x_opt) <= cert.radius), np.max(np.abs(x_opt) - cert.radius)
        alone = np.abs(relaxed.solution.x[relaxed.relaxed.free]) + MARGIN
        outside_without_plan += bool(np.any(np.abs(x_opt) > alone))
    assert outside_without_plan > 0  # the plan's point is needed: the check can fail


def test_a_near_solution_is_taken_only_with_small_residuals(box_queries):
    """`near_solution` (how an AlmostSolved answer is vetted) passes Clarabel's own solution and refuses
    the same primal point moved off feasibility, or paired with a tampered dual."""
    for _, _, relaxed in box_queries[:3]:
        conic, sol = relaxed.relaxed, relaxed.solution
        x = sol.x[conic.free]
        assert near_solution(conic, x, sol.z)
        assert not near_solution(conic, x + 1e-3, sol.z)
        z = sol.z.copy()
        z[: conic.zero] += 1e-3
        assert not near_solution(conic, x, z)


@pytest.mark.slow  # the T's one-push graph, 45 paths through SCIP
def test_the_t_bound_is_below_every_paths_global_optimum():
    """gym-pusht's T on a one-push graph (3 knots), near its goal: the plan's bound at or below the least
    of every path's global optimum (SCIP's spatial branch and bound, test_contact_graph_global.py's
    program), on three starts (one with a certified gap of 50 %: a loose bound, still below)."""
    pytest.importorskip("pyscipopt")
    pytest.importorskip("gym_pusht")
    from test_contact_graph_global import plan_and_path_optima

    from lerobot_gcs_push.contact import ContactPlanner
    from lerobot_gcs_push.registration import PUSHT_ENV_ID, SCENES

    planner = ContactPlanner(SCENES[PUSHT_ENV_ID], layers=1, knots=3)
    gx, gy, gh = planner.model.goal
    # Starts a single push can solve (most with a turn cannot: 2 steps of at most 0.2 rad, one face).
    starts = [
        ((gx + dx, gy + dy, gh), (gx + 20 * dx, gy + 20 * dy)) for dx, dy in ((0.1, 0.1), (-0.1, -0.1), (0.1, -0.1))
    ]
    checked = 0
    for pose, finger in starts:
        plan, optima = plan_and_path_optima(planner, *planner.plannable(pose, finger))
        best = min(b for b, _, _ in optima)
        assert np.isfinite(best) and plan.lower_bound <= best + 1e-5 * best, (pose, plan.lower_bound, best)
        print(f"bound {plan.lower_bound:.6f} <= global optimum {best:.6f} ({len(optima)} paths), plan {plan.cost:.6f}")
        checked += 1
    assert checked == len(starts)
