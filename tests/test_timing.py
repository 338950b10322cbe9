"""The finger's timing along a plan (`planning.timing`): hand-computed profiles, and the bound a policy sees."""

import math

import numpy as np
import pytest

from lerobot_gcs_push.planning import FREE, PUSH, Plan, Speeds
from lerobot_gcs_push.planning.timing import CORNER_S, Timing


def test_without_a_bound_each_segment_runs_at_its_speed():
    path = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 2.0]])
    t = Timing(path, np.array([1.0, 0.5]), np.zeros(2))
    np.testing.assert_allclose(t.times, [0.0, 1.0, 5.0])
    seg, share = t.where(np.array([0.5, 3.0]))
    np.testing.assert_array_equal(seg, [0, 1])
    np.testing.assert_allclose(share, [0.5, 0.5])


def test_a_straight_segment_is_a_trapezoid_and_a_short_one_a_triangle():
    """1 m at 1 m/s under 4 m/s^2: 0.25 s up (0.125 m), 0.75 s cruising, 0.25 s down: 1.25 s; 0.1 m never
    reaches 1 m/s: up to sqrt(4 x 0.1) and down, 2 sqrt(0.4) / 4 s."""
    long = Timing(np.array([[0.0, 0.0], [1.0, 0.0]]), np.array([1.0]), np.zeros(1), accel=4.0)
    assert long.duration == pytest.approx(1.25)
    _, share = long.where(np.array([0.1, 0.25, 0.75, 1.25]))
    np.testing.assert_allclose(share, [0.5 * 4 * 0.01, 0.125, 0.125 + 0.5, 1.0])
    short = Timing(np.array([[0.0, 0.0], [0.1, 0.0]]), np.array([1.0]), np.zeros(1), accel=4.0)
    assert short.duration == pytest.approx(2 * math.sqrt(0.4) / 4)


def test_a_corner_is_taken_at_the_speed_whose_turn_the_bound_allows_and_a_dwell_at_rest():
    """A right angle between two 1 m legs at 1 m/s under 2 m/s^2: through the corner at 2 x CORNER_S /
    sqrt(2) m/s. Each leg is then up from (or down to) that speed: the whole time is the two legs' sum."""
    a, vc = 2.0, 2.0 * CORNER_S / math.sqrt(2)
    path = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]])
    t = Timing(path, np.array([1.0, 1.0]), np.zeros(2), accel=a)

    def leg(v0, v1):  # a trapezoid from v0 to v1 over 1 m, peak 1 m/s
        d = (1 - v0**2) / (2 * a) + (1 - v1**2) / (2 * a)
        return (1 - v0) / a + (1 - v1) / a + (1 - d)

    np.testing.assert_allclose(t.times, [0.0, leg(0.0, vc), leg(0.0, vc) + leg(vc, 0.0)])
    dwell = Timing(np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 0.0], [2.0, 0.0]]), np.ones(3), np.array([0, 0.5, 0]), a)
    assert dwell.duration == pytest.approx(2 * leg(0.0, 0.0) + 0.5)  # at rest on both sides of the hold


def test_a_bounded_schedule_keeps_its_commands_second_difference_under_the_bound():
    """A free leg, a turn into a push and a reversal, at 10 commands a second under 4 m/s^2: no command's
    second difference exceeds what the bound gives over two actions and at a corner (accel x dt^2 each);
    without the bound the reversal alone jumps by the two speeds' sum over an action."""
    plan = Plan(
        method="hand", cost=0.0, lower_bound=None, solve_time_s=0.0, modes=[],
        slider_poses=np.zeros((4, 2)), finger_path=np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [2.0, 0.2]]),
        segment_kinds=[FREE, PUSH, FREE], goal=np.zeros(2),
    )  # fmt: skip
    speeds = Speeds(free=2.0, push=1.0, push_dwell_s=0.0, push_lead=0.0)
    dt, accel = 0.1, 4.0
    bounded = plan.schedule(10, Speeds(**{**speeds.__dict__, "accel": accel})).commands
    second = np.linalg.norm(np.diff(bounded, 2, axis=0), axis=1)
    assert second.max() <= 2 * accel * dt**2 + 1e-9
    np.testing.assert_allclose(bounded[-1], [2.0, 0.2])
    free = plan.schedule(10, speeds).commands
    assert np.linalg.norm(np.diff(free, 2, axis=0), axis=1).max() > 0.25


