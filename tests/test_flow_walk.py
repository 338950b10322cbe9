"""The one rounding walk (`flow_walk.walk`), on graphs small enough to enumerate by hand."""

from collections import Counter

import numpy as np
import pytest

from lerobot_gcs_push.planning.flow_walk import walk


def graph(edges):
    """out(v) over {name: (tail, head, flow)}, edges in the given order."""

    def out(v):
        return [(name, h, f) for name, (t, h, f) in edges.items() if t == v]

    return out


DIAMOND = {"sa": ("s", "a", 0.6), "sb": ("s", "b", 0.4), "at": ("a", "t", 0.6), "bt": ("b", "t", 0.4)}


def test_greedy_takes_the_largest_flow_and_the_first_of_equals():
    assert walk(graph(DIAMOND), "s", "t") == ("sa", "at")
    tie = {"sb": ("s", "b", 0.5), "sa": ("s", "a", 0.5), "at": ("a", "t", 0.5), "bt": ("b", "t", 0.5)}
    assert walk(graph(tie), "s", "t") == ("sb", "bt")


def test_a_dead_end_is_backed_out_of():
    # The greedy first step leads to c, from which nothing reaches t: the walk must return through b.
    edges = {"sa": ("s", "a", 0.9), "ac": ("a", "c", 0.9), "sb": ("s", "b", 0.1), "bt": ("b", "t", 0.1)}
    assert walk(graph(edges), "s", "t") == ("sb", "bt")
    assert walk(graph(edges), "s", "t", np.random.default_rng(0)) == ("sb", "bt")


def test_cycles_end_in_a_simple_path():
    edges = {"sa": ("s", "a", 1.0), "ab": ("a", "b", 1.0), "ba": ("b", "a", 1.0), "bt": ("b", "t", 0.5)}
    path = walk(graph(edges), "s", "t")
    assert path == ("sa", "ab", "bt")


def test_no_path_and_min_flow():
    edges = {"sa": ("s", "a", 1.0), "at": ("a", "t", 1e-5)}
    assert walk(graph(edges), "s", "t") == ("sa", "at")
    assert walk(graph(edges), "s", "t", min_flow=1e-4) is None
    assert walk(graph({"sa": ("s", "a", 1.0)}), "s", "t") is None


def test_draws_follow_the_flows():
    # Two layers of splits: each path's probability is the product of its edges' shares of their vertex's
    # outflow. 20000 walks; every frequency within 4 standard deviations of it.
    edges = {
        "sa": ("s", "a", 0.7),
        "sb": ("s", "b", 0.3),
        "ac": ("a", "c", 0.2),
        "ad": ("a", "d", 0.5),
        "bc": ("b", "c", 0.3),
        "ct": ("c", "t", 0.5),
        "dt": ("d", "t", 0.5),
    }
    out = graph(edges)
    rng = np.random.default_rng(7)
    n = 20000
    seen = Counter(walk(out, "s", "t", rng) for _ in range(n))
    exact = {("sa", "ac", "ct"): 0.7 * 0.2 / 0.7, ("sa", "ad", "dt"): 0.7 * 0.5 / 0.7, ("sb", "bc", "ct"): 0.3}
    assert set(seen) == set(exact)
    for path, p in exact.items():
        assert seen[path] / n == pytest.approx(p, abs=4 * np.sqrt(p * (1 - p) / n))


def test_a_draw_is_rng_choice_over_the_flows():
    # Each vertex costs one `rng.choice` over its positive flows (zero flows change nothing), so a walk draws
    # exactly as the contact planner's rounding did before the walks were one (its sampled paths unchanged).
    edges = {"s0": ("s", "a", 0.0), "s1": ("s", "b", 0.25), "s2": ("s", "c", 0.75)}
    edges |= {"at": ("a", "t", 1.0), "bt": ("b", "t", 0.25), "ct": ("c", "t", 0.75)}
    for seed in range(20):
        rng, ref = np.random.default_rng(seed), np.random.default_rng(seed)
        first = ["s0", "s1", "s2"][ref.choice(3, p=[0.0, 0.25, 0.75])]
        ref.choice(1, p=[1.0])
        assert walk(graph(edges), "s", "t", rng)[0] == first
        assert rng.random() == ref.random()  # the same number of draws
