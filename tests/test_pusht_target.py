"""gym-pusht's own env as a target: the frame maps against gym-pusht's geometry and physics (pymunk, the
other simulator), the resets that land on a reported state, the planner's limit surface against the
block's measured rotation, and the closed-loop expert driving it to gym-pusht's success."""

import math

import gymnasium as gym
import numpy as np
import pytest

import lerobot_gcs_push  # noqa: F401
from lerobot_gcs_push.contact.model import PushModel
from lerobot_gcs_push.pusht.env import GymPushTTarget
from lerobot_gcs_push.pusht.frame import COG_PX, GOAL_STATE, PixelFrame, check_pusht_state, reset_to_state
from lerobot_gcs_push.registration import PUSHT_ENV_ID, SCENES, make_env

gym_pusht = pytest.importorskip("gym_pusht")
SCENE = SCENES[PUSHT_ENV_ID]
FRAME = PixelFrame()


@pytest.fixture(scope="module")
def raw():
    """gym-pusht's env itself, unwrapped, state observations."""
    env = gym.make(PUSHT_ENV_ID, obs_type="state", render_mode="rgb_array", disable_env_checker=True)
    yield env.unwrapped
    env.close()


@pytest.fixture(scope="module")
def target():
    env = make_env(PUSHT_ENV_ID, obs_type="state")
    yield env
    env.close()


def test_metres_and_pixels_map_both_ways():
    rng = np.random.default_rng(0)
    uv = rng.uniform(0, 512, size=(20, 2))
    np.testing.assert_allclose(FRAME.to_px(FRAME.to_m(uv)), uv, atol=1e-9)
    # By hand: the screen's centre is the origin, 60 px right is +1 m, 60 px down is -1 m (y flips).
    np.testing.assert_allclose(FRAME.to_m([[256, 256], [316, 256], [256, 316]]), [[0, 0], [1, 0], [0, -1]])
    for _ in range(20):
        block = np.array([*rng.uniform(60, 450, 2), rng.uniform(0, 2 * math.pi)])
        back = FRAME.block_of_pose(FRAME.pose_of_block(block))
        np.testing.assert_allclose(back[:2], block[:2], atol=1e-9)
        assert math.isclose(back[2], block[2], abs_tol=1e-12)


def test_the_shapes_outline_lands_on_gym_pushts_own_vertices(raw):
    """gym-pusht's T at a reported state, its vertices as pymunk places them (`get_keypoints`), against this
    project's T (about gym-pusht's centre of gravity) at the mapped pose, mapped back to pixels."""
    rng = np.random.default_rng(1)
    for _ in range(5):
        raw.reset(options={"reset_to_state": [*rng.uniform(50, 450, 4), rng.uniform(-math.pi, math.pi)]})
        keypoints = raw.get_keypoints(raw._block_shapes)  # (8, 2) world px, bar then stem
        pose = FRAME.pose_of_block([*raw.block.position, raw.block.angle])
        ours = np.vstack([FRAME.to_px(p) for p in SCENE.shape.world_parts(pose)])
        for k in keypoints:
            assert np.min(np.linalg.norm(ours - k, axis=1)) < 1e-6, k


def test_the_goal_is_gym_pushts_goal_and_coverage_agrees_with_its_own(raw):
    """The scene's goal pose is gym-pusht's goal mapped (coverage 1), and the shape's exact clipping gives
    the coverage gym-pusht computes with shapely after a step, at random poses."""
    np.testing.assert_allclose(SCENE.goal_pose, FRAME.pose_of_block(GOAL_STATE))
    assert SCENE.coverage(SCENE.goal_pose) == pytest.approx(1.0)
    np.testing.assert_allclose(SCENE.goal_pose[2], -math.pi / 4)  # the mirror of GOAL_STATE's pi / 4
    rng = np.random.default_rng(2)
    seen = []
    for _ in range(12):
        near = np.array([*rng.normal(GOAL_STATE[:2], 15), GOAL_STATE[2] + rng.normal(0, 0.2)])
        raw.reset(options={"reset_to_state": reset_to_state([10.0, 10.0, *near])})
        _, _, _, _, info = raw.step(np.array([10.0, 10.0]))  # the agent far away: the block stays put
        pose = FRAME.pose_of_block(info["block_pose"])
        assert SCENE.coverage(pose) == pytest.approx(info["coverage"], abs=1e-9)
        seen.append(info["coverage"])
    assert min(seen) < 0.9 < max(seen)  # the poses span both sides of the success rule


