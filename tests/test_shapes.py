"""Slider shapes as data: gym-pusht's T in proportion, and coverage and signed distance against
independent computations (Monte Carlo over matplotlib's point-in-polygon, dense outline sampling)."""

import math

import numpy as np
import pytest
from matplotlib.path import Path

from lerobot_gcs_push.shapes import square, tee

TEE = tee(2.0)


def test_tee_has_gym_pusht_proportions_about_its_centroid():
    # gym-pusht: bar 120 x 30 px, stem 30 x 90 px, i.e. bar 4:1, stem one bar-width wide, 3/4 bar long.
    bar, stem = (np.asarray(p) for p in TEE.parts)
    assert np.ptp(bar, axis=0) == pytest.approx([2.0, 0.5])
    assert np.ptp(stem, axis=0) == pytest.approx([0.5, 1.5])
    # By hand: bar (area 1) centred 1.75 above the stem's foot, stem (area 0.75) at 0.75: centroid at
    # (1.75 + 0.5625) / 1.75 = 1.3214 above the foot, which the shape's frame puts at the origin.
    assert TEE.area == pytest.approx(1.75)
    assert stem[:, 1].min() == pytest.approx(-2.3125 / 1.75)
    # The stem's foot corners are the farthest points: r_max^2 = 0.25^2 + 1.3214^2.
    assert TEE.r_max == pytest.approx(math.hypot(0.25, 2.3125 / 1.75))
    assert len(TEE.faces()) == 8


def outline_path(shape, pose):
    return Path(np.vstack([shape.world_outline(pose), shape.world_outline(pose)[:1]]), closed=True)


@pytest.mark.parametrize("shape", [square(1.0), TEE], ids=lambda s: s.name)
def test_coverage_matches_a_monte_carlo_estimate(shape):
    rng = np.random.default_rng(0)
    goal = (0.3, -0.2, math.pi / 4)
    goal_path = outline_path(shape, goal)
    lo, hi = shape.world_outline(goal).min(axis=0), shape.world_outline(goal).max(axis=0)
    n = 200_000
    points = rng.uniform(lo, hi, size=(n, 2))
    in_goal = goal_path.contains_points(points)
    seen = []
    for scale in (0.02, 0.05, 0.1, 0.2, 0.4, 0.8):  # from near success to small overlaps
        pose = np.array(goal) + rng.normal(0, scale, size=3)
        both = in_goal & outline_path(shape, pose).contains_points(points)
        estimate = both.mean() * np.prod(hi - lo) / shape.area
        sigma = math.sqrt(both.mean() * (1 - both.mean()) / n) * np.prod(hi - lo) / shape.area
        assert shape.coverage(pose, goal) == pytest.approx(estimate, abs=4 * sigma + 1e-3)
        seen.append(estimate)
    assert min(seen) < 0.5 and max(seen) > 0.9  # partial overlaps, not only the trivial ends


def test_coverage_ends_and_symmetry():
    goal = (0.0, 0.0, math.pi / 4)
    assert TEE.coverage(goal, goal) == pytest.approx(1.0, abs=1e-12)
    assert TEE.coverage((5.0, 0.0, 0.0), goal) == 0.0
    assert TEE.coverage((0.0, 0.0, math.pi / 4 + 2 * math.pi), goal) == pytest.approx(1.0, abs=1e-12)
    # The square looks the same a quarter turn on; the T does not (a half turn leaves the bar's middle
    # and the stem's top overlapping only).
    assert square(1.0).coverage((0.0, 0.0, math.pi / 2), (0.0, 0.0, 0.0)) == pytest.approx(1.0, abs=1e-12)
    assert TEE.coverage((0.0, 0.0, math.pi), (0.0, 0.0, 0.0)) < 0.5
    # A unit square shifted by d along a side covers 1 - d of its goal.
    assert square(1.0).coverage((0.06, 0.0, 0.0), (0.0, 0.0, 0.0)) == pytest.approx(0.94)


def test_signed_distance_matches_dense_outline_sampling():
    rng = np.random.default_rng(1)
    pose = (0.4, -0.3, 1.1)
    outline = TEE.world_outline(pose)
    dense = np.vstack(
        [a + np.linspace(0, 1, 2000)[:, None] * (b - a) for a, b in zip(outline, np.roll(outline, -1, 0))]
    )
    path = outline_path(TEE, pose)
    for point in rng.uniform(-2.5, 2.5, size=(300, 2)):
        d = np.min(np.linalg.norm(dense - point, axis=1))
        expected = -d if path.contains_point(point) else d
        assert TEE.signed_distance(pose, point) == pytest.approx(expected, abs=2e-3)
