"""The rotating envs `GcsPushBoxSE2-v0` and `GcsPushT-v0`: the yaw joint's physics against hand-computed
and independently integrated quasi-static motion, coverage-based success, the goal outline in pixels, the
heading's sampler and initial-condition files, and the LeRobot configs."""

import dataclasses
import json
import math
import warnings

import gymnasium as gym
import numpy as np
import pytest
from env_checks import passes_gymnasium_checks
from gymnasium.utils.env_checker import check_env
from scipy import stats

import lerobot_gcs_push  # noqa: F401  (registers the env ids)
from lerobot_gcs_push.registration import SCENES
from lerobot_gcs_push.scene import Disturbances, Scene, load_initial_conditions, sample_initial_conditions
from lerobot_gcs_push.sim import PushSim
from lerobot_gcs_push.sim.env import SE2_ENV_ID, TEE_ENV_ID, GcsPushEnv

TEE_SCENE, SE2_SCENE = SCENES[TEE_ENV_ID], SCENES[SE2_ENV_ID]
# By hand (tests/test_shapes.py): the T of bar 2 m reaches r_max^2 = 0.25^2 + (2.3125 / 1.75)^2 from its
# centroid, the unit square 0.5^2 + 0.5^2.
TEE_R_MAX2 = 0.25**2 + (2.3125 / 1.75) ** 2
B = 100.0  # N*s/m, the scene's box_damping
C = 0.6  # the scene's limit_surface_c


@pytest.fixture(scope="module")
def tee_env():
    e = gym.make(TEE_ENV_ID, render_size=96)
    yield e.unwrapped
    e.close()


@pytest.fixture(scope="module")
def tee_sim():
    return PushSim(TEE_SCENE, render_size=None)


# --- Gymnasium API -----------------------------------------------------------------------------------
@pytest.mark.parametrize("env_id", [SE2_ENV_ID, TEE_ENV_ID])
@pytest.mark.parametrize("obs_type", ["pixels_agent_pos", "environment_state_agent_pos", "state"])
def test_check_env_passes(env_id, obs_type):
    env = gym.make(env_id, obs_type=obs_type, render_size=96, disturbances=True)
    obs, info = passes_gymnasium_checks(env)
    if obs_type == "environment_state_agent_pos":
        np.testing.assert_array_equal(obs["environment_state"], info["slider_pose"])
    env.close()


def test_the_box_env_offers_environment_state_with_heading_zero():
    env = gym.make("GcsPushBox-v0", obs_type="environment_state_agent_pos", render_size=96)
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        check_env(env.unwrapped)
    obs, info = env.reset(options={"box": [1.0, -2.0], "finger": [-3.0, 3.0]})
    np.testing.assert_array_equal(obs["environment_state"], [1.0, -2.0, 0.0])
    assert "coverage" not in info  # the box env's info is as it was
    env.close()


def test_registered_scenes_and_workspace():
    # gym-pusht's goal angle pi/4 in its y-down frame is -pi/4 here (y up), not its mirror image.
    assert (TEE_SCENE.slider, TEE_SCENE.rotates, TEE_SCENE.goal_heading) == ("tee", True, -math.pi / 4)
    assert (SE2_SCENE.slider, SE2_SCENE.rotates) == ("box", True)
    e = gym.make(TEE_ENV_ID, render_size=96).unwrapped
    assert e.scene.slider == "tee" and e.task == "Push the red T onto the green outline."
    assert e.sim.plant.num_positions() == 5
    # The slider's sampling region is the box's; the finger's grows by r_max instead of half a side, so
    # the finger can pass around a slider at the region's edge whatever its heading.
    r_max = math.sqrt(TEE_R_MAX2)
    assert e.scene.finger_limit == pytest.approx(4.5 + r_max + 2 * 0.3 + 0.4)
    assert e.scene.box_reach == pytest.approx(e.scene.finger_limit - (r_max + 0.3 + 0.2))
    np.testing.assert_allclose(e.action_space.high, e.scene.finger_limit)
    with pytest.raises(ValueError, match="must rotate"):
        Scene(slider="tee")
    with pytest.raises(ValueError, match="unknown slider"):
        Scene(slider="disc", rotates=True)
    with pytest.raises(ValueError, match="goal heading needs a rotating slider"):
        Scene().with_goal((0.0, 0.0, 1.0))
    box = Scene()  # the paper's box: as before
    assert box.finger_limit == 6.0 and box.box_reach == 5.0 == box.finger_limit - box.approach_distance
    e.close()


