"""Where a pool's demonstrations cross gym-pusht's threshold and where they end: each replay list run in
gym-pusht itself, its coverage read after every action.

    python -m experiments.pusht.finish_stats lead4_finish98
"""

from __future__ import annotations

import json
import sys

import numpy as np

from benchmarks.learnability import POOLS
from lerobot_gcs_push.pusht import keypoint_data


def stats(pool: str) -> dict:
    import gym_pusht  # noqa: F401  (registers the env)
    import gymnasium as gym

    from lerobot_gcs_push.pusht.env import GYM_PUSHT_ID, GYM_PUSHT_STEPS
    from lerobot_gcs_push.pusht.frame import reset_to_state

    env = gym.make(GYM_PUSHT_ID, obs_type="environment_state_agent_pos", max_episode_steps=GYM_PUSHT_STEPS)
    first, total, final = [], [], []
    for demo in keypoint_data.read_lists(POOLS[pool].lists, POOLS[pool].episodes):
        env.reset(options={"reset_to_state": reset_to_state(demo["pusht_state"])})
        cover = []
        for action in demo["actions"]:  # the float32 the list stores, as the replay runs it
            *_, info = env.step(np.asarray(action, np.float32).astype(np.float64))
            cover.append(info["coverage"])
        cover = np.array(cover)
        first.append(int(np.argmax(cover > 0.95)) + 1)
        total.append(len(cover))
        final.append(cover[-1])
    env.close()
    first, total, final = map(np.array, (first, total, final))
    return {
        "pool": pool,
        "episodes": len(total),
        "frames_median": float(np.median(total)),
        "frames_mean": round(float(total.mean()), 1),
        "to_first_success_median": float(np.median(first)),
        "past_it_median": float(np.median(total - first)),
        "past_it_mean": round(float((total - first).mean()), 1),
        "final_coverage_median": round(float(np.median(final)), 4),
        "final_coverage_at_least_0.98": int((final >= 0.98).sum()),
    }


if __name__ == "__main__":
    for name in sys.argv[1:]:
        print(json.dumps(stats(name)))
