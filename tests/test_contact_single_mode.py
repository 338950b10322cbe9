"""One sticking contact mode against independent evidence: SCIP's global optimum of the nonconvex
program (written here from the physics, not from the planner's forms) must lie between the relaxation's
bound and the rounded plan's cost."""

from __future__ import annotations

import math
import warnings

import cvxpy as cp
import numpy as np
import pytest

from lerobot_gcs_push.contact.face_contact import S1, NlpFaceContact, RelaxedFaceContact, step_forms
from lerobot_gcs_push.contact.model import PushModel
from lerobot_gcs_push.contact.relaxation import pose_moments, pose_vector
from lerobot_gcs_push.scene import Scene

MODEL = PushModel.from_scene(Scene(rotates=True))
ROT_W = MODEL.r_max**2
KNOTS = 3
FACE = MODEL.faces[3]  # the left face: pushing it moves the box along +x


def step(pose, face, lam, fn, ft):
    """The discrete model, independently: sin(dtheta) = kappa p x d with p the contact at the step's
    mean lam, the contact rolling back by r sin(dtheta) along the face, midpoint translation. Returns the
    next pose and lam."""
    d = -fn * face.n + ft * face.t
    length = float(np.linalg.norm(face.e))
    roll = MODEL.finger_radius / length
    p = face.a + lam * face.e
    # S = kappa (a + (lam - roll S / 2) e) x d, solved for S.
    sin_dth = MODEL.kappa * (p[0] * d[1] - p[1] * d[0])
    sin_dth /= 1 + MODEL.kappa * roll / 2 * (face.e[0] * d[1] - face.e[1] * d[0])
    th1 = pose[2] + math.asin(sin_dth)
    rm = (np.array([math.cos(pose[2]), math.sin(pose[2])]) + np.array([math.cos(th1), math.sin(th1)])) / 2
    dx = rm[0] * d[0] - rm[1] * d[1]
    dy = rm[1] * d[0] + rm[0] * d[1]
    return np.array([pose[0] + dx, pose[1] + dy, th1]), lam - roll * sin_dth


def target(start, lam, pushes):
    pose = np.asarray(start, float)
    for fn, ft in pushes:
        pose, lam = step(pose, FACE, lam, fn, ft)
    return pose


def relaxed_bound(start, goal):
    forms = step_forms(FACE, MODEL, ROT_W)
    m = RelaxedFaceContact(FACE, MODEL, forms, KNOTS, 1.0)
    cons = list(m.constraints)
    cons += [m.pose(False) == pose_vector(start), m.pose(True) == pose_vector(goal)]
    cons += [m.pose_moments(False) == pose_moments(start), m.pose_moments(True) == pose_moments(goal)]
    prob = cp.Problem(cp.Minimize(m.cost), cons)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        prob.solve(solver=cp.CLARABEL)
    assert prob.status.startswith("optimal"), prob.status
    return prob.value, m.values(1.0)