# --- physics -----------------------------------------------------------------------------------------
def test_rotational_damping_is_the_limit_surface_of_the_notes():
    # tau_max / f_max = c * r_max, and b_theta / b = (tau_max / f_max)^2.
    assert TEE_SCENE.rot_damping == pytest.approx(B * C**2 * TEE_R_MAX2)  # 65.11 N*m*s/rad
    assert SE2_SCENE.rot_damping == pytest.approx(B * C**2 * 0.5)  # 18 N*m*s/rad


@pytest.mark.parametrize("scene", [TEE_SCENE, SE2_SCENE], ids=["tee", "box"])
def test_constant_wrench_moves_the_slider_at_f_over_b_and_tau_over_b_theta(scene):
    sim = PushSim(scene, render_size=None)
    sim.reset([-1.0, 0.5], [-6.0, -6.0], 0.2)
    wrench = np.array([40.0, -25.0, 9.0])  # N, N, N*m at the centroid
    ticks = round(1.0 / scene.disturbances.tick_s)
    sim.step([-6.0, -6.0], 1.0, np.tile(wrench, (ticks, 1)))  # transients (m / b = 0.05 s) die out
    before = np.array([*sim.box_position(), sim.box_heading()])
    sim.step([-6.0, -6.0], 2.0, np.tile(wrench, (2 * ticks, 1)))
    rate = (np.array([*sim.box_position(), sim.box_heading()]) - before) / 2.0
    b_theta = B * C**2 * (TEE_R_MAX2 if scene.slider == "tee" else 0.5)
    np.testing.assert_allclose(rate, [40.0 / B, -25.0 / B, 9.0 / b_theta], rtol=1e-3)


def test_slider_inertia_is_the_shapes_uniform_lamina(tee_sim):
    # By hand, about the centroid: bar (2.857 kg, 2 x 0.5, 0.4286 m off) + stem (2.143 kg, 0.5 x 1.5,
    # 0.5714 m off), each m (w^2 + h^2) / 12 + m d^2.
    m_bar, m_stem = 5.0 / 1.75, 5.0 * 0.75 / 1.75
    d_bar, d_stem = 1.75 - 2.3125 / 1.75, 2.3125 / 1.75 - 0.75
    izz = m_bar * (4.25 / 12 + d_bar**2) + m_stem * (2.5 / 12 + d_stem**2)
    body = tee_sim._model.box_body
    assert body.default_rotational_inertia().get_moments()[2] == pytest.approx(izz)
    assert body.default_com() == pytest.approx(np.zeros(3), abs=1e-12)


def test_off_centre_push_turns_the_tee_as_the_limit_surface_predicts(tee_sim):
    """The finger pushes the bar's underside right of the stem, straight up: the T must turn
    counter-clockwise, along the quasi-static model v = f / b, omega = tau / b_theta integrated
    independently from the contact wrench the sim measures at each step."""
    scene, sim = TEE_SCENE, tee_sim
    bar_bottom = scene.shape.parts[0][0][1]
    start = np.array([0.75, bar_bottom - scene.finger_radius - 0.05])
    sim.reset([0.0, 0.0], start, 0.0)
    model = np.zeros(3)
    dt, speed = scene.time_step, 0.3
    b_theta = B * C**2 * TEE_R_MAX2
    for k in range(1, 301):
        fx, fy, tau = sim.contact_wrench()
        model += dt * np.array([fx / B, fy / B, tau / b_theta])
        sim.step(start + [0.0, speed * k * dt], dt)
    end = np.array([*sim.box_position(), sim.box_heading()])
    assert end[2] > 0.3  # it turned, counter-clockwise
    # The sim's inertia (m / b = 0.05 s, I / b_theta = 0.04 s) is all that separates the two.
    np.testing.assert_allclose(end, model, atol=0.01)


