"""Demonstrations that go on past gym-pusht's success (`pusht/finish.py`): the episode ends once the T
covers `coverage` of the goal, or `frames` steps after the first success (at a success), and the replay
list keeps that setting so the episode rebuilds to the same length.

The evidence is gym-pusht's own coverage on hand-placed states: its T 1.5 px off the goal covers 0.960 of it
(a success, below 0.98), 0.5 px off 0.987, and an agent parked in a corner never touches it."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from lerobot_gcs_push.pusht.dataset import PushTFrames
from lerobot_gcs_push.pusht.finish import Finish
from lerobot_gcs_push.registration import PUSHT_ENV_ID

PARK = [60.0, 60.0]  # the agent, far from the T: held there, it moves nothing


def _state(dx: float) -> list:
    return [*PARK, 256.0 + dx, 256.0, math.pi / 4]  # gym-pusht's goal is (256, 256, pi / 4)


class Hold:
    def reset(self, obs, info, seed):
        pass

    def act(self, obs, info):
        return np.array(PARK)


def _frames(dx: float, finish: Finish | None, seconds: float = 3.0) -> dict:
    from lerobot_gcs_push.episodes.rollout import rollout
    from lerobot_gcs_push.registration import make_env

    env = make_env(PUSHT_ENV_ID, max_sim_time_s=seconds, obs_type="environment_state_agent_pos")
    frames = PushTFrames(env if finish is None else finish.wrap(env), "environment_state_agent_pos")
    result = rollout(frames.env, Hold(), pusht_state=_state(dx))
    env.close()
    return frames.arrays() | {"result": result}


# --- fast ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("spec", [{"coverage": 0.95, "frames": 5}, {"coverage": 1.01, "frames": 5},
                                  {"coverage": float("nan"), "frames": 5}, {"coverage": 0.98, "frames": 0},
                                  {"coverage": 0.98, "frames": 2.5}, {"coverage": 0.98}, None])  # fmt: skip
def test_bad_finish_specs_are_refused(spec):
    with pytest.raises(ValueError, match="finish"):
        Finish.of(spec)


def test_a_success_below_the_finish_goes_on_for_its_frames_then_ends_at_a_success():
    finish = Finish(0.98, 5)
    held = _frames(1.5, finish)
    # gym-pusht alone ends at the first step (coverage 0.960 > 0.95).
    assert len(_frames(1.5, None)["action"]) == 1
    # With the finish: the first success at step 1, then 5 more steps, the last a success that ends it.
    assert len(held["action"]) == 6
    assert held["next.success"].all()
    assert held["next.done"].ravel().tolist() == [False] * 5 + [True]
    assert held["result"]["success"] and abs(held["result"]["coverage"] - 0.960) < 0.001


def test_a_success_past_the_finish_ends_at_once():
    assert len(_frames(0.5, Finish(0.98, 5))["action"]) == 1  # coverage 0.987 >= 0.98
    assert len(_frames(1.5, Finish(0.955, 50))["action"]) == 1  # 0.960 >= 0.955


def test_no_success_no_finish_frames():
    # 2 px off: coverage 0.947, never a success while the agent is parked: the env's own time limit ends it.
    a = _frames(2.0, Finish(0.98, 5), seconds=1.0)
    assert len(a["action"]) == 10 and not a["next.success"].any() and not a["result"]["success"]


def test_generate_refuses_a_finish_where_it_has_no_meaning(tmp_path):
    from lerobot_gcs_push.generate import GenerateConfig

    with pytest.raises(ValueError, match="gym-pusht"):
        GenerateConfig(repo_id="local/x", finish_coverage=0.98)  # the Drake box: success is a distance
    with pytest.raises(ValueError, match="finish"):
        GenerateConfig(env_id=PUSHT_ENV_ID, repo_id="local/x", finish_coverage=0.9)
    listed = tmp_path / "list.json"
    listed.write_text(json.dumps([{"pusht_state": _state(1.5), "actions": [PARK]}]))
    with pytest.raises(ValueError, match="drop --finish_coverage"):
        GenerateConfig(env_id=PUSHT_ENV_ID, repo_id="local/x", initial_conditions=str(listed), finish_coverage=0.98)


def test_a_finish_list_replays_to_its_length_and_writes_its_setting_again(tmp_path):
    """`generate --expert=replay` on a hand-made list: with its "finish" the episode runs all 6 actions,
    without it gym-pusht ends it at the first; the rebuilt list is the list."""
    from lerobot_gcs_push.generate import GenerateConfig, generate
    from lerobot_gcs_push.generate.replay import REPLAY_META

    entry = {"pusht_state": _state(1.5), "finish": {"coverage": 0.98, "frames": 5}, "actions": [PARK] * 6}
    common = dict(env_id=PUSHT_ENV_ID, repo_id="local/finish", obs_type="environment_state_agent_pos", workers=1,
                  progress=False)  # fmt: skip
    for name, e, frames in (("with", entry, 6), ("without", {k: v for k, v in entry.items() if k != "finish"}, 1)):
        listed = tmp_path / f"{name}.json"
        listed.write_text(json.dumps([e]))
        cfg = GenerateConfig(**common, root=str(tmp_path / name), initial_conditions=str(listed))
        assert generate(cfg).frames == frames, name
    again = json.loads((Path(tmp_path / "with") / REPLAY_META).read_text())
    assert again == [entry]