def scip_optimum(start, goal):
    from pyscipopt import Model, quicksum

    s = Model()
    s.hideOutput()
    s.setParam("limits/gap", 1e-7)
    s.setParam("limits/time", 60)
    lam = [s.addVar(lb=0, ub=1) for _ in range(KNOTS)]
    c = [s.addVar(lb=-1, ub=1) for _ in range(KNOTS)]
    sn = [s.addVar(lb=-1, ub=1) for _ in range(KNOTS)]
    x = [s.addVar(lb=-10, ub=10) for _ in range(KNOTS)]
    y = [s.addVar(lb=-10, ub=10) for _ in range(KNOTS)]
    fn = [s.addVar(lb=0, ub=10) for _ in range(KNOTS - 1)]
    ft = [s.addVar(lb=-10, ub=10) for _ in range(KNOTS - 1)]
    obj = s.addVar(lb=0, ub=1e3)
    n, t, a, e = FACE.n, FACE.t, FACE.a, FACE.e
    for k, v in enumerate(pose_vector(start)):
        s.addCons([x[0], y[0], c[0], sn[0]][k] == v)
    for k, v in enumerate(pose_vector(goal)):
        s.addCons([x[-1], y[-1], c[-1], sn[-1]][k] == v)
    cost = []
    for k in range(KNOTS):
        s.addCons(c[k] * c[k] + sn[k] * sn[k] == 1)
    for k in range(KNOTS - 1):
        dx = -fn[k] * n[0] + ft[k] * t[0]
        dy = -fn[k] * n[1] + ft[k] * t[1]
        mid = (lam[k] + lam[k + 1]) / 2
        px, py = a[0] + mid * e[0], a[1] + mid * e[1]
        sin_dth = c[k] * sn[k + 1] - sn[k] * c[k + 1]
        s.addCons(sin_dth == MODEL.kappa * (px * dy - py * dx))
        s.addCons(lam[k + 1] == lam[k] - MODEL.finger_radius / float(np.linalg.norm(e)) * sin_dth)
        s.addCons(x[k + 1] - x[k] == ((c[k] + c[k + 1]) * dx - (sn[k] + sn[k + 1]) * dy) / 2)
        s.addCons(y[k + 1] - y[k] == ((sn[k] + sn[k + 1]) * dx + (c[k] + c[k + 1]) * dy) / 2)
        s.addCons(ft[k] <= MODEL.mu * fn[k])
        s.addCons(-ft[k] <= MODEL.mu * fn[k])
        s.addCons(c[k] * c[k + 1] + sn[k] * sn[k + 1] >= math.cos(0.35))
        cost.append(fn[k] * fn[k] + ft[k] * ft[k] + ROT_W * (2 - 2 * (c[k] * c[k + 1] + sn[k] * sn[k + 1])))
    s.addCons(quicksum(cost) <= obj)
    s.setObjective(obj, "minimize")
    s.optimize()
    assert s.getStatus() in ("optimal", "gaplimit"), s.getStatus()  # gaplimit: within 1e-7 relative
    return s.getObjVal(), s.getDualbound()


def rounded_cost(start, goal, guess):
    from pydrake.solvers import MathematicalProgram, SnoptSolver

    prog = MathematicalProgram()
    m = NlpFaceContact(prog, FACE, MODEL, step_forms(FACE, MODEL, ROT_W), KNOTS, "m")
    for u, v in zip(m.pose(False), pose_vector(start)):
        prog.AddLinearEqualityConstraint(u - v, 0.0)
    for u, v in zip(m.pose(True), pose_vector(goal)):
        prog.AddLinearEqualityConstraint(u - v, 0.0)
    m.set_guess(prog, guess)
    res = SnoptSolver().Solve(prog)
    assert res.is_success()
    return res.get_optimal_cost()


# Targets reached by known pushes (so feasible): central, off-centre, and with a sideways slip.
CASES = [
    ((-2.0, 0.5, 0.2), 0.5, [(0.8, 0.0), (0.6, 0.02)]),
    ((-2.0, 0.5, 0.2), 0.2, [(0.15, 0.01), (0.12, 0.01)]),
    ((1.0, -1.0, -0.4), 0.8, [(0.2, -0.02), (0.15, 0.015)]),
]


@pytest.mark.parametrize("start,lam,pushes", CASES)
def test_bound_below_global_optimum_and_rounding_within_gap(start, lam, pushes):
    goal = target(start, lam, pushes)
    bound, guess = relaxed_bound(start, goal)
    opt, dual = scip_optimum(start, goal)
    cost = rounded_cost(start, goal, guess)
    tol = 1e-5 * max(1.0, opt)
    assert bound <= opt + tol, (bound, opt)
    assert cost >= dual - tol, (cost, dual)  # SCIP's dual bound is global: nothing feasible beats it
    assert cost - opt <= (cost - bound) + tol  # the plan is within its reported gap of the optimum
    assert (cost - bound) / cost < 0.05  # inside the motion cone one mode's relaxation is tight


