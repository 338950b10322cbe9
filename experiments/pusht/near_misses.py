"""Where a learnability judge's episodes end: successes, and the failures binned by their max reward
(clip(coverage / 0.95)), read from `lerobot-eval`'s per-episode record (`eval_info.json`).

    python -m experiments.pusht.near_misses position_shift2 lead4_finish98
"""

from __future__ import annotations

import json
import sys

import numpy as np

from benchmarks.learnability import REPO, VERSION

BINS = ((0.95, 1.01), (0.90, 0.95), (0.80, 0.90), (0.50, 0.80), (0.0, 0.50))


def bins(eval_info) -> dict:
    metrics = json.loads(eval_info.read_text())["per_task"][0]["metrics"]
    top, won = np.array(metrics["max_rewards"]), np.array(metrics["successes"], bool)
    out = {"successes": int(won.sum())}
    for lo, hi in BINS:
        out[f"failed, max reward {lo:g}-{min(hi, 1):g}"] = int(((top >= lo) & (top < hi) & ~won).sum())
    return out


def main(pools: list[str]) -> None:
    for pool in pools:
        for path in sorted((REPO / "outputs" / "learnability" / VERSION / pool).glob("judge*/eval_info.json")):
            print(pool, path.parent.name, json.dumps(bins(path)))


if __name__ == "__main__":
    main(sys.argv[1:])