def quasi_static_push(scene, finger_path, face_y, dt):
    """The planner's model, integrated on its own: a slider at rest at the origin on the ellipsoidal limit
    surface (v = f / b, omega = tau / b_theta), pushed on the face y = face_y (outward normal -y, slider
    frame) by a sphere finger that follows `finger_path`, with Coulomb friction: sticking when the cone
    allows it, else sliding on the cone's edge. Returns the final pose and the steps spent in each mode."""
    b, b_theta = B, B * C**2 * TEE_R_MAX2
    mu, radius = scene.finger_box_friction, scene.finger_radius
    pose, modes = np.zeros(3), {"stick": 0, "slide": 0}
    for prev, now in zip(finger_path[:-1], finger_path[1:]):
        u = (now - prev) / dt  # finger velocity
        c, s = math.cos(pose[2]), math.sin(pose[2])
        n_in, tangent = np.array([-s, c]), np.array([c, s])  # into the face, along it (world)
        local_y = -s * (now[0] - pose[0]) + c * (now[1] - pose[1])
        if face_y - local_y - radius > 1e-4 or n_in @ u <= 0:
            continue  # not touching, or moving away
        r = now + radius * n_in - pose[:2]  # contact point from the centroid

        def contact_velocity(f, r=r):  # of the slider's material point at the contact, under force f
            return f / b + (r[0] * f[1] - r[1] * f[0]) / b_theta * np.array([-r[1], r[0]])

        f = np.linalg.solve(np.column_stack([contact_velocity(e) for e in np.eye(2)]), u)
        if f @ n_in >= 0 and abs(f @ tangent) <= mu * (f @ n_in):
            modes["stick"] += 1
        else:  # sliding: on the cone's edge, the normal speed still the finger's
            d = n_in + np.sign(f @ tangent) * mu * tangent
            f = d * (n_in @ u) / (n_in @ contact_velocity(d))
            modes["slide"] += 1
        pose += dt * np.array([f[0] / b, f[1] / b, (r[0] * f[1] - r[1] * f[0]) / b_theta])
    return pose, modes


@pytest.mark.parametrize(("x", "velocity"), [(0.75, (0.0, 0.3)), (0.9, (-0.1, 0.25))])
def test_pushed_tee_follows_the_quasi_static_model_with_friction(tee_sim, x, velocity):
    """A known push (the finger's path, measured) predicts the T's end pose through the planner's model
    alone, friction included: no contact force from the sim enters the prediction."""
    scene, sim, dt = TEE_SCENE, tee_sim, TEE_SCENE.time_step
    face_y = scene.shape.parts[0][0][1]  # the bar's underside
    start = np.array([x, face_y - scene.finger_radius - 0.02])
    sim.reset([0.0, 0.0], start, 0.0)
    path = [sim.finger_position()]
    for k in range(1, 301):
        sim.step(start + np.array(velocity) * k * dt, dt)
        path.append(sim.finger_position())
    model, modes = quasi_static_push(scene, np.array(path), face_y, dt)
    end = np.array([*sim.box_position(), sim.box_heading()])
    assert end[2] > 0.3 and modes["slide"] > 100  # it turned, and the finger slid along the face
    np.testing.assert_allclose(end, model, atol=0.01)


def test_a_disturbance_pushes_and_twists_by_its_impulse():
    protocol = Disturbances(probability_per_tick=1.0, max_count=1)  # one push at the first tick
    scene = dataclasses.replace(TEE_SCENE, disturbances=protocol)
    e = GcsPushEnv(scene=scene, disturbances=True, render_size=96)
    heading = 0.7
    e.reset(seed=5, options={"box": [1.0, 1.0], "finger": [-5.0, -5.0], "heading": heading})
    for _ in range(30):
        *_, info = e.step([-5.0, -5.0])
    (d,) = info["disturbances"]
    force, point = np.array(d["force"]), np.array(d["point"])
    # The point lies on a face the force pushes into, and the torque is that of the force there.
    assert abs(scene.shape.signed_distance((0, 0, 0), point)) < 1e-9
    rot = np.array([[math.cos(heading), -math.sin(heading)], [math.sin(heading), math.cos(heading)]])
    r = rot @ point
    assert d["torque"] == pytest.approx(r[0] * force[1] - r[1] * force[0])
    assert scene.shape.signed_distance((0, 0, heading), r - 1e-3 * force / np.linalg.norm(force)) > 0
    impulse_s = protocol.duration_ticks * protocol.tick_s
    np.testing.assert_allclose(info["box"] - [1.0, 1.0], force * impulse_s / B, atol=2e-3)
    b_theta = B * C**2 * TEE_R_MAX2
    assert info["heading"] - heading == pytest.approx(d["torque"] * impulse_s / b_theta, abs=2e-3)
    assert abs(info["heading"] - heading) > 0.05  # it twisted
    e.close()


# --- success and info --------------------------------------------------------------------------------
@pytest.mark.parametrize("env_id", [SE2_ENV_ID, TEE_ENV_ID])
def test_success_at_exactly_the_goal_pose(env_id):
    e = gym.make(env_id, render_size=96).unwrapped
    goal = e.scene.goal_pose
    _, info = e.reset(options={"box": goal[:2], "finger": [-5.0, -5.0], "heading": goal[2] + 2 * math.pi})
    assert info["is_success"] and info["coverage"] == pytest.approx(1.0, abs=1e-12)
    assert info["position_error"] == 0.0 and info["heading_error"] == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(info["slider_pose"], goal, atol=1e-12)  # heading wrapped to [-pi, pi)
    _, reward, terminated, _, info = e.step([-5.0, -5.0])
    assert terminated and reward == 1.0
    e.close()


