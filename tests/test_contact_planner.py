"""The rotating-box contact planner end to end, checked against evidence it does not produce itself:
the quasi-static model re-integrated from the plan's pushes, the shape's own signed distance, the
friction cone, and the baseline's independent plans against the relaxation's bound."""

from __future__ import annotations

import json
import math
import warnings

import numpy as np
import pytest

from lerobot_gcs_push.conic.certificate import CERTIFY_TOL, certify, project_dual, solve_with_dual
from lerobot_gcs_push.contact import ContactPlanner
from lerobot_gcs_push.planning import FREE, PUSH, PlanningError
from lerobot_gcs_push.scene import Scene

SCENE = Scene(rotates=True)
STARTS = [
    ((3.0, 2.0, 0.5), (4.5, 2.0)),  # finger behind the box's goal-facing side
    ((-3.0, 1.0, -0.3), (-3.0, -1.5)),  # finger below: it must go round a corner first
    ((-1.5, -3.5, 2.9), (-1.5, -1.0)),  # heading near pi: the symmetric goal heading is near 3 pi / 2... or pi
]


@pytest.fixture(scope="module")
def planner():
    return ContactPlanner(SCENE)


@pytest.fixture(scope="module")
def plans(planner):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # Clarabel's "optimal_inaccurate" at a 1e-7 relative gap
        return [planner.plan(pose, finger) for pose, finger in STARTS]


def integrate(pose, pushes, sub: int = 400):
    """The continuous quasi-static model v = f / b, omega = tau / b_theta, each push step's body-frame
    displacement applied at a constant rate over one unit of time (RK2 on fine sub-steps)."""
    kappa = SCENE.box_damping / SCENE.rot_damping
    faces = SCENE.shape.faces()
    pose = np.array(pose, float)
    for push in pushes:
        a, b, n = faces[push["face"]]
        length = np.linalg.norm(b - a)
        t = (b - a) / length
        lam = push["lam"][0]
        for fn, ft in zip(push["fn"], push["ft"]):
            d = -fn * n + ft * t
            for _ in range(sub):
                # The round finger sticks to the slider's material point under it, which moves along the
                # face by -r dtheta as the slider turns (the finger translates only).
                p = a + lam * (b - a)
                w = kappa * (p[0] * d[1] - p[1] * d[0])
                pm = a + (lam - 0.5 * SCENE.finger_radius * w / sub / length) * (b - a)
                wm = kappa * (pm[0] * d[1] - pm[1] * d[0])
                th = pose[2] + 0.5 * wm / sub
                rot = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
                pose = pose + np.array([*(rot @ d) / sub, wm / sub])
                lam -= SCENE.finger_radius * wm / sub / length
        assert abs(lam - push["lam"][-1]) * length < 0.03  # where the finger ends on the face
    return pose


def test_plans_reach_the_goal_and_certify_a_bound(plans):
    for plan, (pose, _) in zip(plans, STARTS):
        assert np.allclose(plan.slider_final[:2], SCENE.goal, atol=1e-5)
        # The goal heading up to the square's symmetry, and the nearest copy to the start's heading.
        assert abs(math.remainder(plan.slider_final[2] - SCENE.goal_heading, math.pi / 2)) < 1e-5
        assert abs(plan.goal[2] - pose[2]) <= math.pi / 4 + 1e-9
        assert plan.certified and np.isfinite(plan.lower_bound)  # -inf or None would pass any comparison
        assert plan.lower_bound <= plan.cost + 1e-6
        assert 0 <= plan.gap < 0.25


def test_plan_dynamics_hold_when_re_integrated(plans):
    for plan, (pose, _) in zip(plans, STARTS):
        end = integrate(pose, plan.pushes)
        # The planner's discretisation (midpoint translation, sin(dtheta) for dtheta) against the
        # continuous model: millimetres per step at the 0.35 rad per-step cap.
        assert np.linalg.norm(end[:2] - plan.slider_final[:2]) < 0.03
        assert abs(end[2] - plan.slider_final[2]) < 0.03