def test_model_dynamics_match_the_forms():
    """A known push sequence satisfies the planner's equality forms to round-off (the forms encode the
    same model as the independent `step` above)."""
    forms = step_forms(FACE, MODEL, ROT_W)
    start, lam = np.array([0.3, -0.2, 0.6]), 0.35
    p1, lam1 = step(start, FACE, lam, 0.3, -0.02)
    assert abs(lam1 - lam) > 1e-3  # the push turns the box, so the contact rolls
    z = [1, lam, math.cos(start[2]), math.sin(start[2]), 0.3, -0.02, math.cos(p1[2]), math.sin(p1[2]), lam1]
    z = np.array(z)
    pos = np.array([start[0], p1[0], start[1], p1[1]])
    residual = np.einsum("i,mij,j->m", z, forms.eq_q, z) + forms.eq_l @ pos
    assert np.max(np.abs(residual)) < 1e-12
    assert np.all(np.einsum("i,mij,j->m", z, forms.ineq_q, z) >= -1e-12)
    assert np.all(np.einsum("i,mij,j->m", z, forms.redundant_q, z) >= -1e-12)  # RLT cuts keep feasible points
    z_bad = z.copy()
    z_bad[S1] = -z_bad[S1]  # a heading that the rotation equation rejects
    assert np.max(np.abs(np.einsum("i,mij,j->m", z_bad, forms.eq_q, z_bad) + forms.eq_l @ pos)) > 1e-2


def test_a_planned_turning_push_replayed_in_the_sim_ends_at_the_planned_pose():
    """The model above (`step`, which the planner's forms encode) against Drake: the sim's finger, driven
    along the knots of a push that turns the box by ~0.6 rad, leaves the box at the planned pose and itself
    at the planned contact. The finger is a sphere that cannot turn, so its contact rolls ~18 cm along the
    face; a model that held the contact still ended 15-20 cm off (experiments/rotation/README.md)."""
    from lerobot_gcs_push.registration import SCENES, SE2_ENV_ID
    from lerobot_gcs_push.sim import PushSim

    scene = SCENES[SE2_ENV_ID]
    face, r = FACE, scene.finger_radius
    pose, lam = np.array([0.0, 0.0, 0.0]), 0.2  # the left face, 0.3 m above the centre: the box turns
    poses, lams = [pose], [lam]
    for _ in range(10):
        pose, lam = step(pose, face, lam, 0.12, 0.0)
        poses.append(pose)
        lams.append(lam)
    poses, lams = np.array(poses), np.array(lams)

    def finger(p, lam_k):  # the finger's centre in the world, touching the face at lam_k
        q = face.a + lam_k * face.e + r * face.n
        c, s = math.cos(p[2]), math.sin(p[2])
        return p[:2] + np.array([c * q[0] - s * q[1], s * q[0] + c * q[1]])

    knots = np.array([finger(p, lam_k) for p, lam_k in zip(poses, lams)])
    assert poses[-1][2] < -0.5 and (lams[-1] - lams[0]) * np.linalg.norm(face.e) > 0.15  # turns and rolls
    sim = PushSim(scene, render_size=None)
    sim.reset([0.0, 0.0], knots[0] - 0.03 * face.n, 0.0)  # 3 cm off the face, slider frame = world here
    dt, speed, lead = scene.time_step, 0.1, 0.85  # Speeds.push_lead: the PID integral takes up the rest
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(knots, axis=0), axis=1))])
    times = arc / speed
    for t in np.arange(dt, times[-1] + 2.0, dt):
        target = np.array([np.interp(t, times, knots[:, i]) for i in range(2)])
        k = min(np.searchsorted(times, t) - 1, len(times) - 2)
        if t < times[-1]:  # the finger trails its command by v * lag while it pushes: lead it by as much
            target += lead * scene.push_lag_s * (poses[k + 1, :2] - poses[k, :2]) / (times[k + 1] - times[k])
        sim.step(target, dt)
    end = np.array([*sim.box_position(), sim.box_heading()])
    assert np.linalg.norm(end[:2] - poses[-1][:2]) < 0.02, (end, poses[-1])
    assert abs(end[2] - poses[-1][2]) < 0.02, (end, poses[-1])
    assert np.linalg.norm(sim.finger_position() - knots[-1]) < 0.02