def test_success_is_95_percent_coverage():
    e = gym.make(SE2_ENV_ID, render_size=96).unwrapped
    # The unit box shifted by d along a side covers 1 - d of its goal (goal heading 0).
    _, info = e.reset(options={"box": [0.06, 0.0], "finger": [-5.0, -5.0]})
    assert info["coverage"] == pytest.approx(0.94) and not info["is_success"]
    _, reward, terminated, _, info = e.step([-5.0, -5.0])
    assert not terminated and reward == pytest.approx(0.94 / 0.95)
    _, info = e.reset(options={"box": [0.04, 0.0], "finger": [-5.0, -5.0]})
    assert info["coverage"] == pytest.approx(0.96) and info["is_success"]
    # A quarter turn looks the same to coverage; the heading error still reports it.
    _, info = e.reset(options={"box": [0.0, 0.0], "finger": [-5.0, -5.0], "heading": -math.pi / 2})
    assert info["is_success"] and info["heading_error"] == pytest.approx(-math.pi / 2)
    e.close()


def test_heading_error_is_wrapped():
    assert TEE_SCENE.heading_error(-math.pi / 4 + math.pi) == pytest.approx(-math.pi)
    assert TEE_SCENE.heading_error(-math.pi / 4 - 3 * math.pi / 2) == pytest.approx(math.pi / 2)


# --- image -------------------------------------------------------------------------------------------
def distance_to_outline(points, outline):
    out = np.full(len(points), np.inf)
    for a, b in zip(outline, np.roll(outline, -1, axis=0)):
        t = np.clip((points - a) @ (b - a) / ((b - a) @ (b - a)), 0, 1)
        out = np.minimum(out, np.linalg.norm(points - (a + t[:, None] * (b - a)), axis=1))
    return out


def test_goal_outline_is_drawn_at_the_goal_pose(tee_env):
    obs, _ = tee_env.reset(options={"box": [3.5, -3.0], "finger": [-3.0, 3.0], "heading": 0.3})
    img = obs["pixels"].astype(int)
    green = (img[..., 1] - img[..., 0] > 40) & (img[..., 1] - img[..., 2] > 30)
    rows, cols = np.nonzero(green)
    world = tee_env.sim.pixel_to_world(np.stack([rows, cols], axis=1), z=0.0)
    px = 2 * tee_env.scene.view_half_width / 96
    shape, goal = tee_env.scene.shape, tee_env.scene.goal_pose
    # Every goal-coloured pixel is on the outline (within its half width, the pixel's half diagonal and
    # the renderer's anti-aliasing fringe), ...
    near = distance_to_outline(world, shape.world_outline(goal))
    assert len(rows) > 60 and near.max() < 2.5 * px
    # ... and the outline runs through goal-coloured pixels all the way round.
    outline = shape.world_outline(goal)
    along = np.vstack([a + np.linspace(0, 1, 50)[:, None] * (b - a) for a, b in zip(outline, np.roll(outline, -1, 0))])
    hit = [green[tuple(np.clip(np.round(tee_env.sim.world_to_pixel(p, z=0.0)).astype(int), 0, 95))] for p in along]
    assert np.mean(hit) > 0.9
    # A T at another heading would not fit these pixels.
    for heading in (goal[2] - math.pi / 2, goal[2] + math.pi / 2, goal[2] + math.pi):
        wrong = distance_to_outline(world, shape.world_outline([*goal[:2], heading]))
        assert wrong.max() > 3.5 * px


# --- initial conditions ------------------------------------------------------------------------------
@pytest.mark.parametrize("sampler", ["uniform", "sobol"])
def test_sampler_draws_headings_uniformly_and_collision_free(sampler):
    ics = sample_initial_conditions(TEE_SCENE, 400, seed=3, sampler=sampler)
    heading = np.array([ic.heading for ic in ics])
    assert np.all(heading >= -math.pi) and np.all(heading < math.pi)
    assert stats.kstest((heading + math.pi) / (2 * math.pi), "uniform").pvalue > 0.01
    box, finger = np.array([ic.box for ic in ics]), np.array([ic.finger for ic in ics])
    assert np.abs(box).max() <= TEE_SCENE.box_init_half_width
    assert np.abs(finger).max() <= TEE_SCENE.finger_init_half_width
    assert min(TEE_SCENE.finger_box_gap(b, f, h) for b, f, h in zip(box, finger, heading)) >= 0
    assert ics[:10] == sample_initial_conditions(TEE_SCENE, 10, seed=3, sampler=sampler)
    with pytest.raises(ValueError, match="hard"):
        sample_initial_conditions(TEE_SCENE, 1, sampler="hard")