def test_friction_cone_and_contact_geometry(plans):
    shape, r = SCENE.shape, SCENE.finger_radius
    for plan in plans:
        for push in plan.pushes:
            assert np.all(push["fn"] >= -1e-7)
            assert np.all(np.abs(push["ft"]) <= SCENE.finger_box_friction * push["fn"] + 1e-6)
            assert np.all((-1e-7 <= push["lam"]) & (push["lam"] <= 1 + 1e-7))
        poses, fingers = plan.slider_poses, plan.finger_path
        for k, kind in enumerate(plan.segment_kinds):
            if kind == PUSH:  # touching at both ends of a push step
                for j in (k, k + 1):
                    assert abs(shape.signed_distance(poses[j], fingers[j]) - r) < 1e-5
            else:  # the slider rests; every point of the finger's segment clears it
                assert kind == FREE and np.allclose(poses[k], poses[k + 1])
                for w in np.linspace(0, 1, 25):
                    q = (1 - w) * fingers[k] + w * fingers[k + 1]
                    assert shape.signed_distance(poses[k], q) >= r - 1e-6


def test_start_is_where_the_query_says(plans):
    for plan, (pose, finger) in zip(plans, STARTS):
        assert np.allclose(plan.slider_poses[0], pose)
        assert np.allclose(plan.finger_path[0], finger)


def test_baseline_never_beats_the_bound(planner, plans):
    """The baseline's one-push plans are paths of the same graph: a valid bound lies below every one. The
    baseline plans from every one of these starts (measured), so every comparison runs: a baseline that
    stops planning fails here instead of leaving the bound unchecked."""
    failed = []
    for plan, (pose, finger) in zip(plans, STARTS):
        try:
            base = planner.baseline(pose, finger)
        except PlanningError as err:
            failed.append((pose, str(err)))
            continue
        assert not base.certified  # the baseline certifies nothing
        assert np.isfinite(plan.lower_bound) and base.cost >= plan.lower_bound - 1e-6
        assert np.allclose(base.slider_final[:2], SCENE.goal, atol=1e-5)
    assert not failed, failed


def test_commands_and_json(plans):
    plan = plans[0]
    cmds = plan.commands(10)
    assert np.allclose(cmds[-1], plan.finger_path[-1])
    assert len(cmds) == math.ceil(plan.duration() * 10 - 1e-9)
    steps = np.linalg.norm(np.diff(cmds, axis=0), axis=1)
    assert steps.max() <= 1.0 / 10 + 1e-9  # never faster than the free speed
    out = json.loads(json.dumps(plan.to_json()))
    assert out["cost"] == plan.cost and out["modes"] == plan.modes


def test_finger_inside_the_slider_is_rejected(planner):
    with pytest.raises(ValueError, match="free-space pieces"):
        planner.plan((0.0, 2.0, 0.0), (0.1, 2.1))


def lift(relaxation, graph, plan) -> float:
    """Set the relaxation's variables to the plan's rank-one lift (flow 1 on its path, moment blocks
    z z^T); return the lifted path's cost."""
    for v in relaxation.problem.variables():
        v.value = np.zeros(v.shape)
    path = plan.extra["graph_path"]
    pc, pf, pt = (np.zeros(v.shape) for v in (relaxation.phi_c, relaxation.phi_f, relaxation.phi_t))
    pose = np.array([*plan.slider_poses[0][:2], math.cos(plan.slider_poses[0][2]), math.sin(plan.slider_poses[0][2])])
    cost = 0.0
    for f, c, push, q in zip(path["frees"], path["contacts"], plan.pushes, plan.free_knots):
        pf[f], pc[c] = 1, 1
        fr, rc = relaxation.frees[f], relaxation.contacts[c]
        fr.q.value, fr.pose.value = q, pose
        fr.moments.value = np.outer([1, *pose[2:]], [1, *pose[2:]])
        cost += float(np.sum(np.diff(q, axis=0) ** 2))
        rc.x.value, rc.y.value = push["x"], push["y"]
        for k, m in enumerate(rc.blocks):
            z = [1, push["lam"][k], push["c"][k], push["s"][k], push["fn"][k], push["ft"][k]]
            z = np.array(z + [push["c"][k + 1], push["s"][k + 1], push["lam"][k + 1]])
            m.value = np.outer(z, z)
        for row, moments in rc.cut_rows:
            row.value = moments.value
        cost += float(rc.cost.value)
        pose = np.array([push["x"][-1], push["y"][-1], push["c"][-1], push["s"][-1]])
    pt[path["contacts"][-1]] = 1
    relaxation.phi_c.value, relaxation.phi_f.value, relaxation.phi_t.value = pc, pf, pt
    return cost


