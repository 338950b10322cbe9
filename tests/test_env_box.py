"""Behaviour of the Drake sim and the `GcsPushBox-v0` env: physics, images, disturbances, bad input."""

import dataclasses
import math

import gymnasium as gym
import numpy as np
import pytest
from env_checks import passes_gymnasium_checks

import lerobot_gcs_push  # noqa: F401  (registers the env ids)
from lerobot_gcs_push.scene import Disturbances, Scene
from lerobot_gcs_push.sim import TopDownCamera
from lerobot_gcs_push.sim.env import ENV_ID, DisturbanceSchedule, GcsPushEnv, register_envs

SCENE = Scene()


@pytest.fixture(scope="module")
def env():
    e = GcsPushEnv()
    yield e
    e.close()


def hold(env, target, seconds):
    for _ in range(round(seconds * env.fps)):
        *_, info = env.step(np.asarray(target, float))
    return info


def ramp(env, start, end, speed):
    """Command a straight line from `start` to `end` at `speed` m/s, one target per env step."""
    start, end = np.asarray(start, float), np.asarray(end, float)
    n = math.ceil(np.linalg.norm(end - start) / speed * env.fps)
    for k in range(1, n + 1):
        env.step(start + (end - start) * k / n)


# --- Gymnasium API -----------------------------------------------------------------------------------
@pytest.mark.parametrize("obs_type", ["pixels_agent_pos", "state"])
def test_check_env_passes(obs_type):
    env = gym.make("GcsPushBox-v0", obs_type=obs_type)
    passes_gymnasium_checks(env)
    env.close()


def test_the_registered_id_makes_the_env_without_time_limit():
    register_envs()  # idempotent
    register_envs()
    # one registration per id: the box, and the rotating box and T beside it
    assert [i for i in gym.registry if i.startswith("GcsPush")] == [ENV_ID, "GcsPushBoxSE2-v0", "GcsPushT-v0"]
    e = gym.make(ENV_ID, max_sim_time_s=0.3, render_size=96)
    assert isinstance(e.unwrapped, GcsPushEnv)
    assert e.get_wrapper_attr("_max_episode_steps") == 3
    assert e.spec.max_episode_steps is None  # our own truncation is the only one
    assert e.unwrapped.metadata["render_fps"] == 10
    assert e.unwrapped.task == e.unwrapped.task_description == "Push the red box onto the green goal."
    e.close()


def test_actions_outside_the_action_space_are_clipped_to_it():
    e = GcsPushEnv(max_sim_time_s=30, render_size=96)
    e.reset(options={"box": [-3.0, -3.0], "finger": [3.0, 3.0]})
    lim = e.scene.finger_limit
    assert np.all(e.action_space.high == lim)
    for _ in range(60):
        _, _, _, _, info = e.step([100.0, 100.0])
    # The finger settles at the corner of its square (within the PID's millimetres), not beyond it.
    np.testing.assert_allclose(info["finger"], [lim, lim], atol=0.02)


def test_truncation_success_and_info():
    e = GcsPushEnv(fps=20, max_sim_time_s=0.2, goal=(1.0, 1.0), render_size=96)
    assert e._max_episode_steps == 4 and e.metadata["render_fps"] == 20
    _, info = e.reset(options={"box": [1.05, 1.0], "finger": [-3.0, -3.0]})
    assert info["is_success"] and info["box_goal_distance"] == pytest.approx(0.05)
    assert set(info) >= {
        "is_success",
        "box_goal_distance",
        "box",
        "finger",
        "sim_time_s",
        "disturbances",
        "goal",
        "slider_pose",
    }
    np.testing.assert_array_equal(info["goal"], [1.0, 1.0])
    # Every env reports the slider's pose [x, y, heading]; the box's heading is always 0.
    np.testing.assert_array_equal(info["slider_pose"], [*info["box"], 0.0])
    flags = [e.step(np.array([-3.0, -3.0]))[2:4] for _ in range(4)]
    assert all(terminated for terminated, _ in flags)
    assert [truncated for _, truncated in flags] == [False, False, False, True]
    assert e.step(np.array([-3.0, -3.0]))[4]["sim_time_s"] == pytest.approx(0.25)
    assert e.render().shape == (96, 96, 3) and e.render().dtype == np.uint8


