"""What a pool's actions ask of a policy, over its replayed frames (the learnability benchmark's keypoint
arrays, `outputs/keypoints/`): the 90th percentile of the actions' second difference against the agent's
own, within episodes, and the episodes' frames.

    python -m experiments.pusht.pool_stats steer1 position
"""

from __future__ import annotations

import json
import sys

import numpy as np

from benchmarks.learnability import POOLS, REPO
from lerobot_gcs_push.pusht import keypoint_data


def stats(pool: str) -> dict:
    data = keypoint_data.load(
        POOLS[pool].lists, POOLS[pool].episodes, REPO / "outputs" / "keypoints", progress=False
    ).labels_ahead(POOLS[pool].label_shift)
    act, agent = data.arrays["action"].astype(float), data.arrays["observation.state"].astype(float)
    second_a, second_s, frames = [], [], np.diff(np.concatenate([[0], data.ends]))
    for s, e in zip(data.starts(), data.ends):
        second_a.append(np.linalg.norm(np.diff(act[s:e], 2, axis=0), axis=1))
        second_s.append(np.linalg.norm(np.diff(agent[s:e], 2, axis=0), axis=1))
    a90, s90 = np.percentile(np.concatenate(second_a), 90), np.percentile(np.concatenate(second_s), 90)
    return {
        "pool": pool,
        "episodes": len(data),
        "frames": data.frames,
        "frames_median": float(np.median(frames)),
        "frames_mean": round(float(np.mean(frames)), 1),
        "action_second_diff_p90_px": round(float(a90), 2),
        "agent_second_diff_p90_px": round(float(s90), 2),
        "ratio_p90": round(float(a90 / s90), 2),
    }


if __name__ == "__main__":
    for pool in sys.argv[1:]:
        print(json.dumps(stats(pool)))
