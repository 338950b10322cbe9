"""Checks every Drake env passes, shared by the box's tests and the turning sliders'."""

import warnings

from gymnasium.utils.env_checker import check_env

# Actions are metres, not a normalised [-1, 1] box; nothing bounds where the slider can go.
EXPECTED_WARNINGS = ("symmetric and normalized", "infinity")


def passes_gymnasium_checks(env):
    """Gymnasium's own env checker with no warning but the expected ones, then a reset whose observation lies
    in the observation space; returns that reset's (obs, info)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped)
    assert all(any(e in str(w.message) for e in EXPECTED_WARNINGS) for w in caught), [str(w.message) for w in caught]
    obs, info = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    return obs, info
