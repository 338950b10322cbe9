"""The graph relaxation's certificate at graph level, against independent evidence: on a small graph (the
rotating box, 2 layers, 3 knots, the knot windows' chord cuts on) every path's restriction, the nonconvex
program of one mode sequence, solved to global optimality by SCIP (spatial branch and bound, written here
from the planner's constraint forms with pyscipopt, not through the relaxation). The relaxation's bound
must lie at or below the least of them, and the rounded plan at or above it."""

from __future__ import annotations

import time
import warnings

import numpy as np
import pytest

from lerobot_gcs_push.contact import ContactPlanner
from lerobot_gcs_push.contact.face_contact import finger_body
from lerobot_gcs_push.contact.non_collision import knots_of, segment_region
from lerobot_gcs_push.contact.relaxation import pose_vector
from lerobot_gcs_push.contact.rounding import ranked_paths
from lerobot_gcs_push.scene import Scene

pytest.importorskip("pyscipopt")

SCENE = Scene(slider="box", rotates=True)
START = ((2.0, 0.8, 0.35), (3.6, 0.9))  # finger behind the face that looks away from the goal


def _quadratic(q: np.ndarray, z: list) -> object:
    """z^T Q z with z[0] the constant 1."""
    out = 0.0
    for i, j in zip(*np.nonzero(np.triu(q))):
        coef = q[i, j] if i == j else 2 * q[i, j]
        out = out + coef * (z[i] * z[j])
    return out


def scip_restriction(planner: ContactPlanner, path, pose, q0, goal, cap: float) -> tuple[str, float, float]:
    """(status, best objective, dual bound) of the path's restriction with cost <= cap, solved globally.
    The variables' boxes are the restriction's own (lam on its face, (c, s) in [-1, 1]^2, the slider
    within reach, the finger within its free pieces), and |fn|, |ft| <= sqrt(cap): each push step costs at
    least fn^2 + ft^2, so no plan within the cap leaves them."""
    from pyscipopt import Model, quicksum

    model, graph = planner.model, planner.graph
    m = Model()
    m.hideOutput()
    m.setParam("limits/gap", 1e-7)
    m.setParam("limits/time", 300)
    reach, big = model.reach, float(np.sqrt(cap)) + 1e-6
    cost = []
    prev_pose = list(pose_vector(pose))
    prev_finger = [float(v) for v in q0]
    for f, c in zip(path.frees, path.contacts):
        route = graph.frees[f].route
        n = knots_of(route, planner.per_region)
        fq = [[m.addVar(lb=-model.finger_reach, ub=model.finger_reach) for _ in range(2)] for _ in range(n)]
        for seg in range(n - 1):
            reg = planner.regions[segment_region(route, planner.per_region, seg)]
            for p in (fq[seg], fq[seg + 1]):
                for a, b in zip(reg.a, reg.b):
                    m.addCons(a[0] * p[0] + a[1] * p[1] <= b)
        for k in range(n - 1):
            cost += [(fq[k + 1][i] - fq[k][i]) * (fq[k + 1][i] - fq[k][i]) for i in range(2)]
        for i in range(2):
            m.addCons(fq[0][i] == prev_finger[i])
        v = graph.contacts[c]
        face, forms = model.faces[v.face], planner.rounding_forms[v.face, v.piece]
        kn = planner.knots
        lam = [m.addVar(lb=forms.lam_range[0], ub=forms.lam_range[1]) for _ in range(kn)]
        cs = [m.addVar(lb=-1, ub=1) for _ in range(kn)]
        sn = [m.addVar(lb=-1, ub=1) for _ in range(kn)]
        x = [m.addVar(lb=-reach, ub=reach) for _ in range(kn)]
        y = [m.addVar(lb=-reach, ub=reach) for _ in range(kn)]
        fn = [m.addVar(lb=0, ub=big) for _ in range(kn - 1)]
        ft = [m.addVar(lb=-big, ub=big) for _ in range(kn - 1)]
        for k in range(kn - 1):
            z = [1.0, lam[k], cs[k], sn[k], fn[k], ft[k], cs[k + 1], sn[k + 1], lam[k + 1]]
            pos = [x[k], x[k + 1], y[k], y[k + 1]]
            for qf, lin in zip(forms.eq_q, forms.eq_l):
                m.addCons(_quadratic(qf, z) + quicksum(float(lin[i]) * pos[i] for i in range(4)) == 0)
            for qf in forms.ineq_q:
                m.addCons(_quadratic(qf, z) >= 0)
            cost.append(_quadratic(forms.cost_q, z))
        body = finger_body(face, model, 0.0), np.asarray(face.e, float)
        for i in range(2):
            m.addCons(fq[-1][i] == float(body[0][i]) + float(body[1][i]) * lam[0])
        for u, w in zip([x[0], y[0], cs[0], sn[0]], prev_pose):
            m.addCons(u == w)
        prev_pose = [x[-1], y[-1], cs[-1], sn[-1]]
        prev_finger = [float(body[0][i]) + float(body[1][i]) * lam[-1] for i in range(2)]
    for u, w in zip(prev_pose, pose_vector(goal)):
        m.addCons(u == float(w))
    obj = m.addVar(lb=0, ub=cap)
    m.addCons(quicksum(cost) <= obj)
    m.setObjective(obj, "minimize")
    m.optimize()
    status = m.getStatus()
    best = m.getObjVal() if m.getNSols() > 0 else np.inf
    return status, best, m.getDualbound()


def plan_and_path_optima(planner: ContactPlanner, pose, finger) -> tuple:
    """The planner's plan from (pose, finger), and every path's (best objective, dual bound, path) from
    the finger's start piece, each restriction solved globally by SCIP below 1.5 times the plan's cost
    (the plan is one path's feasible point: the least optimum lies below it)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        plan = planner.plan(pose, finger)
    assert plan.certified and np.isfinite(plan.lower_bound)
    p, q, goal, allow = planner.query(pose, finger)
    res = planner.relaxation.solve(p, q, goal, allow, planner.window(p, goal))
    optima = []
    for path in ranked_paths(planner.graph, res, allow):
        status, best, dual = scip_restriction(planner, path, p, q, goal, 1.5 * plan.cost)
        assert status in ("optimal", "gaplimit", "infeasible"), (path, status)
        optima.append((best, dual, path))
    return plan, optima


@pytest.mark.slow  # 24 s: 30 paths through SCIP
def test_the_bound_is_below_every_paths_global_optimum():
    planner = ContactPlanner(SCENE, layers=2, knots=3)
    assert planner.knot_windows and planner.relaxation.knot_arcs  # the chord cuts are on
    t0 = time.perf_counter()
    plan, optima = plan_and_path_optima(planner, *START)
    assert len(optima) >= 20
    print(f"{len(optima)} paths in {time.perf_counter() - t0:.1f} s")
    best, dual, path = min(optima, key=lambda t: t[0])
    assert np.isfinite(best)
    tol = 1e-5 * best
    assert plan.lower_bound <= best + tol, (plan.lower_bound, best, path)
    # Nothing feasible beats SCIP's global bounds: the rounded plan neither (its SNOPT point is feasible).
    assert plan.cost >= min(d for _, d, _ in optima) - tol
    assert (plan.cost - best) / plan.cost <= plan.gap + 1e-5  # the plan is within its certified gap
    print(f"bound {plan.lower_bound:.6f} <= global optimum {best:.6f} (path {path}), plan {plan.cost:.6f}")