def test_same_seed_same_observations():
    e = GcsPushEnv(disturbances=True, render_size=96)

    def rollout(seed):
        obs, info = e.reset(seed=seed)
        frames, states = [obs["pixels"]], [np.concatenate([obs["agent_pos"], info["box"]])]
        action_rng = np.random.default_rng(0)
        for _ in range(40):
            obs, _, _, _, info = e.step(action_rng.uniform(-3, 3, size=2))
            frames.append(obs["pixels"])
            states.append(np.concatenate([obs["agent_pos"], info["box"]]))
        return np.stack(frames), np.stack(states), info["disturbances"]

    a, b, c = rollout(3), rollout(3), rollout(4)
    assert a[2], "seed 3 should see a disturbance within 4 s (p = 0.86)"
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])
    assert a[2] == b[2]
    assert not np.array_equal(a[0][0], c[0][0])
    # A fresh env with the same seed reproduces it too: nothing leaks between envs or episodes.
    fresh = GcsPushEnv(disturbances=True, render_size=96)
    np.testing.assert_array_equal(fresh.reset(seed=3)[0]["pixels"], a[0][0])


def test_reset_samples_collision_free_states_in_the_workspace(env):
    for seed in range(20):
        _, info = env.reset(seed=seed)
        assert np.max(np.abs(info["box"])) <= SCENE.box_init_half_width
        assert np.max(np.abs(info["finger"])) <= SCENE.finger_init_half_width
        assert SCENE.finger_box_gap(info["box"], info["finger"]) >= 0
        assert info["sim_time_s"] == 0.0


# --- physics -----------------------------------------------------------------------------------------
def test_plant_has_four_positions_and_box_never_rotates(env):
    assert env.sim.plant.num_positions() == 4 and env.sim.plant.num_velocities() == 4
    box = np.array([0.5, -0.5])
    env.reset(options={"box": box, "finger": box - [0.0, SCENE.contact_distance]})
    # Push off-centre along a diagonal: a rotating box would turn here.
    ramp(env, box - [0.0, SCENE.contact_distance], box + [1.0, 1.0], speed=0.5)
    np.testing.assert_array_equal(env.sim.box_pose().rotation().matrix(), np.eye(3))
    assert env.sim.box_pose().translation()[2] == SCENE.box_half
    assert np.linalg.norm(env.sim.box_position() - box) > 0.3  # it was pushed


def test_diagram_inputs_are_found_by_name(env):
    assert env.sim.diagram.GetInputPort("finger_command").size() == 2  # finger (x, y)
    assert env.sim.diagram.GetInputPort("applied_force").size() == 4  # one per plant velocity


def test_push_moves_box_one_metre(env):
    box = np.array([-1.0, 0.5])
    finger = box - [SCENE.contact_distance, 0.0]  # touching the centre of the left face
    env.reset(options={"box": box, "finger": finger})
    ramp(env, finger, finger + [1.0, 0.0], speed=0.2)
    info = hold(env, finger + [1.0, 0.0], seconds=10.0)
    moved = info["box"] - box
    # The box ends where the finger stops, plus the PID's integral windup: while pushing, the finger lags
    # by box_damping * v / kp, and ki integrates that lag into an overshoot of about
    # (ki / kp) * (box_damping / kp) * distance = 1 cm per metre pushed, which decays over ~kp / ki = 100 s.
    # Contact compliance is below a millimetre. 2 cm holds that with margin; the y error is only numerical.
    assert abs(moved[0] - 1.0) < 0.02, moved
    assert abs(moved[1]) < 0.01, moved
    assert abs(moved[1]) < 1e-9  # the symmetric push has no y force at all


def test_free_finger_never_moves_box(env):
    box = np.array([2.5, 2.5])
    env.reset(options={"box": box, "finger": [-4.0, -4.0]})
    for corner in ([-4.0, 1.0], [0.5, 1.0], [0.5, -4.0], [-4.0, -4.0]):
        ramp(env, env.sim.finger_position(), corner, speed=1.0)
        assert np.max(np.abs(env.sim.box_position() - box)) < 1e-6
    assert np.linalg.norm(env.sim.finger_position() - [-4.0, -4.0]) < 0.05  # the finger really moved