def test_without_a_bound_a_schedule_is_linear_interpolation_in_time_even_through_a_segment_of_no_length():
    """A free leg, a push whose finger does not move while the slider does (no time), and a push: every
    command and reference pose is np.interp over the hand-computed knot times (1 s, 1 s, 1 s + 2 s), the
    last knot of an instant winning, as before the acceleration bound existed."""
    fp = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 0.0], [1.0, 1.0]])
    sp = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.3, 0.0, 0.2], [0.3, 1.0, 0.2]])
    plan = Plan("hand", 0.0, None, 0.0, [], sp, fp, [FREE, PUSH, PUSH], np.zeros(3))
    sched = plan.schedule(10, Speeds(free=1.0, push=0.5, push_dwell_s=0.0, push_lead=0.0))
    times, t = np.array([0.0, 1.0, 1.0, 3.0]), np.arange(1, 31) / 10
    expected = np.stack([np.interp(t, times, fp[:, i]) for i in range(2)], axis=1)
    np.testing.assert_allclose(sched.commands, expected, atol=1e-12)
    np.testing.assert_allclose(sched.slider, np.stack([np.interp(t, times, sp[:, i]) for i in range(3)], 1), atol=1e-12)
    assert [str(k) for k in sched.kinds[9:11]] == ["free", "push"]  # t = 1.0 ends the free leg


def test_the_last_push_arrives_at_the_arrival_speed_over_its_last_stretch():
    """A free leg and a 1 m push at 1 m/s under 4 m/s^2, the last 0.1 m at 0.2 m/s. Hand-computed: the push
    is up 0.25 s (0.125 m), down to 0.2 m/s in 0.2 s (0.12 m), cruising 0.655 m between; then 0.095 m at
    0.2 m/s (0.475 s) and down to rest in 0.05 s (0.005 m): 1.63 s against 1.25 s without the arrival. Every
    command in the last 0.1 m moves at most 0.2 m/s x dt, and an earlier push keeps its speed."""
    fp = np.array([[0.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, 2.0], [2.0, 2.0]])
    plan = Plan("hand", 0.0, None, 0.0, [], np.zeros((5, 2)), fp, [FREE, PUSH, FREE, PUSH], np.zeros(2))
    fast = Speeds(free=1.0, push=1.0, push_dwell_s=0.0, push_lead=0.0, accel=4.0)
    slow = Speeds(**{**fast.__dict__, "arrive": 0.2, "arrive_m": 0.1})
    assert plan.duration(slow) - plan.duration(fast) == pytest.approx(1.63 - 1.25)
    commands = plan.schedule(10, slow).commands
    np.testing.assert_allclose(commands[-1], [2.0, 2.0])
    steps = np.linalg.norm(np.diff(commands, axis=0), axis=1)
    last = commands[:-1, 0] >= 1.9 - 1e-9  # steps within the last 0.1 m
    assert last.sum() >= 5 and steps[last].max() <= 0.2 * 0.1 + 1e-9
    first_push = (commands[1:, 1] > 0.3) & (commands[1:, 1] < 0.7) & (commands[1:, 0] == 0.0)
    np.testing.assert_allclose(steps[first_push], 0.1, atol=1e-9)  # the earlier push cruises at 1 m/s
    short = Plan("hand", 0.0, None, 0.0, [], np.zeros((2, 2)), fp[:2] * 0.05, [PUSH], np.zeros(2))
    assert short.duration(slow) == pytest.approx(0.05 / 0.2 + 0.2 / 4)  # shorter than 0.1 m: all of it at 0.2


def test_the_experts_arrival_reaches_the_speeds_its_plans_run_at():
    from lerobot_gcs_push.planning.factory import ExpertConfig, make_expert
    from lerobot_gcs_push.registration import make_env

    env = make_env("gym_pusht/PushT-v0")
    arriving = make_expert(env.scene, env.fps, ExpertConfig(mode="closed-loop", arrive=0.15), planner=object())
    plain = make_expert(env.scene, env.fps, ExpertConfig(mode="closed-loop"), planner=object())
    assert (arriving.expert.speeds.arrive, arriving.expert.speeds.arrive_m) == (0.15, 0.1)
    assert plain.expert.speeds.arrive == 0.0 and arriving.expert.speeds.push == plain.expert.speeds.push