def test_a_reset_to_a_reported_state_reports_that_state(raw, target):
    """gym-pusht's `reset_to_state` moves the block by (I - R(angle)) (0, 45) px; the target lands on it."""
    for seed in range(10):
        reported, _ = raw.reset(seed=seed)
        moved, _ = raw.reset(options={"reset_to_state": reported})
        if abs(math.sin(reported[4] / 2)) > 0.1:
            assert np.linalg.norm(moved[2:4] - reported[2:4]) > 1.0  # why the map is needed
        obs, info = target.reset(options={"pusht_state": reported.tolist()})
        np.testing.assert_allclose(obs, reported, atol=1e-9)
        np.testing.assert_allclose(info["pusht_state"], reported, atol=1e-9)
        # The same start in metres (an initial-condition file's box, finger and heading).
        obs2, _ = target.reset(options={"box": info["box"], "finger": info["finger"], "heading": info["heading"]})
        np.testing.assert_allclose(obs2, reported, atol=1e-6)


def test_a_seed_alone_is_gym_pushts_own_reset(raw, target):
    for seed in (0, 7, 123):
        a, _ = raw.reset(seed=seed)
        b, _ = target.reset(seed=seed)
        np.testing.assert_array_equal(a, b)


def test_starts_from_a_seed_are_gym_pushts_resets_and_land_exactly(raw, target):
    """`--seed` alone: the evaluation's and the generator's starts are gym-pusht's own resets (its
    RandomState from each episode's seed), and a reset to a start's pusht_state reports it to the bit."""
    from lerobot_gcs_push.registration import sample_starts
    from lerobot_gcs_push.scene import episode_seed

    starts = sample_starts(SCENE, 4, seed=9)
    for i, ic in enumerate(starts):
        reported, _ = raw.reset(seed=episode_seed(9, i))
        np.testing.assert_array_equal(ic.pusht_state, reported)
        np.testing.assert_allclose([*ic.box, ic.heading], FRAME.pose_of_block(reported[2:]))
        obs, _ = target.reset(options={"pusht_state": list(ic.pusht_state)})
        np.testing.assert_allclose(obs, reported, atol=1e-9)


def test_info_carries_the_state_in_metres(target):
    obs, info = target.reset(seed=5)
    pose, finger = FRAME.pose_finger_of(obs)
    np.testing.assert_allclose(info["slider_pose"], pose)
    np.testing.assert_allclose(info["finger"], finger)
    assert info["box_goal_distance"] == pytest.approx(np.linalg.norm(pose[:2] - SCENE.goal_array))
    obs, reward, terminated, truncated, info = target.step(obs[:2])
    assert info["sim_time_s"] == pytest.approx(0.1) and not terminated and not truncated
    assert reward == pytest.approx(min(info["coverage"] / 0.95, 1.0))


def test_bad_input_is_refused_by_name(target):
    with pytest.raises(ValueError, match="pusht_state"):
        check_pusht_state([1, 2, 3])
    with pytest.raises(ValueError, match="pusht_state must be finite"):
        target.reset(options={"pusht_state": [1, 2, 3, 4, float("nan")]})
    with pytest.raises(ValueError, match=r"pusht_state's block \(200, -1\) px lies outside gym-pusht's arena"):
        check_pusht_state([100, 10, 200, -1, 0.5])
    check_pusht_state([0, 512, 0, 512, 0.5])  # the arena's edges are in it
    ic = {"pusht_state": [600, 10, 200, 200, 0.5], "box": [0.0, 0.0], "finger": [0.0, 0.0]}
    with pytest.raises(ValueError, match=r"entry 3: pusht_state's agent \(600, 10\) px lies outside"):
        SCENE.validate_start(ic, "entry 3")  # 5.7 m from the centre: beyond the planner's 5.3 m workspace
    assert FRAME.to_m([600, 10])[0] > SCENE.finger_limit
    with pytest.raises(ValueError, match="action must be finite"):
        target.step([float("nan"), 0.0])
    with pytest.raises(ValueError, match="fps"):
        GymPushTTarget(fps=20)
    with pytest.raises(ValueError, match="disturbances"):
        GymPushTTarget(disturbances=True)