def test_rounded_plan_lifts_into_the_relaxation(planner, plans):
    """A relaxation must contain every feasible plan: the rank-one lift of each rounded plan satisfies
    every constraint of the compiled relaxation (so its bound is a bound), at the plan's own cost."""
    relax = planner.relaxation
    for plan, (pose, finger) in zip(plans, STARTS):
        p, q, goal, allow = planner.query(pose, finger)
        relax.set_query(p, q, goal, allow, planner.window(p, goal))
        cost = lift(relax, planner.graph, plan)
        assert cost == pytest.approx(plan.cost, rel=1e-6)
        worst = max(float(np.max(c.violation(), initial=0.0)) for c in relax.problem.constraints)
        assert worst < 1e-6
        assert np.isfinite(plan.lower_bound) and plan.lower_bound <= cost + 1e-6


def test_relaxation_on_the_conic_core_is_cvxpys_program(planner):
    """The relaxation solved from its cached conic data (Clarabel called directly) against cvxpy solving
    the same program: the same optimum; the values read back from the conic solution satisfy every
    constraint of the cvxpy program and evaluate to that optimum (so the unpacking reads each variable
    from the right entries); and the reported bound, the checked dual objective less its residual's
    share (`certify`), lies below it, within 1e-3 of it."""
    import cvxpy as cp

    relax = planner.relaxation
    for pose, finger in STARTS[:2]:
        p, q, goal, allow = planner.query(pose, finger)
        res = relax.solve(p, q, goal, allow, planner.window(p, goal))
        primal = float(relax.problem.objective.value)
        worst = max(float(np.max(c.violation(), initial=0.0)) for c in relax.problem.constraints)
        assert worst < 1e-5
        assert res.certified and res.dual_residual <= CERTIFY_TOL
        assert primal - 1e-3 * primal <= res.bound <= primal + 1e-7 * primal
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            reference = relax.problem.solve(solver=cp.CLARABEL)
        assert reference - 1e-3 * reference <= res.bound <= reference + 1e-6 * reference


def test_a_dual_point_is_checked_not_taken_on_the_solvers_word(planner):
    """`certify` against dual points it must refuse or repair: Clarabel's own point certifies a bound at
    or below its dual objective; the same point with a residual of 1e-3 added (a dual that is not feasible)
    certifies nothing; a point pushed outside the dual cone is projected back, and the bound it then gives
    is still below the primal optimum."""
    relax = planner.relaxation
    pose, finger = STARTS[0]
    p, q, goal, allow = planner.query(pose, finger)
    relax.set_query(p, q, goal, allow, planner.window(p, goal))
    theta = np.concatenate([np.ravel(np.asarray(v.value, float), order="F") for v in relax.params])
    conic = relax.data.at(theta)
    status, x, z = solve_with_dual(conic)
    primal = float(conic.c @ x + conic.d)
    bound, residual = certify(conic, x, z)
    assert status in ("Solved", "AlmostSolved") and bound is not None and residual <= CERTIFY_TOL
    assert bound <= float(conic.d - conic.b @ z) + 1e-12 and bound <= primal
    zero = np.zeros_like(z)
    zero[: conic.zero] = 1e-3 * np.sign(np.random.default_rng(0).standard_normal(conic.zero))
    refused, big = certify(conic, x, z + zero)  # zero-cone duals are free: only the residual can refuse it
    assert refused is None and big > CERTIFY_TOL
    nonneg = slice(conic.zero, conic.zero + conic.nonneg)
    outside = z.copy()
    outside[nonneg] = -1.0  # every nonnegative dual negative
    projected = project_dual(conic, outside)
    assert np.all(projected[nonneg] == 0.0)
    ruined, big = certify(conic, x, outside)  # projected back, but far from dual feasible: nothing certified
    assert ruined is None and big > CERTIFY_TOL
    # A point the projection repairs: the duals of inactive inequalities (below 1e-8) with b > 0 pushed to
    # -1. Taken at its word, its dual objective d - b.z claims more than the optimum (measured: 4 above it);
    # projected back, it certifies the bound of Clarabel's own point again, below the optimum.
    small = conic.zero + np.flatnonzero((z[nonneg] < 1e-8) & (conic.b[nonneg] > 0))
    assert len(small) > 0
    outside = z.copy()
    outside[small] = -1.0
    assert float(conic.d - conic.b @ outside) > primal
    repaired, _ = certify(conic, x, outside)
    assert repaired is not None and repaired <= primal and repaired == pytest.approx(bound, rel=1e-6)
    start = conic.zero + conic.nonneg + sum(conic.soc)
    n = conic.psd[0]
    m = -np.eye(n)  # negative definite: projected to 0
    rows, cols = np.array([(r, c) for c in range(n) for r in range(c + 1)]).T
    bad = z.copy()
    bad[start : start + len(rows)] = m[rows, cols]
    assert np.allclose(project_dual(conic, bad)[start : start + len(rows)], 0.0)