def test_reset_clears_the_controller_so_the_finger_holds_still(env):
    box = np.array([-1.0, 0.5])
    env.reset(options={"box": box, "finger": box - [SCENE.contact_distance, 0.0]})
    ramp(env, box - [SCENE.contact_distance, 0.0], box + [1.0, 0.0], speed=0.5)  # winds up the PID integral
    finger = np.array([2.0, -3.0])
    env.reset(options={"box": [-2.0, 2.0], "finger": finger})
    info = hold(env, finger, seconds=5.0)
    assert np.max(np.abs(info["finger"] - finger)) < 1e-9
    assert info["sim_time_s"] == pytest.approx(5.0)


def test_out_of_range_actions_are_clipped(env):
    env.reset(options={"box": [0.0, 0.0], "finger": [3.0, 3.0]})
    info = hold(env, [100.0, 100.0], seconds=8.0)
    lim = SCENE.finger_limit
    assert np.all(info["finger"] > lim - 0.05) and np.all(info["finger"] < lim + 0.02)


def test_disturbance_pushes_the_box_by_its_impulse():
    protocol = Disturbances(probability_per_tick=1.0, max_count=1)  # one push at the first tick
    e = GcsPushEnv(scene=dataclasses.replace(SCENE, disturbances=protocol), disturbances=True, render_size=96)
    box = np.array([1.0, 1.0])
    e.reset(seed=5, options={"box": box, "finger": [-4.0, -4.0]})
    info = hold(e, [-4.0, -4.0], seconds=3.0)
    (d,) = info["disturbances"]
    assert d["t"] == 0.0
    force = np.array(d["force"])
    # A damped point mass travels impulse / damping in total: F * duration / c per axis.
    expected = force * protocol.duration_ticks * protocol.tick_s / SCENE.box_damping
    np.testing.assert_allclose(info["box"] - box, expected, atol=0.02 * np.abs(expected).max() + 1e-9)


# --- image -------------------------------------------------------------------------------------------
def blob_centroid(mask):
    rows, cols = np.nonzero(mask)
    assert len(rows) > 0, "colour not found in the image"
    return np.array([rows.mean(), cols.mean()])


def test_image_shows_box_finger_and_goal_where_projected(env):
    box, finger = np.array([3.0, -2.0]), np.array([-3.0, 2.5])
    obs, _ = env.reset(options={"box": box, "finger": finger})
    img = obs["pixels"].astype(int)
    assert obs["pixels"].shape == (96, 96, 3) and obs["pixels"].dtype == np.uint8
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    red = (r > 150) & (g < 80) & (b < 80)
    black = (r < 60) & (g < 60) & (b < 60)
    green = (g > 150) & (r < 80) & (b < 120)
    sim = env.sim
    # Box (its top face plus the sides perspective shows, all lit red) and finger are centred on their
    # centres in the motion plane; the goal lies on the ground (z = 0).
    assert np.linalg.norm(blob_centroid(red) - sim.world_to_pixel(box)) < 1.0
    assert np.linalg.norm(blob_centroid(black) - sim.world_to_pixel(finger)) < 1.0
    assert np.linalg.norm(blob_centroid(green) - sim.world_to_pixel(SCENE.goal, z=0.0)) < 1.0
    # Blob sizes follow the geometry: pixels per metre = width / (2 * view_half_width).
    px_per_m = 96 / (2 * SCENE.view_half_width)
    assert red.sum() == pytest.approx((SCENE.box_size * px_per_m) ** 2, rel=0.3)
    assert green.sum() == pytest.approx((SCENE.box_size * px_per_m) ** 2, rel=0.3)
    # Everything else is the uniform ground.
    ground = np.array(SCENE.camera.ground_rgba[:3]) * 255
    background = ~(red | black | green)
    assert np.mean(np.all(np.abs(img[background] - ground) <= 2, axis=-1)) > 0.97


