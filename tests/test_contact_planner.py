"""The rotating-box contact planner end to end, checked against evidence it does not produce itself:
the quasi-static model re-integrated from the plan's pushes, the shape's own signed distance, the
friction cone, and the baseline's independent plans against the relaxation's bound."""

from __future__ import annotations

import json
import math
import warnings

import numpy as np
import pytest

from lerobot_gcs_push.contact import ContactPlanner, PlanningError
from lerobot_gcs_push.contact.plan import FREE, PUSH
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
        t = (b - a) / np.linalg.norm(b - a)
        p = a + push["lam"] * (b - a)
        for fn, ft in zip(push["fn"], push["ft"]):
            d = -fn * n + ft * t
            w = kappa * (p[0] * d[1] - p[1] * d[0])
            for _ in range(sub):
                th = pose[2] + 0.5 * w / sub
                rot = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
                pose = pose + np.array([*(rot @ d) / sub, w / sub])
    return pose


def test_plans_reach_the_goal_and_certify_a_bound(plans):
    for plan, (pose, _) in zip(plans, STARTS):
        assert np.allclose(plan.slider_final[:2], SCENE.goal, atol=1e-5)
        # The goal heading up to the square's symmetry, and the nearest copy to the start's heading.
        assert abs(math.remainder(plan.slider_final[2] - SCENE.goal_heading, math.pi / 2)) < 1e-5
        assert abs(plan.goal[2] - pose[2]) <= math.pi / 4 + 1e-9
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
            assert -1e-7 <= push["lam"] <= 1 + 1e-7
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
    """The baseline's one-push plans are paths of the same graph: a valid bound lies below every one."""
    checked = 0
    for plan, (pose, finger) in zip(plans, STARTS):
        try:
            base = planner.baseline(pose, finger)
        except PlanningError:
            continue
        checked += 1
        assert base.cost >= plan.lower_bound - 1e-6
        assert np.allclose(base.slider_final[:2], SCENE.goal, atol=1e-5)
    assert checked >= 1


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