def test_a_solve_the_certificate_refuses_is_repeated_with_refinement(planner, monkeypatch):
    """The first solve skips Clarabel's iterative refinement; where its dual point certifies nothing, the
    same program is solved again with it, and that solve's bound is the one reported: the certificate, not
    the setting, decides."""
    import lerobot_gcs_push.conic.certificate as certificate

    relax = planner.relaxation
    pose, finger = STARTS[0]
    p, q, goal, allow = planner.query(pose, finger)
    relax.set_query(p, q, goal, allow, planner.window(p, goal))
    conic = relax.data.at(np.concatenate([np.ravel(np.asarray(v.value, float), order="F") for v in relax.params]))
    calls, real_solve, real_certify = [], certificate.solve_with_dual, certificate.certify

    def solve(conic, **settings):
        calls.append(settings)
        return real_solve(conic, **settings)

    def refuse_the_first(conic, x, z, tol=CERTIFY_TOL):
        return (None, 1.0) if len(calls) == 1 else real_certify(conic, x, z, tol)

    monkeypatch.setattr(certificate, "solve_with_dual", solve)
    monkeypatch.setattr(certificate, "certify", refuse_the_first)
    status, x, z, bound, residual = certificate.solve_certified(conic)
    assert calls == list(certificate.SOLVES[:2]) and calls[0]["refine"] is False and calls[1].get("refine", True)
    refined = real_certify(conic, *real_solve(conic)[1:])
    assert bound is not None and bound == pytest.approx(refined[0], rel=1e-9) and residual <= CERTIFY_TOL
    assert bound <= float(conic.c @ x + conic.d)


def test_an_uncertified_relaxation_gives_a_plan_that_says_so(monkeypatch, capsys):
    """A solve whose dual point cannot be vouched for: the plan carries no bound (None, not -inf or the
    solver's unchecked number), its gap is None, and the command line prints 'uncertified'."""
    import lerobot_gcs_push.conic.certificate as certificate
    from lerobot_gcs_push.cli import main

    monkeypatch.setattr(certificate, "certify", lambda conic, x, z, tol=CERTIFY_TOL: (None, 1.0))
    pose, finger = STARTS[0]
    plan = ContactPlanner(SCENE).plan(pose, finger)
    assert plan.lower_bound is None and not plan.certified and plan.gap is None
    assert plan.gap_text() == "uncertified" and plan.to_json()["certified"] is False
    assert plan.extra["dual_residual"] == 1.0
    box, heading = list(pose[:2]), pose[2]
    code = main(
        ["plan", "--env_id=GcsPushBoxSE2-v0", f"--box={box}", f"--finger={list(finger)}", f"--heading={heading}"]
    )
    assert code == 0 and "uncertified" in capsys.readouterr().out