def test_pixel_mapping_spans_the_view_edge_to_edge(env):
    v = SCENE.view_half_width
    np.testing.assert_allclose(env.sim.world_to_pixel([-v, v]), [-0.5, -0.5])
    np.testing.assert_allclose(env.sim.world_to_pixel([v, -v]), [95.5, 95.5])
    np.testing.assert_allclose(env.sim.pixel_to_world(env.sim.world_to_pixel([1.2, -3.4])), [1.2, -3.4])
    np.testing.assert_allclose(env.sim.pixel_to_world(env.sim.world_to_pixel([1.2, -3.4], z=0), z=0), [1.2, -3.4])
    # The optical axis is the image centre: a finger at the origin is centred on ((H-1)/2, (W-1)/2).
    env.reset(options={"box": [3.0, 3.0], "finger": [0.0, 0.0]})
    np.testing.assert_allclose(blob_centroid(np.all(env.render() < 60, axis=-1)), [191.5, 191.5], atol=0.01)
    # A finger at a corner of its commandable region is entirely in view (same silhouette as mid-image),
    # at the far corner of the image.
    lim = SCENE.finger_limit
    env.reset(options={"box": [0.0, 0.0], "finger": [lim, -lim]})
    corner = np.all(env.render() < 60, axis=-1)
    env.reset(options={"box": [3.0, 3.0], "finger": [0.0, -2.0]})
    centre = np.all(env.render() < 60, axis=-1)
    assert corner.sum() > 0.97 * centre.sum()
    assert np.linalg.norm(blob_centroid(corner) - env.sim.world_to_pixel([lim, -lim], size=(384, 384))) < 1.0
    assert blob_centroid(corner).min() > 384 - 2 * SCENE.finger_radius / (2 * v) * 384


def test_top_down_camera_maps_a_non_square_image_edge_to_edge():
    camera, v = TopDownCamera(SCENE, (48, 96)), SCENE.view_half_width
    info = camera.camera_info()
    assert (info.height(), info.width()) == (48, 96) and (info.center_y(), info.center_x()) == (24, 48)
    np.testing.assert_allclose(camera.world_to_pixel([[-v, v], [v, -v]]), [[-0.5, -0.5], [47.5, 95.5]])
    np.testing.assert_allclose(camera.pixel_to_world(camera.world_to_pixel([1.2, -3.4], z=0), z=0), [1.2, -3.4])


def test_render_image_is_larger_and_consistent(env):
    box = np.array([-2.0, 1.0])
    env.reset(options={"box": box, "finger": [3.0, -3.0]})
    frame = env.render().astype(int)
    assert frame.shape == (384, 384, 3)
    red = (frame[..., 0] > 150) & (frame[..., 1] < 80) & (frame[..., 2] < 80)
    expected = env.sim.world_to_pixel(box, size=(384, 384))
    assert np.linalg.norm(blob_centroid(red) - expected) < 1.0


