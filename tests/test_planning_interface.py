"""The one planning interface: the scene picks the planner, every planner returns a `Plan` and raises
`PlanningError`, one expert runs them all, and a plan's schedule on hand-computed cases."""

import numpy as np
import pytest

from lerobot_gcs_push.box_gcs import GcsPlanner
from lerobot_gcs_push.contact import ContactPlanner
from lerobot_gcs_push.planning import DWELL, FREE, PUSH, Plan, Speeds
from lerobot_gcs_push.planning.expert import BOX_RULE, TURNING_RULE, PlanExpert
from lerobot_gcs_push.planning.factory import ExpertConfig, make_expert, make_planner, speeds_for
from lerobot_gcs_push.pusht.agent import PixelActions
from lerobot_gcs_push.registration import SCENES

BOX, SE2, PUSHT = SCENES["GcsPushBox-v0"], SCENES["GcsPushBoxSE2-v0"], SCENES["gym_pusht/PushT-v0"]


def test_the_scene_picks_the_planner_and_the_expert():
    box = make_planner(BOX)
    assert isinstance(box, GcsPlanner) and box.method == "relaxation"
    assert make_planner(BOX, "micp").method == "micp"
    assert isinstance(make_planner(SE2), ContactPlanner)
    with pytest.raises(ValueError, match="relaxation only"):
        make_planner(SE2, "micp")
    e = make_expert(BOX, 10, ExpertConfig(mode="closed-loop"), box)
    assert type(e) is PlanExpert and e.rule == BOX_RULE and e.speeds == Speeds()
    turning = make_expert(SE2, 10, ExpertConfig(mode="closed-loop"), planner=object())
    assert type(turning) is PlanExpert and turning.rule == TURNING_RULE and turning.speeds.push_dwell_s == 0
    pusht = make_expert(PUSHT, 10, planner=object())
    assert type(pusht) is PixelActions and type(pusht.expert) is PlanExpert
    assert pusht.speeds is speeds_for(PUSHT) and pusht.speeds.push_lead == 0


def test_the_box_planner_returns_the_one_plan_type():
    planner = make_planner(BOX)
    plan = planner.plan([2.0, -1.0], [-3.0, 0.0])
    assert type(plan) is Plan and plan.certified and plan.lower_bound <= plan.cost + 1e-9
    # A bound that means something: finite, below the exact optimum (the MICP's, SCIP), and close to the
    # plan's cost (measured: 10.60 against 11.21, a gap of 5.4 %), not any number below it (-inf passed).
    optimum = planner.plan([2.0, -1.0], [-3.0, 0.0], method="micp").cost
    assert np.isfinite(plan.lower_bound) and plan.lower_bound <= optimum + 1e-6 * optimum
    assert plan.gap < 0.1, plan.gap
    assert plan.slider_poses.shape == (len(plan.segment_kinds) + 1, 2) == (len(plan.finger_path), 2)
    np.testing.assert_allclose(plan.slider_final, BOX.goal_array, atol=1e-5)
    # Its solver failures are PlanningError too (test_box_gcs_planner.py), as the planner through contact's are
    # (test_contact_planner.py); the expert holds the finger where there is no plan (test_expert_turning.py).


def straight_push(length=1.0) -> Plan:
    """Free 1 m to the box's left face, then one push of `length` m along +x (hand-made, the box's shape)."""
    finger = np.array([[-2.0, 0.0], [-1.0, 0.0], [-1.0 + length, 0.0]])
    box = np.array([[0.0, 0.0], [0.0, 0.0], [length, 0.0]])
    return Plan("test", length + 1.0, length + 1.0, 0.0, [], box, finger, [FREE, PUSH], np.array([length, 0.0]))


def test_the_push_lead_passes_the_push_end_only_where_a_dwell_follows():
    plan, fps, lag = straight_push(), 10, 1.0
    with_dwell = Speeds(free=1.0, push=0.5, push_dwell_s=1.0, push_lead=0.8)
    lead = 0.8 * lag * 0.5  # push_lead x lag_s x push speed = 0.4 m
    sched = plan.schedule(fps, with_dwell, lag)
    # Free 1 s, push 2 s, dwell 1 s: 40 commands; during the push every command leads the plan by 0.4 m.
    assert len(sched) == 40 and sched.kinds.count(DWELL) == 10
    t = np.arange(1, 41) / fps
    pushing = (t > 1.0) & (t < 3.0 - 1e-9)
    np.testing.assert_allclose(sched.commands[pushing, 0], -1.0 + 0.5 * (t[pushing] - 1.0) + lead, atol=1e-12)
    assert sched.commands[:, 0].max() == pytest.approx(0.0 + lead - 0.05, abs=1e-12)  # the last push command
    np.testing.assert_allclose(sched.commands[-10:], [[0.0, 0.0]] * 10)  # the dwell holds the push's end
    no_dwell = Speeds(free=1.0, push=0.5, push_dwell_s=0.0, push_lead=0.8)
    sched = plan.schedule(fps, no_dwell, lag)
    assert len(sched) == 30 and sched.commands[:, 0].max() == pytest.approx(0.0)  # never past the end
    t = t[:30]
    on = (t > 1.0) & (t < 1.0 + 2.0 * (1 - lead / 1.0) - 1e-9)  # until the lead reaches the push's end
    np.testing.assert_allclose(sched.commands[on, 0], -1.0 + 0.5 * (t[on] - 1.0) + lead, atol=1e-12)
    np.testing.assert_allclose(sched.commands[~on & (t > 1.0), 0], 0.0, atol=1e-12)


def test_the_reference_is_the_planned_slider_and_duration_counts_dwells():
    plan = straight_push(2.0)
    assert plan.duration(Speeds(free=1.0, push=0.5, push_dwell_s=1.5)) == pytest.approx(1.0 + 4.0 + 1.5)
    assert plan.duration(Speeds(free=1.0, push=0.5, push_dwell_s=0.0)) == pytest.approx(5.0)
    sched = plan.schedule(10, Speeds(free=1.0, push=0.5, push_dwell_s=0.0))
    np.testing.assert_allclose(sched.slider[14], [0.25, 0.0])  # t = 1.5 s: half a second into the push
    assert plan.num_pushes == 1 and plan.finger_length == pytest.approx(3.0)


@pytest.mark.parametrize(
    "field, value",
    [
        ("replan_tolerance", 0.0),
        ("replan_tolerance", float("nan")),
        ("max_replans", -1),
        ("lead_actions", 0),
        ("commands", "velocity"),
    ],
)
def test_expert_settings_out_of_range_are_refused_naming_the_field(field, value):
    with pytest.raises(ValueError, match=field):
        ExpertConfig(**{field: value})


def test_the_pusht_expert_sends_the_configured_commands_with_their_timing():
    """Position commands (the default) run the plan with its acceleration bounded; steered ones as before."""
    default = make_expert(PUSHT, 10, planner=object())
    assert (default.commands, default.lead_actions) == ("position", 3) and default.speeds.accel > 0
    assert make_expert(PUSHT, 10, ExpertConfig(commands="steer"), planner=object()).lead_actions == 2
    steer = make_expert(PUSHT, 10, ExpertConfig(commands="steer", lead_actions=1), planner=object())
    assert (steer.commands, steer.lead_actions) == ("steer", 1) and steer.speeds.accel == 0