@pytest.mark.slow
def test_a_fresh_contact_planner_reads_its_compiled_relaxation(compilations, tmp_path):
    """The first planner of a machine compiles the relaxation and keeps it; a fresh one (another CLI call,
    another worker) compiles nothing and plans the same plan; a damaged file is compiled again."""
    calls = compilations
    pose, finger = STARTS[0]
    first = ContactPlanner(SCENE).plan(pose, finger)
    assert len(calls) == 1 and len(list(tmp_path.glob("contact-relaxation-*.npz"))) == 1
    second = ContactPlanner(SCENE).plan(pose, finger)
    assert len(calls) == 1
    assert second.cost == first.cost and second.lower_bound == first.lower_bound
    (cache,) = tmp_path.glob("contact-relaxation-*.npz")
    cache.write_bytes(cache.read_bytes()[:1000])  # cut short, as by a full disk: compiled and written again
    assert ContactPlanner(SCENE).plan(pose, finger).cost == first.cost
    assert len(calls) == 2
    assert ContactPlanner(SCENE).plan(pose, finger).lower_bound == first.lower_bound and len(calls) == 2
    ContactPlanner(SCENE, rolling=False).warm_up()  # another model: its own program
    assert len(calls) == 3 and len(list(tmp_path.glob("contact-relaxation-*.npz"))) == 2


def test_near_goal_start_is_rescued_by_the_fallback(planner):
    """At the goal but 0.02 rad off: the relaxation's favourite paths are infeasible (it never detects
    infeasible modes); the ranked fallback finds a plan, and its bound stays below it."""
    pose, finger = (0.08546293, 0.09799996, 1.58983568), (-3.30953286, 3.00449116)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        plan = planner.plan(pose, finger)
    assert plan.extra["fallback"]
    assert np.allclose(plan.slider_final[:2], SCENE.goal, atol=1e-5)
    assert np.isfinite(plan.lower_bound) and plan.lower_bound <= plan.cost
    end = integrate(pose, plan.pushes)
    assert np.linalg.norm(end[:2] - plan.slider_final[:2]) < 0.03


@pytest.mark.parametrize("steps, max_step", [(10, 0.2), (16, 0.2)])
def test_knot_windows_hold_every_heading_sequence_a_plan_can_take(steps, max_step):
    """Brute force against `reachable_windows`: heading sequences drawn at random, each step turning at
    most max_step and the last knot on the goal (any of its 2 pi copies in reach, so the T's 16 steps also
    go the long way round), never leave a knot's window, so the cuts restrict no plan."""
    from lerobot_gcs_push.contact.model import reachable_windows

    rng = np.random.default_rng(5)
    for _ in range(300):
        start = rng.uniform(-math.pi, math.pi)
        goal = start + rng.uniform(-1, 1) * min(math.pi, steps * max_step)
        windows = reachable_windows(start, goal, steps, max_step)
        targets = [g for g in goal + 2 * math.pi * np.arange(-2, 3) if abs(g - start) <= steps * max_step]
        assert windows[0] is not None and windows[0].half_width < 1e-5  # knot 0 is the start
        for _ in range(5):
            target, theta = rng.choice(targets), [start]
            for j in range(1, steps + 1):
                left = (steps - j) * max_step  # still to go from knot j: stay where the target is in reach
                lo, hi = max(theta[-1] - max_step, target - left), min(theta[-1] + max_step, target + left)
                lo, hi = min(lo, hi), max(lo, hi)  # equal but for rounding when the target pins the knot
                theta.append(rng.uniform(lo, hi) if rng.random() < 0.6 else rng.choice([lo, hi]))
            for th, w in zip(theta, windows):
                if w is not None:
                    assert w.u @ [math.cos(th), math.sin(th)] >= w.cos_half - 1e-9


def test_split_contact_pieces_refused_with_a_rolling_contact():
    """A rolling contact moves along the face within a push (the finger's radius times the turn), so a
    graph that keeps each push inside half a face misses plans that cross the middle: its bound would not
    be a lower bound, and the planner refuses it; with the contact held still the split stays valid."""
    with pytest.raises(ValueError, match="pieces=2 needs rolling=False"):
        ContactPlanner(SCENE, pieces=2)
    planner = ContactPlanner(SCENE, pieces=2, rolling=False)
    assert planner.graph.pieces == 2 and planner.model.rolling_radius == 0.0