# --- disturbance protocol (pure, no Drake) -----------------------------------------------------------
def run_schedules(n_episodes, n_ticks, chunk=10, seed=0, protocol=SCENE.disturbances):
    rng = np.random.default_rng(seed)
    episodes = []
    for _ in range(n_episodes):
        schedule = DisturbanceSchedule(protocol, rng)
        parts = [schedule.forces(chunk) for _ in range(n_ticks // chunk)]
        forces = np.concatenate([np.zeros((chunk, 2)) if p is None else p for p in parts])
        episodes.append((schedule.started, forces))
    return episodes


def test_disturbance_schedule_matches_the_protocol():
    p = SCENE.disturbances
    n_episodes, n_ticks = 4000, 300
    episodes = run_schedules(n_episodes, n_ticks)
    counts = np.array([len(started) for started, _ in episodes])
    # Count: min(Binomial(n_ticks, p), max_count) (a disturbance starting in the last ticks still counts).
    pmf = [
        math.comb(n_ticks, k) * p.probability_per_tick**k * (1 - p.probability_per_tick) ** (n_ticks - k)
        for k in range(p.max_count)
    ]
    expected = sum(k * pk for k, pk in enumerate(pmf)) + p.max_count * (1 - sum(pmf))
    assert counts.max() == p.max_count
    assert abs(counts.mean() - expected) < 4 * counts.std() / math.sqrt(n_episodes)
    # Onset: the first disturbance is geometric in ticks, P(T1 < k) = 1 - (1 - p)^k.
    first = np.array([started[0].tick if started else n_ticks for started, _ in episodes])
    for k in (20, 100, 200):
        cdf = 1 - (1 - p.probability_per_tick) ** k
        assert abs(np.mean(first < k) - cdf) < 4 * math.sqrt(cdf * (1 - cdf) / n_episodes)
    everything = [d for started, _ in episodes for d in started]
    magnitudes = np.array([np.abs(d.force).max() for d in everything])
    low, high = p.force_range_n
    assert magnitudes.min() >= low and magnitudes.max() <= high
    assert abs(magnitudes.mean() - (low + high) / 2) < 4 * (high - low) / math.sqrt(12 * len(magnitudes))
    assert magnitudes.min() < low + 0.05 * (high - low) and magnitudes.max() > high - 0.05 * (high - low)
    # Direction: one of four axis directions, equally likely, pushing on the named face.
    faces = {"left": (1, 0), "right": (-1, 0), "bottom": (0, 1), "top": (0, -1)}
    for d in everything:
        assert tuple(np.sign(d.force).astype(int)) == faces[d.face]
    share = np.array([sum(d.face == f for d in everything) for f in faces]) / len(everything)
    assert np.all(np.abs(share - 0.25) < 4 * math.sqrt(0.25 * 0.75 / len(everything)))
    # Duration: each acts for exactly duration_ticks consecutive ticks from its onset.
    for started, forces in episodes:
        if len(started) == 1 and started[0].tick + p.duration_ticks <= n_ticks:
            active = np.flatnonzero(np.any(forces != 0, axis=1))
            np.testing.assert_array_equal(active, np.arange(p.duration_ticks) + started[0].tick)
            np.testing.assert_array_equal(forces[active], np.tile(started[0].force, (p.duration_ticks, 1)))


def test_disturbance_schedule_stops_at_max_count_and_does_not_depend_on_chunking():
    long = run_schedules(200, 5000, chunk=10)
    assert all(len(started) == SCENE.disturbances.max_count for started, _ in long)  # 25 expected by 5000 ticks
    assert all(np.count_nonzero(np.any(f != 0, axis=1)) <= 15 for _, f in long)
    a = run_schedules(300, 600, chunk=10, seed=1)
    b = run_schedules(300, 600, chunk=3, seed=1)  # another fps draws the same disturbances
    assert sum(len(x[0]) for x in a) > 300
    assert all(x[0] == y[0] for x, y in zip(a, b))
    assert all(np.array_equal(x[1], y[1]) for x, y in zip(a, b))


# --- bad input ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("bad", [[np.nan, 0.0], [0.0, np.inf], [-np.inf, 1.0]])
def test_non_finite_action_raises(env, bad):
    env.reset(seed=0)
    with pytest.raises(ValueError, match="finite"):
        env.step(np.array(bad))


def test_wrong_action_shape_raises(env):
    env.reset(seed=0)
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros(3))


@pytest.mark.parametrize(
    "options, message",
    [
        ({"box": [0.0, 0.0], "finger": [0.5, 0.0]}, "overlaps the box"),
        ({"box": [0.0, 0.0], "finger": [0.7, 0.7]}, "overlaps the box"),  # near the corner: sphere vs. edge
        ({"box": [5.0, 0.0], "finger": [0.0, 0.0]}, "outside the box workspace"),
        ({"box": [0.0, 0.0], "finger": [0.0, -7.0]}, "outside the finger workspace"),
        ({"box": [0.0, np.nan], "finger": [3.0, 3.0]}, "finite"),
        ({"box": [0.0, 0.0]}, "finger must be a pair"),
    ],
)
def test_bad_initial_conditions_raise(env, options, message):
    with pytest.raises(ValueError, match=message):
        env.reset(options=options)


def test_touching_initial_condition_is_allowed(env):
    _, info = env.reset(options={"box": [0.0, 0.0], "finger": [-SCENE.contact_distance, 0.0]})
    assert info["finger"][0] == -SCENE.contact_distance


def test_drake_collision_query_agrees_with_exact_geometry(env):
    rng = np.random.default_rng(0)
    boxes = rng.uniform(-1, 1, size=(500, 2))
    fingers = boxes + rng.uniform(-1.2, 1.2, size=(500, 2))
    for box, finger in zip(boxes, fingers):
        gap = SCENE.finger_box_gap(box, finger)
        assert env.sim.signed_distance(box, finger) == pytest.approx(gap, abs=1e-9)
        if abs(gap) > 1e-9:
            assert env.sim.collides(box, finger) == (gap < 0)


def test_bad_constructor_arguments_raise():
    with pytest.raises(ValueError, match="obs_type"):
        GcsPushEnv(obs_type="pixels")
    with pytest.raises(ValueError, match="multiple"):
        GcsPushEnv(fps=30)  # 1/30 s is not a whole number of 0.01 s ticks