def test_the_limit_surface_is_the_blocks_mass_matrix_about_its_centre_of_gravity(raw):
    """The block is first order and contact frictionless, so a push along the stem's side turns it by
    (lever x normal) / c^2 per unit of travel with c^2 = I / m. The planner's model (kappa = 1 / c^2 about
    its frame's origin, the centre of gravity) against gym-pusht's block, pushed slowly at three heights."""
    model = PushModel.from_scene(SCENE)
    assert model.kappa == pytest.approx(1 / (3000 / 60**2))
    for local_y in (60.0, 90.0, 110.0):
        # The T upright (angle 0): the stem's left side at local x = -15; the agent's centre 15 px off it.
        raw.reset(options={"reset_to_state": [256 - 15 - 15.5, 200 + local_y, 256.0, 200.0, 0.0]})
        start = np.array([*raw.block.position, raw.block.angle])
        agent = np.array(raw.agent.position)
        for k in range(1, 9):  # 8 px at 10 px/s
            raw.step(agent + [k * 1.0, 0.0])
        for _ in range(5):
            raw.step(agent + [8.0, 0.0])
        end = np.array([*raw.block.position, raw.block.angle])
        cog0 = start[:2] + COG_PX
        c, s = math.cos(end[2]), math.sin(end[2])
        cog1 = end[:2] + np.array([-s * COG_PX[1], c * COG_PX[1]])
        travel = (cog1 - cog0)[0] / 60.0
        assert travel > 0.02  # it moved
        # In metres, y up: the contact lever from the centre of gravity, the push along +x.
        lever = np.array([-15.0, -(local_y - COG_PX[1])]) / 60.0
        predicted = model.kappa * (lever[0] * 0.0 - lever[1] * 1.0)  # (lever x +x) per metre of travel
        measured = -(end[2] - start[2]) / travel  # heading = -angle
        assert measured == pytest.approx(predicted, rel=0.08), (local_y, measured, predicted)


def test_the_steered_agent_lands_where_it_is_sent_in_gym_pusht(raw):
    """The agent's one-action map (derived from the PD law) inverted: gym-pusht's own agent, from moving
    starts, lands on random points within 1e-6 px; commanded with the point itself it falls short by its lag."""
    from lerobot_gcs_push.pusht.agent import target_for

    rng = np.random.default_rng(3)
    raw.reset(options={"reset_to_state": [256.0, 256.0, 60.0, 60.0, 0.0]})
    raw.step(np.array([300.0, 200.0]))  # moving now
    for _ in range(10):
        goal = np.array(raw.agent.position) + rng.uniform(-25, 25, 2)
        raw.step(target_for(np.array(raw.agent.position), np.array(raw.agent.velocity), goal))
        np.testing.assert_allclose(np.array(raw.agent.position), goal, atol=1e-6)
    start = np.array(raw.agent.position)
    raw.step(start + [20.0, 0.0])
    assert np.array(raw.agent.position)[0] - start[0] < 16.0  # the plain command: lag
    for actions in (2, 3):  # a target held for several actions lands the agent at their end
        goal = np.array(raw.agent.position) + rng.uniform(-40, 40, 2)
        target = target_for(np.array(raw.agent.position), np.array(raw.agent.velocity), goal, actions)
        for _ in range(actions):
            raw.step(target)
        np.testing.assert_allclose(np.array(raw.agent.position), goal, atol=1e-6)


@pytest.mark.slow
def test_the_closed_loop_expert_succeeds_in_gym_pusht():
    """Three of gym-pusht's own resets (seeds no choice used), the expert through contact closed loop:
    success by gym-pusht's rule (its shapely coverage > 0.95) within its 300 steps, the actions in px."""
    from lerobot_gcs_push.episodes.rollout import rollout
    from lerobot_gcs_push.planning.factory import ExpertConfig, make_expert

    env = make_env(PUSHT_ENV_ID, obs_type="state")
    expert = make_expert(env.scene, env.fps, ExpertConfig(mode="closed-loop"))
    for seed in (100, 101, 102):
        actions: list = []
        res = rollout(env, expert, seed=seed, on_step=lambda o, a, i, out=actions: out.append(a))
        assert res["success"] and res["coverage"] > 0.95 and res["sim_time_s"] <= 30.0, (seed, res["coverage"])
        acts = np.array(actions)
        assert acts.min() >= -1.0 and acts.max() <= 513.0  # pixels, not metres
        assert np.ptp(acts) > 50


@pytest.mark.slow
def test_an_agent_far_from_the_t_with_no_plan_from_where_it_stands_goes_to_it_first_and_succeeds():
    """gym-pusht's reset of seed 9777 puts the agent 2.2 m (131 px) from the T's centre of gravity. From
    there no sampled path's restriction solves (SNOPT finds each infeasible); the expert sends the agent
    straight at the T, plans from just beyond its reach, and succeeds within gym-pusht's 300 steps."""
    from lerobot_gcs_push.episodes.rollout import rollout
    from lerobot_gcs_push.planning import PlanningError
    from lerobot_gcs_push.planning.factory import ExpertConfig, make_expert

    env = make_env(PUSHT_ENV_ID, obs_type="state")
    expert = make_expert(env.scene, env.fps, ExpertConfig(mode="closed-loop"))
    planner = expert.expert.planner
    _, info = env.reset(seed=9777)
    slider, finger = planner.plannable(info["slider_pose"], info["finger"])
    assert np.linalg.norm(finger - slider[:2]) > 2.0
    with pytest.raises(PlanningError):
        planner.plan(slider, finger)
    res = rollout(env, expert, seed=9777)
    assert res["success"] and res["coverage"] > 0.95 and res["sim_time_s"] <= 30.0
    assert res["plan"].extra["staged_from"] == pytest.approx(finger.tolist())