def test_drake_collision_query_agrees_with_the_shape(tee_sim):
    rng = np.random.default_rng(2)
    for _ in range(300):
        box, finger, heading = rng.uniform(-1, 1, 2), rng.uniform(-2.5, 2.5, 2), rng.uniform(-math.pi, math.pi)
        gap = TEE_SCENE.finger_box_gap(box, finger, heading)
        drake = tee_sim.signed_distance(box, finger, heading)
        assert (drake < 0) == (gap < 0) or abs(gap) < 1e-6
        if gap > 0:
            assert drake == pytest.approx(gap, abs=1e-6)


def test_reset_samples_collision_free_poses(tee_env):
    headings = []
    for seed in range(15):
        _, info = tee_env.reset(seed=seed)
        assert not tee_env.sim.collides(info["box"], info["finger"], info["heading"])
        assert TEE_SCENE.finger_box_gap(info["box"], info["finger"], info["heading"]) >= 0
        headings.append(info["heading"])
    assert np.ptp(headings) > math.pi  # headings spread, not all 0


def test_initial_condition_files_with_and_without_heading(tmp_path, tee_env):
    ics = sample_initial_conditions(TEE_SCENE, 3, seed=0)
    new, old = tmp_path / "new.json", tmp_path / "old.json"
    new.write_text(json.dumps([ic.to_json() for ic in ics]))
    old.write_text(json.dumps([{"box": [2.0, 1.0], "finger": [-4.0, -4.0]}]))
    loaded = load_initial_conditions(new)
    assert [item["heading"] for item in loaded] == [ic.heading for ic in ics]
    _, info = tee_env.reset(options=loaded[1])
    assert info["heading"] == pytest.approx(ics[1].heading)
    (item,) = load_initial_conditions(old)
    assert "heading" not in item
    _, info = tee_env.reset(options=item)
    assert info["heading"] == 0.0
    # The box's samples and files keep their format: no heading.
    assert "heading" not in sample_initial_conditions(Scene(), 1)[0].to_json()
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps([{"box": [0, 0], "finger": [3, 3], "heading": "north"}]))
    with pytest.raises(ValueError, match="entry 0.*heading"):
        load_initial_conditions(bad)


def test_bad_rotating_initial_conditions_raise(tee_env):
    # The stem hangs below the centroid at heading 0; turned a half turn, it points up, into the finger.
    with pytest.raises(ValueError, match="overlaps"):
        tee_env.reset(options={"box": [0.0, 0.0], "finger": [0.0, 1.0], "heading": math.pi})
    tee_env.reset(options={"box": [0.0, 0.0], "finger": [0.0, 1.0], "heading": 0.0})
    with pytest.raises(ValueError, match="heading"):
        tee_env.reset(options={"box": [0.0, 0.0], "finger": [3.0, 3.0], "heading": float("nan")})
    box_env = GcsPushEnv(render_size=96)
    with pytest.raises(ValueError, match="cannot rotate"):
        box_env.reset(options={"box": [0.0, 0.0], "finger": [3.0, 3.0], "heading": 0.5})
    box_env.close()


# --- LeRobot -----------------------------------------------------------------------------------------
@pytest.mark.parametrize(("env_type", "env_id"), [("gcs_push_t", TEE_ENV_ID), ("gcs_push_se2", SE2_ENV_ID)])
def test_lerobot_env_configs(env_type, env_id):
    from lerobot.envs import make_env, make_env_config

    import lerobot_gcs_push.lerobot_plugin  # noqa: F401

    cfg = make_env_config(env_type, episode_length=3, success_coverage=0.9)
    assert cfg.gym_id == env_id and "success_threshold" not in cfg.gym_kwargs
    vec = make_env(cfg, n_envs=1)[env_type][0]
    try:
        obs, _ = vec.reset(seed=0)
        assert obs["pixels"].shape == (1, 96, 96, 3) and obs["agent_pos"].shape == (1, 2)
        env = vec.envs[0].unwrapped
        assert env.scene.rotates and env.scene.success_coverage == 0.9
        assert vec.call("task")[0] == env.scene.task
        *_, info = vec.step(obs["agent_pos"])
        assert {"is_success", "coverage", "position_error", "heading_error"} <= set(info)
    finally:
        vec.close()
