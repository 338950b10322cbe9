"""Where each policy of an evaluation leaves the T: how far it moved and turned it, and how far from the
goal it ends against how far it started (scene metres, 60 px a metre; the goal is the origin).

    python experiments/pusht/where_the_t_ends.py outputs/improve/pusht/work/r1/validation_uniform/runs.jsonl
"""

from __future__ import annotations

import json
import sys

import numpy as np


def main(path: str) -> None:
    recs = [json.loads(line) for line in open(path)]
    for policy in sorted({r["policy"] for r in recs}):
        rs = [r for r in recs if r["policy"] == policy]
        start = np.array([r["box_initial"] for r in rs])
        end = np.array([r["slider_pose_final"] for r in rs])
        turned = np.abs((end[:, 2] - np.array([r["heading_initial"] for r in rs]) + np.pi) % (2 * np.pi) - np.pi)
        final = np.array([r["final_distance"] for r in rs])
        moved = np.median(np.linalg.norm(end[:, :2] - start, axis=1))
        began = np.median(np.linalg.norm(start, axis=1))
        print(
            f"{policy}: {len(rs)} runs, {sum(r['success'] for r in rs)} successes; moved {moved:.2f} m and turned "
            f"{np.median(turned):.2f} rad (medians); from the goal {began:.2f} m at the start, "
            f"{np.median(final):.2f} m at the end; {int(np.sum(final < 0.3))} end within 0.3 m"
        )


if __name__ == "__main__":
    main(sys.argv[1])