@pytest.mark.parametrize("steer_actions", [1, 2, 3])
def test_the_steered_expert_tracks_its_plan_in_gym_pusht_over_n_actions(raw, steer_actions):
    """A hand-made schedule, a 1 m/s ramp to the right (6 px an action), run by `PixelActions` in gym-pusht
    itself, each action re-solved for the plan's point N actions on. Over one action the agent stands on
    each command just sent (within 1e-6 px). Over N > 1 it settles at a constant distance ahead of it on
    the ramp's line (a target held N actions overshoots the first of them), under a third of an action's
    travel for N = 2 (measured 1.8 px; 5.5 for N = 3). Aimed one point early it would trail by 4 px, one
    late it would lead by 8."""
    from types import SimpleNamespace

    from lerobot_gcs_push.planning import FREE, Schedule
    from lerobot_gcs_push.planning.expert import BOX_RULE, PlanExpert
    from lerobot_gcs_push.pusht.agent import PixelActions

    start = np.array([-1.5, -1.5])  # metres: the agent's start, (166, 346) px
    commands = start + np.outer(np.arange(1, 41) * 0.1, [1.0, 0.0])
    inner = PlanExpert(None, 10, SimpleNamespace(mode="open-loop"), rule=BOX_RULE)
    inner._schedule, inner._k = Schedule(commands, [FREE] * 40, np.zeros((40, 3))), 0
    expert = PixelActions(inner, FRAME, "steer", steer_actions)
    raw.reset(options={"reset_to_state": [*FRAME.to_px(start), 450.0, 100.0, 0.0]})
    offsets = []
    for k in range(30):
        info = {"pos_agent": np.array(raw.agent.position), "vel_agent": np.array(raw.agent.velocity)}
        raw.step(expert.act(None, info))
        offsets.append(np.array(raw.agent.position) - FRAME.to_px(commands[k]))
    settled = np.array(offsets[20:])
    np.testing.assert_allclose(settled, np.broadcast_to(settled[0], settled.shape), atol=1e-6)  # a steady state
    assert settled[0][1] == pytest.approx(0.0, abs=1e-9)  # on the ramp's line
    lead = settled[0][0]
    if steer_actions == 1:
        np.testing.assert_allclose(offsets, 0.0, atol=1e-6)
    else:
        assert 0.0 < lead < (2.0 if steer_actions == 2 else 6.0)
    with pytest.raises(ValueError, match="lead_actions"):
        PixelActions(inner, FRAME, "steer", 0)
    with pytest.raises(ValueError, match="commands"):
        PixelActions(inner, FRAME, "velocity", 2)


@pytest.mark.parametrize("lead", [2, 3])
def test_position_commands_are_the_plans_own_points_and_the_agent_rides_the_plan_within_an_action(raw, lead):
    """The same 1 m/s ramp run by position commands: each action is exactly the plan's point `lead` actions
    on (no dependence on the agent's state, so on the ramp the commands' second difference is nil), and in
    gym-pusht itself the PD agent settles on the ramp's line within one action's travel (6 px) of the plan's
    point at the action's end: it trails its command by about one and a half actions."""
    from types import SimpleNamespace

    from lerobot_gcs_push.planning import FREE, Schedule
    from lerobot_gcs_push.planning.expert import BOX_RULE, PlanExpert
    from lerobot_gcs_push.pusht.agent import PixelActions

    start = np.array([-1.5, -1.5])
    commands = start + np.outer(np.arange(1, 41) * 0.1, [1.0, 0.0])
    inner = PlanExpert(None, 10, SimpleNamespace(mode="open-loop"), rule=BOX_RULE)
    inner._schedule, inner._k = Schedule(commands, [FREE] * 40, np.zeros((40, 3))), 0
    expert = PixelActions(inner, FRAME, "position", lead)
    raw.reset(options={"reset_to_state": [*FRAME.to_px(start), 450.0, 100.0, 0.0]})
    sent, offsets = [], []
    for k in range(30):
        info = {"pos_agent": np.array([1e3, -1e3]), "vel_agent": np.array([1e3, 1e3])}  # never read
        action = expert.act(None, info)
        np.testing.assert_allclose(action, FRAME.to_px(commands[k + lead - 1]), atol=1e-9)
        sent.append(action)
        raw.step(action)
        offsets.append(np.array(raw.agent.position) - FRAME.to_px(commands[k]))
    np.testing.assert_allclose(np.diff(sent, 2, axis=0), 0.0, atol=1e-9)
    settled = np.array(offsets[20:])
    np.testing.assert_allclose(settled, np.broadcast_to(settled[0], settled.shape), atol=1e-4)
    assert settled[0][1] == pytest.approx(0.0, abs=1e-9) and abs(settled[0][0]) < 6.0
