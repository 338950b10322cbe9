"""Demonstrations that finish past gym-pusht's threshold.

gym-pusht ends an episode at the first step whose coverage passes 0.95, so every demonstration stops just
over it (the position pool: median 0.960). A policy imitates the expert's finish only roughly; in the
learnability benchmark's judges a fifth to a quarter of all episodes ended with the T between 0.90 and 0.95
(max reward >= 0.95, no success). A demonstration that goes on until the T covers more of the goal shows the
policy an aim with a margin. `Finish` keeps the episode running past the first success until the coverage
reaches `coverage`, or until `frames` steps after the first success, then at the next step that is a
success: the last frame is always one, so the list still replays to its success.
"""

from __future__ import annotations

from dataclasses import dataclass
from numbers import Integral


@dataclass(frozen=True)
class Finish:
    """When a demonstration ends: coverage >= `coverage`, or `frames` steps after gym-pusht's first success
    (at the first success from then on)."""

    coverage: float
    frames: int

    def __post_init__(self) -> None:
        if not 0.95 < self.coverage <= 1.0:  # also refuses NaN
            raise ValueError(f"finish coverage must be in (0.95, 1] (gym-pusht's success is 0.95), got {self.coverage}")
        if isinstance(self.frames, bool) or not isinstance(self.frames, Integral) or self.frames < 1:
            raise ValueError(f"finish frames must be a whole number >= 1, got {self.frames}")

    @classmethod
    def of(cls, spec: dict) -> Finish:
        """From a replay entry's or an episode's "finish" record."""
        try:
            return cls(float(spec["coverage"]), spec["frames"])
        except (KeyError, TypeError, ValueError) as err:
            raise ValueError(f'"finish" must be {{"coverage": c, "frames": n}} with c in (0.95, 1]: {err}') from None

    def spec(self) -> dict:
        return {"coverage": self.coverage, "frames": int(self.frames)}

    def wrap(self, env) -> FinishPast:
        return FinishPast(env, self)


class FinishPast:
    """The env, its `terminated` held back past the first success as `finish` says; everything else is the
    env's (gym-pusht itself steps on after a success as before it)."""

    def __init__(self, env, finish: Finish):
        self._env, self.finish = env, finish
        self._since: int | None = None  # steps since the first success

    def __getattr__(self, name):
        return getattr(self._env, name)

    def reset(self, **kwargs):
        self._since = None
        return self._env.reset(**kwargs)

    def step(self, action):
        obs, reward, terminated, truncated, info = self._env.step(action)
        if info["is_success"] and self._since is None:
            self._since = 0
        elif self._since is not None:
            self._since += 1
        if terminated:  # a success: the end only once the T covers enough, or the frames are spent
            terminated = info["coverage"] >= self.finish.coverage or self._since >= self.finish.frames
        return obs, reward, terminated, truncated, info
