"""How fast a pool's T comes into gym-pusht's goal band: the mean move of its 8 keypoints a frame over each
demonstration's last 3 frames, and by frame over the last 10, from the replayed keypoints (the benchmark's
cache, `outputs/keypoints`; a rebuild is minutes).

    python -m experiments.pusht.arrival_stats position arrive_shift1
"""

from __future__ import annotations

import json
import sys

import numpy as np

from benchmarks.learnability import POOLS, REPO
from lerobot_gcs_push.pusht import keypoint_data
from lerobot_gcs_push.pusht.keypoint_data import ENV_STATE


def stats(pool: str) -> dict:
    spec = POOLS[pool]
    data = keypoint_data.load(spec.lists, spec.episodes, REPO / "outputs" / "keypoints", progress=False)
    keypoints = data.arrays[ENV_STATE].reshape(-1, 8, 2)
    last3, last10 = [], []
    for start, end in zip(data.starts(), data.ends):
        speed = np.linalg.norm(np.diff(keypoints[start:end], axis=0), axis=-1).mean(-1)
        last3.append(speed[-3:].mean())
        if end - start >= 12:
            last10.append(speed[-10:])
    last3, frames = np.array(last3), data.ends - data.starts()
    return {
        "pool": pool,
        "frames_median": float(np.median(frames)),
        "frames_mean": round(float(frames.mean()), 1),
        "last3_px_median_p10_p90": [round(float(x), 2) for x in np.percentile(last3, [50, 10, 90])],
        "faster_than_2px": int((last3 > 2).sum()),
        "by_frame_last10": [round(float(x), 2) for x in np.median(np.array(last10), 0)],
    }


if __name__ == "__main__":
    for name in sys.argv[1:]:
        print(json.dumps(stats(name)))
