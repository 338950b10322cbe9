"""Why does a policy fail? Reads an evaluation directory written by `gcs-push evaluate` and prints, per
policy label:

- failures that are wrong-face pushes: the box ends farther from the goal than it started, i.e. the
  finger pushed it away instead of towards the goal;
- the other failures, and how many of them are near misses (box within 1 m of the goal at the timeout);
- failures per initial condition (are they spread out, or the same few configurations every run?);
- for the expert's open-loop rollouts, the fraction of frames before the box first moves (the approach
  phase, where the image shows a still box and only the finger position changes).

    .venv/bin/python results/train/failure_analysis.py results/eval_policy_ft1000
"""

import argparse
import json
from collections import Counter, defaultdict
from pathlib import Path

import numpy as np

from lerobot_gcs_push.scene import Scene

parser = argparse.ArgumentParser()
parser.add_argument("eval_dir", type=Path)
parser.add_argument("--near", type=float, default=1.0, help="'ended close' radius in metres")
args = parser.parse_args()

goal = Scene().goal_array
runs = [json.loads(line) for line in (args.eval_dir / "runs.jsonl").read_text().splitlines() if line]
by_label = defaultdict(list)
for r in runs:
    by_label[r["label"]].append(r)

print(f"{'policy':50s} {'runs':>5s} {'fail':>5s} {'wrong-face':>10s} {'other':>6s} {'near miss':>10s}  failures per IC")
for label, rs in by_label.items():
    failures = [r for r in rs if not r["success"]]
    wrong, other = [], []
    for r in failures:
        pushed_away = r["final_distance"] > np.linalg.norm(np.asarray(r["box_initial"]) - goal)
        (wrong if pushed_away else other).append(r)
    near = [r for r in other if r["final_distance"] <= args.near]
    per_ic = Counter(r["initial_condition_index"] for r in failures).most_common()
    print(
        f"{label:50s} {len(rs):5d} {len(failures):5d} {len(wrong):10d} {len(other):6d} {len(near):10d}  "
        + " ".join(f"IC{i}:{n}" for i, n in per_ic)
    )

approach = []
for path in sorted((args.eval_dir / "trajectories" / "gcs_open_loop").glob("*.npz")):
    box = np.load(path)["box"]
    moved = np.flatnonzero(np.linalg.norm(box - box[0], axis=1) > 1e-6)
    if len(moved):
        approach.append(moved[0] / len(box))
if approach:
    q = np.percentile(approach, [25, 50, 75])
    print(
        f"GCS open loop, fraction of frames before the box first moves ({len(approach)} rollouts): "
        f"median {q[1]:.2f} (quartiles {q[0]:.2f}-{q[2]:.2f})"
    )
